// What the settled blocks make (docs/ridge.md): the freeze joints between touching boxes and
// the largest overlap, the achieved keel and sail profile, and the keel's porosity.
#include "ridge/internal.h"

namespace hs::rigid::detail {

namespace {

double percentile95(std::vector<double>& v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const std::size_t k = static_cast<std::size_t>(std::ceil(0.95 * static_cast<double>(v.size()))) - 1;
  return v[std::min(k, v.size() - 1)];
}

// ---- freeze joints and final overlap: every pair of boxes (block-block, block-ice) closer
// than the gap gets a joint of the area of their gap-inflated intersection over its depth.
void find_joints(const RidgeDef& d, const std::vector<Placed>& placed, const HashGrid& fgrid_in, RidgeResult& res) {
  HashGrid& fgrid = const_cast<HashGrid&>(fgrid_in);  // query() only stamps its scratch
  const double gap = d.joints.gap;
  const Vec3 hg = Vec3::Constant(0.5 * gap);
  auto try_joint = [&](std::int32_t a, std::int32_t b, const Vec3& ha, const Vec3& xa, const Mat3& A,
                       const Vec3& hb, const Vec3& xb, const Mat3& B) {
    const double pen = sat(ha, xa, A, hb, xb, B, nullptr);
    if (pen > 0.0) res.stats.max_final_overlap = std::max(res.stats.max_final_overlap, pen);
    Vec3 axis = Vec3::UnitZ();
    const double s = sat(ha + hg, xa, A, hb + hg, xb, B, &axis);
    if (s <= 0.0) return;
    Vec3 c = Vec3::Zero();
    const double vol = box_intersection(ha + hg, xa, A, hb + hg, xb, B, &c);
    const double area = vol / s;
    if (!(area >= d.joints.min_area) || area <= 0.0) return;
    RidgeJoint j;
    j.a = a;
    j.b = b;
    j.anchor = c;
    j.normal = axis;
    j.area = area;
    res.joints.push_back(j);
  };
  std::vector<std::int32_t> cand;
  for (std::size_t i = 0; i < placed.size(); ++i) {
    const Placed& p = placed[i];
    fgrid.query(p.x - p.aabb - Vec3::Constant(gap), p.x + p.aabb + Vec3::Constant(gap), cand);
    for (std::int32_t j : cand) {
      if (j <= static_cast<std::int32_t>(i)) continue;
      const Placed& o = placed[j];
      if (((p.x - o.x).cwiseAbs() - p.aabb - o.aabb).maxCoeff() > gap) continue;
      try_joint(static_cast<std::int32_t>(i), j, p.h, p.x, p.R, o.h, o.x, o.R);
    }
    for (std::size_t k = 0; k < res.ice.size(); ++k) {
      const IceBox& ib = res.ice[k];
      if (((p.x - ib.position).cwiseAbs() - p.aabb - ib.half_extents).maxCoeff() > gap) continue;
      const std::size_t before = res.joints.size();
      // The ice is b: normal from the block to the ice.
      try_joint(static_cast<std::int32_t>(i), -1 - static_cast<std::int32_t>(k), p.h, p.x, p.R,
                ib.half_extents, ib.position, Mat3::Identity());
      if (!d.joints.to_ice && res.joints.size() > before) res.joints.pop_back();
      else if (res.joints.size() > before) ++res.stats.ice_joints;
    }
  }
  res.stats.joints = res.joints.size();
}

/// The x range and bins of the report: bin b covers [(b0 + b) pb, (b0 + b + 1) pb).
struct ProfileBins {
  double xlo = 0.0, xhi = 0.0, pb = 0.0;
  std::int64_t b0 = 0;
  std::size_t nb = 0;
};

// ---- achieved profile: 95th percentile of block bottoms (keel) / tops (sail) per bin.
ProfileBins measure_profile(const RidgeRun& run, const std::vector<Placed>& placed, RidgeResult& res) {
  const RidgeDef& d = run.d;
  ProfileBins pbins;
  double xlo = 0.0, xhi = 0.0;
  for (const Placed& p : placed) xlo = std::min(xlo, p.x.x()), xhi = std::max(xhi, p.x.x());
  xlo = std::min(xlo, -std::max(run.kx, run.sx));
  xhi = std::max(xhi, std::max(run.kx, run.sx));
  if (!d.keel_profile.empty()) {
    xlo = std::min(xlo, d.keel_profile.front().position);
    xhi = std::max(xhi, d.keel_profile.back().position);
  }
  const double pb = d.profile_bin;
  const std::int64_t b0 = static_cast<std::int64_t>(std::floor(xlo / pb)),
                     b1 = static_cast<std::int64_t>(std::floor(xhi / pb));
  const std::size_t nb = static_cast<std::size_t>(b1 - b0 + 1);
  std::vector<std::vector<double>> kbot(nb), stop(nb);
  for (const Placed& p : placed) {
    const std::size_t bi = static_cast<std::size_t>(static_cast<std::int64_t>(std::floor(p.x.x() / pb)) - b0);
    if (p.part == 0) kbot[bi].push_back(-(p.x.z() - p.aabb.z()));
    else stop[bi].push_back(p.x.z() + p.aabb.z());
  }
  RidgeProfile& pr = res.profile;
  double se = 0.0;
  std::size_t ne = 0;
  for (std::size_t i = 0; i < nb; ++i) {
    const double xc = (static_cast<double>(b0 + static_cast<std::int64_t>(i)) + 0.5) * pb;
    pr.x.push_back(xc);
    pr.keel_target.push_back(keel_target_depth(d, xc));
    pr.keel_depth.push_back(percentile95(kbot[i]));
    pr.sail_target.push_back(sail_target_height(d, xc));
    pr.sail_height.push_back(percentile95(stop[i]));
    if (pr.keel_target.back() > 0.0 || pr.keel_depth.back() > 0.0) {
      const double e = pr.keel_depth.back() - pr.keel_target.back();
      se += e * e;
      ++ne;
    }
    res.stats.keel_depth_target = std::max(res.stats.keel_depth_target, pr.keel_target.back());
    res.stats.keel_depth_achieved = std::max(res.stats.keel_depth_achieved, pr.keel_depth.back());
    res.stats.sail_height_target = std::max(res.stats.sail_height_target, pr.sail_target.back());
    res.stats.sail_height_achieved = std::max(res.stats.sail_height_achieved, pr.sail_height.back());
  }
  res.stats.keel_profile_rms_error = ne ? std::sqrt(se / static_cast<double>(ne)) : 0.0;
  pbins.xlo = xlo;
  pbins.xhi = xhi;
  pbins.pb = pb;
  pbins.b0 = b0;
  pbins.nb = nb;
  return pbins;
}

// ---- porosity: point count inside the achieved keel envelope.
void measure_porosity(const RidgeDef& d, const std::vector<Placed>& placed, const HashGrid& fgrid,
                      const ProfileBins& bins, RidgeResult& res) {
  const double g = d.porosity_grid, pb = bins.pb;
  const RidgeProfile& pr = res.profile;
  std::uint64_t pts_all = 0, in_all = 0, pts_core = 0, in_core = 0;
  const std::int64_t nx = static_cast<std::int64_t>(std::floor((bins.xhi - bins.xlo) / g));
  const std::int64_t ny = static_cast<std::int64_t>(std::floor(d.length / g));
  for (std::int64_t ix = 0; ix < nx; ++ix) {
    const double x = bins.xlo + (static_cast<double>(ix) + 0.5) * g;
    const std::size_t bi = static_cast<std::size_t>(static_cast<std::int64_t>(std::floor(x / pb)) - bins.b0);
    if (bi >= bins.nb) continue;
    const double zb = -pr.keel_depth[bi], zt = -ice_draft(d, x);
    if (!(zb < zt)) continue;
    // Core: under the consolidated layer, upper 80 % of the local keel thickness (away
    // from the rough bottom, where the 95th-percentile envelope is mostly water).
    const bool core_x = std::abs(x) < 0.5 * d.consolidated_layer_width;
    const double zcore = zt + 0.8 * (zb - zt);
    for (std::int64_t iy = 0; iy < ny; ++iy) {
      const double y = (static_cast<double>(iy) + 0.5) * g;
      for (double z = zt - 0.5 * g; z > zb; z -= g) {
        const Vec3 q(x, y, z);
        bool inside = false;
        if (const auto* c = fgrid.cell_of(q))
          for (std::int32_t id : *c) {
            const Placed& p = placed[id];
            if (p.part != 0) continue;
            const Vec3 l = p.R.transpose() * (q - p.x);
            if (std::abs(l.x()) <= p.h.x() && std::abs(l.y()) <= p.h.y() && std::abs(l.z()) <= p.h.z()) {
              inside = true;
              break;
            }
          }
        ++pts_all;
        in_all += inside;
        if (core_x && z > zcore) ++pts_core, in_core += inside;
      }
    }
  }
  res.stats.keel_porosity = pts_all ? 1.0 - static_cast<double>(in_all) / static_cast<double>(pts_all) : 0.0;
  res.stats.core_porosity = pts_core ? 1.0 - static_cast<double>(in_core) / static_cast<double>(pts_core) : 0.0;
}

}  // namespace

void join_and_measure(const RidgeRun& run, const std::vector<Placed>& placed, double ke, RidgeResult& res) {
  const RidgeDef& d = run.d;
  const std::size_t n = placed.size();
  run.report("joints", res.stats.settle_time, ke, n);
  HashGrid fgrid(2.0);
  for (std::size_t i = 0; i < n; ++i)
    fgrid.insert(static_cast<std::int32_t>(i), placed[i].x - placed[i].aabb - Vec3::Constant(d.joints.gap),
                 placed[i].x + placed[i].aabb + Vec3::Constant(d.joints.gap));
  find_joints(d, placed, fgrid, res);
  run.report("measure", res.stats.settle_time, ke, n);
  const ProfileBins bins = measure_profile(run, placed, res);
  measure_porosity(d, placed, fgrid, bins, res);
}

}  // namespace hs::rigid::detail
