// Placement (docs/ridge.md, Method 3): the ice sheet, the target envelopes and the greedy
// deposition of the blocks into them. The generator's whole random stream is drawn here, in a
// fixed order, so a seed gives the same ridge bit for bit.
#include "ridge/internal.h"

#include "common/ice_formulas.h"

namespace hs::rigid::detail {

namespace {

/// Gap left between neighbouring plates and between a plate and the end walls, m: plates
/// that heave independently must not rub (friction) on each other.
constexpr double kPlateGap = 1e-3;

/// Target envelope (keel or sail) on a fine x grid: its thickness integrated over x gives the
/// volume and the distribution of block x positions.
struct Envelope {
  std::vector<double> xs, cdf;
  double volume = 0.0;  ///< m^3

  Envelope() = default;
  Envelope(const RidgeDef& d, bool keel, double hw) {
    const double dxs = 0.02;
    double lo = -hw, hi = hw;
    if (keel && !d.keel_profile.empty()) lo = d.keel_profile.front().position, hi = d.keel_profile.back().position;
    const int n = std::max(2, static_cast<int>(std::ceil((hi - lo) / dxs)));
    xs.resize(n + 1);
    cdf.assign(n + 1, 0.0);
    for (int i = 0; i <= n; ++i) xs[i] = lo + (hi - lo) * i / n;
    auto thick = [&](double x) {
      return keel ? std::max(0.0, keel_target_depth(d, x) - ice_draft(d, x))
                  : std::max(0.0, sail_target_height(d, x) - ice_freeboard(d, x));
    };
    for (int i = 1; i <= n; ++i)
      cdf[i] = cdf[i - 1] + 0.5 * (thick(xs[i - 1]) + thick(xs[i])) * (xs[i] - xs[i - 1]);
    volume = cdf.back() * d.length;
  }
  /// An x drawn with density proportional to the envelope thickness.
  double sample_x(Rng& rng) const {
    const double u = rng.uniform() * cdf.back();
    auto it = std::upper_bound(cdf.begin(), cdf.end(), u);
    const std::size_t i = std::clamp<std::size_t>(it - cdf.begin(), 1, cdf.size() - 1);
    const double c0 = cdf[i - 1], c1 = cdf[i];
    const double t = c1 > c0 ? (u - c0) / (c1 - c0) : 0.5;
    return xs[i - 1] + t * (xs[i] - xs[i - 1]);
  }
};

// ---- placement: non-overlapping piles hanging under / standing on the ice, packed by
// greedy deposition (docs/ridge.md, Method 3): every block tries placement_candidates
// poses, each translated along z from the ice to the first free position (exact: the
// z range where two boxes overlap is an interval, found with the 15 SAT axes), and keeps
// the one that ends least deep relative to the local target depth. Holes are filled
// before the pile grows, so the column starts denser (porosity ~0.6 instead of ~0.8)
// and shaped like the target, and the rise is short.
class Placement {
 public:
  Placement(RidgeRun& run, const Envelope& keel, const Envelope& sail)
      : run_(run), d_(run.d), keel_(keel), sail_(sail), gap_(run.d.joints.gap), h_blk_(run.d.block_thickness),
        zreach_(3.0 * std::max(run.d.keel_depth, run.d.sail_height) + 20.0 * run.d.block_thickness) {}

  /// Adds blocks to the keel (or sail) until their volume reaches volume_target; returns it.
  double fill(bool keel, double volume_target) {
    double vol = 0.0;
    while (vol < volume_target) {
      const double L = h_blk_ * std::exp(sample_ln_r(run_.rng, run_.lnm, run_.lns));
      const double B = L * run_.rng.uniform(d_.width_fraction_min, d_.width_fraction_max);
      Placed best;
      double best_score = std::numeric_limits<double>::infinity();
      for (int c = 0; c < d_.placement_candidates; ++c) {
        double score = 0.0;
        const Placed p = candidate(keel, L, B, score);
        if (score < best_score) best_score = score, best = p;
      }
      const std::int32_t id = static_cast<std::int32_t>(placed.size());
      placed.push_back(best);
      grid_.insert(id, best.x - best.aabb - Vec3::Constant(gap_), best.x + best.aabb + Vec3::Constant(gap_));
      vol += 8.0 * best.h.prod();
      if (placed.size() % 2000 == 0) run_.report("place", 0.0, 0.0, placed.size());
    }
    return vol;
  }

  std::vector<Placed> placed;

 private:
  /// One candidate pose of an L x B block, dropped from the ice to its first free position;
  /// score: how far it reaches into the envelope, as a fraction of the local thickness (the
  /// emptiest place wins; > 1: it sticks out of the envelope).
  Placed candidate(bool keel, double L, double B, double& score) {
    Rng& rng = run_.rng;
    Placed p;
    p.h = Vec3(0.5 * L, 0.5 * B, 0.5 * h_blk_);
    p.part = keel ? 0 : 1;
    const double x = (keel ? keel_ : sail_).sample_x(rng);
    if (d_.max_tilt_deg >= 90.0) {
      p.q = rng.rotation();
    } else {  // random yaw, then a tilt of U(0, max) about a random horizontal axis
      const double yaw = kTwoPi * rng.uniform(), az = kTwoPi * rng.uniform();
      const double tilt = d_.max_tilt_deg * kDeg * rng.uniform();
      p.q = Quat(Eigen::AngleAxisd(tilt, Vec3(std::cos(az), std::sin(az), 0.0))) *
            Quat(Eigen::AngleAxisd(yaw, Vec3::UnitZ()));
    }
    double y = rng.uniform();
    p.R = p.q.toRotationMatrix();
    p.aabb = aabb_half(p.h, p.R);
    const double ylo = p.aabb.y() + gap_, yhi = d_.length - p.aabb.y() - gap_;
    y = ylo < yhi ? ylo + y * (yhi - ylo) : 0.5 * d_.length;
    // Start just clear of the ice over the block's x range.
    const double xl = x - p.aabb.x(), xr = x + p.aabb.x();
    const bool over_cl = xl < 0.5 * run_.wcl && xr > -0.5 * run_.wcl;
    const double t_ice = over_cl ? d_.consolidated_layer_thickness : d_.level_ice_thickness;
    const double ice_z = keel ? -flotation_draft(t_ice, d_.ice_density, d_.water_density) - gap_ - p.aabb.z()
                              : flotation_freeboard(t_ice, d_.ice_density, d_.water_density) + gap_ + p.aabb.z();
    p.x = Vec3(x, y, ice_z);
    p.x.z() += free_shift(p, keel);
    const double reach_z = keel ? -(p.x.z() - p.aabb.z()) : p.x.z() + p.aabb.z();
    const double target = keel ? keel_target_depth(d_, x) : sail_target_height(d_, x);
    score = target > 0.0 ? reach_z / target : std::numeric_limits<double>::infinity();
    return p;
  }

  /// Highest (keel: t <= 0, moving down) / lowest (sail: t >= 0, moving up) shift t of p
  /// along z with no overlap (boxes inflated by gap/2 each).
  double free_shift(const Placed& p, bool keel) {
    const double gap = gap_;
    const Vec3 hp = p.h + Vec3::Constant(0.5 * gap);
    Vec3 lo = p.x - p.aabb - Vec3::Constant(gap), hi = p.x + p.aabb + Vec3::Constant(gap);
    if (keel) lo.z() -= zreach_;
    else hi.z() += zreach_;
    grid_.query(lo, hi, cand_);
    ivals_.clear();
    for (std::int32_t id : cand_) {
      const Placed& o = placed[id];
      const Vec3 dd = o.x - p.x;
      if (std::abs(dd.x()) > p.aabb.x() + o.aabb.x() + gap || std::abs(dd.y()) > p.aabb.y() + o.aabb.y() + gap)
        continue;
      const Vec3 ho = o.h + Vec3::Constant(0.5 * gap);
      // Overlap on axis L at shift t: |dd.L - t L_z| < r_L; intersect over the axes.
      double tlo = -std::numeric_limits<double>::infinity(), thi = std::numeric_limits<double>::infinity();
      auto axis = [&](const Vec3& L) {
        const double r = reach(hp, p.R, L) + reach(ho, o.R, L), c = dd.dot(L), a = L.z();
        if (std::abs(a) < 1e-12) {
          if (std::abs(c) >= r) tlo = thi = 0.0;  // separated for every t
          return;
        }
        double t0 = (c - r) / a, t1 = (c + r) / a;
        if (t0 > t1) std::swap(t0, t1);
        tlo = std::max(tlo, t0);
        thi = std::min(thi, t1);
      };
      for (int i = 0; i < 3 && tlo < thi; ++i) axis(p.R.col(i));
      for (int i = 0; i < 3 && tlo < thi; ++i) axis(o.R.col(i));
      for (int i = 0; i < 3 && tlo < thi; ++i)
        for (int k = 0; k < 3 && tlo < thi; ++k) {
          const Vec3 c = p.R.col(i).cross(o.R.col(k));
          const double nc = c.norm();
          if (nc >= 1e-6) axis(c / nc);
        }
      if (tlo < thi) ivals_.emplace_back(tlo, thi);
    }
    double t = 0.0;
    for (bool moved = true; moved;) {
      moved = false;
      for (const auto& [a, b] : ivals_)
        if (a < t && t < b) {
          t = keel ? a : b;
          moved = true;
        }
    }
    return t;
  }

  RidgeRun& run_;
  const RidgeDef& d_;
  const Envelope& keel_;
  const Envelope& sail_;
  const double gap_, h_blk_;
  const double zreach_;  ///< search depth, m
  HashGrid grid_{2.0};
  std::vector<std::int32_t> cand_;
  std::vector<std::pair<double, double>> ivals_;
};

}  // namespace

/// Ice sheet: level ice left/right, consolidated layer in the middle. Fixed boxes of the
/// solid slab, or (sheet.floating) plates of the run's sheet geometry, each part cut into
/// strips about plate_width wide.
void add_ice_sheet(RidgeRun& run, std::vector<IceBox>& ice) {
  const RidgeDef& d = run.d;
  run.kx = keel_half_width(d);
  run.sx = sail_half_width(d);
  run.ice_half = std::max(run.kx, run.sx) + d.level_ice_margin;
  run.wcl = std::min(2.0 * layer_half_width(d), 2.0 * run.ice_half);
  if (d.sheet.floating) {
    auto plates = [&](double x0, double x1, int part) {
      if (x1 - x0 <= 0.0) return;
      const double top = part == 1 ? d.sheet.layer_top : d.sheet.level_top;
      const double under = part == 1 ? d.sheet.layer_underside : d.sheet.level_underside;
      const int n = d.sheet.plate_width > 0.0
                        ? std::max(1, static_cast<int>(std::lround((x1 - x0) / d.sheet.plate_width)))
                        : 1;
      const double w = (x1 - x0) / n;
      for (int i = 0; i < n; ++i) {
        IceBox b;
        b.half_extents = Vec3(0.5 * (w - kPlateGap), 0.5 * (d.length - 2.0 * kPlateGap), 0.5 * (top - under));
        b.position = Vec3(x0 + (i + 0.5) * w, 0.5 * d.length, 0.5 * (top + under));
        b.part = part;
        ice.push_back(b);
      }
    };
    plates(-run.ice_half, -0.5 * run.wcl, 0);
    plates(-0.5 * run.wcl, 0.5 * run.wcl, 1);
    plates(0.5 * run.wcl, run.ice_half, 0);
    return;
  }
  auto ice_box = [&](double x0, double x1, double t, int part) {
    if (x1 - x0 <= 0.0) return;
    const double draft = flotation_draft(t, d.ice_density, d.water_density);
    IceBox b;
    b.half_extents = Vec3(0.5 * (x1 - x0), 0.5 * d.length, 0.5 * t);
    b.position = Vec3(0.5 * (x0 + x1), 0.5 * d.length, 0.5 * t - draft);
    b.part = part;
    ice.push_back(b);
  };
  ice_box(-run.ice_half, -0.5 * run.wcl, d.level_ice_thickness, 0);
  ice_box(-0.5 * run.wcl, 0.5 * run.wcl, d.consolidated_layer_thickness, 1);
  ice_box(0.5 * run.wcl, run.ice_half, d.level_ice_thickness, 0);
}

std::vector<Placed> place_blocks(RidgeRun& run, RidgeStats& st) {
  const RidgeDef& d = run.d;
  const Envelope keel(d, true, run.kx);
  const Envelope sail = d.sail_height > 0.0 ? Envelope(d, false, run.sx) : Envelope();
  st.keel_target_volume = keel.volume;
  Placement placement(run, keel, sail);
  st.keel_block_volume = placement.fill(true, (1.0 - d.fill_porosity) * keel.volume);
  st.sail_block_volume = sail.volume > 0.0 ? placement.fill(false, (1.0 - d.fill_porosity) * sail.volume) : 0.0;
  return std::move(placement.placed);
}

}  // namespace hs::rigid::detail
