#include "converter.h"

#include "common/error.h"

#include <cmath>
#include <algorithm>
#include <cstdint>
#include <limits>
#include <map>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

namespace hs::bridge {

namespace {

bool finite(const Vec3& v) { return v.allFinite(); }

std::string vec_str(const Vec3& v) {
  return "(" + std::to_string(v.x()) + ", " + std::to_string(v.y()) + ", " + std::to_string(v.z()) + ")";
}

}  // namespace

Mat3 box_inertia_world(const Vec3& he, const Quat& orientation, double mass) {
  const Vec3 s = he.cwiseProduct(he);
  const Vec3 d(mass / 3.0 * (s.y() + s.z()), mass / 3.0 * (s.x() + s.z()), mass / 3.0 * (s.x() + s.y()));
  const Mat3 R = orientation.normalized().toRotationMatrix();
  return R * d.asDiagonal() * R.transpose();
}

ConversionReport convert_block(bonded::Engine& engine, const BlockState& block, const IceMaterial& mat,
                               const SiteBlocked& blocked, const std::vector<Attachment>& attach) {
  using namespace hs::bonded;
  // ---- input checks ----
  // Under MPI every rank runs all of this on the same block (the rigid world is replicated)
  // and gets the same sites; the engine keeps each rank's share.
  const bool distributed = engine.parallel();
  ParticleStore& ps = engine.particles();
  if (!distributed && ps.n_ghost != 0)
    throw std::logic_error("convert_block: a serial engine holding ghost particles");
  const double D = mat.diameter;
  if (!(D > 0.0) || !std::isfinite(D))
    throw InputError("material/diameter", "particle diameter must be positive and finite, got " + std::to_string(D));
  const Vec3& he = block.half_extents;
  if (!finite(he) || !(he.minCoeff() > 0.0))
    throw InputError("block/half_extents", "half extents must be positive and finite, got " + vec_str(he));
  if (2.0 * he.minCoeff() < D)
    throw InputError("block/half_extents",
                     "the block " + vec_str(2.0 * he) + " m is thinner than one particle (D = " + std::to_string(D) +
                         " m) along some axis; use a smaller particle diameter or keep the block rigid");
  if (!finite(block.pose.position) || !finite(block.velocity) || !finite(block.angular_velocity))
    throw InputError("block", "position, velocity and angular velocity must be finite");
  const Quat& q0 = block.pose.orientation;
  if (!q0.coeffs().allFinite() || !(q0.norm() > 1e-12))
    throw InputError("block/orientation", "orientation quaternion must be finite and non-zero");
  const double V = 8.0 * he.x() * he.y() * he.z();
  double M = block.mass;
  if (M > 0.0) {
    if (!std::isfinite(M)) throw InputError("block/mass", "mass must be finite");
    if (block.density > 0.0 && std::abs(block.density * V - M) > 1e-9 * M)
      throw InputError("block", "mass " + std::to_string(M) + " kg and density " + std::to_string(block.density) +
                                    " kg/m^3 x volume " + std::to_string(V) + " m^3 disagree; give one of them");
  } else {
    if (block.mass < 0.0 || !(block.density > 0.0) || !std::isfinite(block.density))
      throw InputError("block", "give a positive mass (kg) or density (kg/m^3); got mass " +
                                    std::to_string(block.mass) + ", density " + std::to_string(block.density));
    M = block.density * V;
  }
  const WaterParams& water = engine.def().water;
  if (water.enabled && water.model != mat.buoyancy)
    throw InputError("material/buoyancy",
                     "the engine's water uses a different buoyancy model from the converted ice's; the lattice "
                     "floats like the block only with the model it was made for (docs/bridge.md)");

  // ---- 1. lattice in the block's frame ----
  Pose pose = block.pose;
  pose.orientation = q0.normalized();
  // hcp_fill_box starts each row D/2 inside the -x face and keeps centres up to the +x face,
  // so rows shifted by D/2 get a site ON each x face: one site too many per row, the lattice
  // overhanging the block by D/2 and its inertia about y and z ~10 % high (2 m x 1.5 m x 1 m,
  // D = 0.25 m). Insetting the fill box by D/4 in x leaves W/D sites in every row (W/D whole),
  // whose cells tile the block's width (docs/bridge.md).
  const Vec3 he_fill(he.x() - 0.25 * D, he.y(), he.z());
  std::vector<Vec3> x = hcp_fill_box(he_fill, pose, D);
  if (x.empty())
    throw InputError("block/half_extents", "no HCP site fits in the block " + vec_str(2.0 * he) +
                                               " m with D = " + std::to_string(D) + " m");

  // ---- 1b. same number of sites in every layer ----
  // A and B layers cut from a box can hold different counts; a solid block has the same area
  // at every height, and with Column buoyancy the waterline layer's count sets the waterplane
  // area, so trim every layer to the smallest count (hcp_equalize_layers).
  const std::size_t trimmed = hcp_equalize_layers(x, pose, D);

  // ---- 2. centroid onto the block centre ----
  const Vec3 c = pose.position;
  Vec3 centroid = Vec3::Zero();
  for (const auto& p : x) centroid += p;
  centroid /= static_cast<double>(x.size());
  const Vec3 shift = c - centroid;
  if (shift.norm() > D)  // cannot happen for hcp_fill_box (margins < D/2 in-plane, < c/4 in z)
    throw std::logic_error("convert_block: lattice centroid is " + std::to_string(shift.norm()) +
                           " m from the block centre, more than one lattice spacing");
  for (auto& p : x) p += shift;

  // ---- 3. drop sites overlapping existing particles (on any rank) ----
  const std::vector<char> drop = engine.overlapping_sites(x, std::vector<double>(x.size(), 0.5 * D));
  std::size_t dropped = 0;
  std::vector<Vec3> kept;
  kept.reserve(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) {
    if (drop[i] || (blocked && blocked(x[i], 0.5 * D)))
      ++dropped;
    else
      kept.push_back(x[i]);
  }
  if (kept.empty())
    throw InputError("block", "every lattice site of the block overlaps existing particles; nothing to convert");

  // ---- 4. mass and buoyant volume ----
  const double n = static_cast<double>(kept.size());
  const double m = M / n, Vb = V / n, r = 0.5 * D;
  const double Is = 0.4 * m * r * r;  // sphere inertia, as ParticleStore sets it

  // ---- 5. momentum ----
  Vec3 cp = Vec3::Zero();
  for (const auto& p : kept) cp += p;
  cp /= n;
  Mat3 Ip = Mat3::Zero();
  for (const auto& p : kept) {
    const Vec3 ri = p - cp;
    Ip += m * (ri.squaredNorm() * Mat3::Identity() - ri * ri.transpose());
  }
  Ip += n * Is * Mat3::Identity();
  const Mat3 Ib = box_inertia_world(he, pose.orientation, M);
  const Vec3& v = block.velocity;
  const Vec3& w = block.angular_velocity;
  // Block's angular momentum about c' (equals the particles' there, since both carry M v).
  const Vec3 L_cp = Ib * w + (c - cp).cross(M * v);
  const Vec3 wp = Ip.ldlt().solve(L_cp);

  ConversionReport rep;
  rep.first = distributed ? ConversionReport::kNoIndex : ps.size();
  rep.particles_dropped = dropped;
  rep.sites_trimmed = trimmed;
  rep.mass = M;
  rep.volume = V;
  rep.lattice_shift = shift;
  rep.com_shift = cp - c;
  rep.linear_momentum_before = M * v;
  rep.angular_momentum_before = Ib * w + c.cross(M * v);
  rep.kinetic_energy_before = 0.5 * M * v.squaredNorm() + 0.5 * w.dot(Ib * w);

  // ---- 6. particles and their lattice bonds (each rank keeps those in its box) ----
  LatticeInsert lat;
  lat.sites.reserve(kept.size());
  for (const auto& p : kept) {
    ParticleInit pi;
    pi.x = p;
    pi.v = v + wp.cross(p - cp);
    pi.omega = wp;
    pi.q = pose.orientation;
    pi.radius = r;
    pi.mass = m;
    pi.buoyant_volume = Vb;
    pi.material = mat.material;
    lat.add_site(pi);  // (out of line: see LatticeInsert::add_site)
  }
  lat.bonds = touching_pairs(kept, std::vector<double>(kept.size(), r));
  lat.kind = BondKind::Lattice;
  // Attachments: each to the nearest kept site not yet bonded to the same particle (first in
  // site order on a tie); the kept sites are the same on every rank, so is the choice. None when
  // that site is more than 1.5 D from the attachment point (the sites there were dropped): a
  // bond that long would not be a freeze bond, and under MPI it would widen every rank's halo.
  std::size_t unattached = 0;
  {
    std::set<std::pair<GlobalId, std::uint32_t>> taken;
    for (const Attachment& a : attach) {
      std::uint32_t best = 0;
      double best_d2 = std::numeric_limits<double>::infinity();
      for (std::uint32_t k = 0; k < kept.size(); ++k) {
        const double d2 = (kept[k] - a.point).squaredNorm();
        if (d2 < best_d2 && !taken.count({a.particle, k})) {
          best_d2 = d2;
          best = k;
        }
      }
      if (!(best_d2 <= 2.25 * D * D)) {  // (also: every site already bonded to this particle)
        ++unattached;
        continue;
      }
      taken.insert({a.particle, best});
      lat.attach.push_back({a.particle, best, BondKind::Freeze});
    }
  }
  lat.drop_overlapping = false;  // done above: the masses and velocities depend on what is kept
  const std::size_t n_old = ps.size();
  if (!distributed) ps.reserve(n_old + kept.size());
  const LatticeInsertReport ins = engine.insert_lattice(lat);
  rep.first_gid = ins.first_gid;
  rep.bonds_created = ins.bonds_created;
  rep.bonds_attached = ins.attached;
  rep.attachments_skipped = unattached;
  rep.orientation = pose.orientation.normalized();  // as the store keeps it
  rep.radius = r;

  // ---- what the engine now holds, measured on the particles (summed over the ranks) ----
  Vec3 P = Vec3::Zero(), L = Vec3::Zero();
  double ke = 0.0, count = 0.0;
  auto add = [&](std::size_t i) {
    P += ps.mass[i] * ps.v[i];
    L += ps.x[i].cross(ps.mass[i] * ps.v[i]) + Is * ps.omega[i];
    ke += 0.5 * ps.mass[i] * ps.v[i].squaredNorm() + 0.5 * Is * ps.omega[i].squaredNorm();
    count += 1.0;
  };
  if (!distributed) {
    for (std::size_t i = n_old; i < ps.size(); ++i) add(i);
  } else {
    const GlobalId end = ins.first_gid + ins.particles_created;
    for (std::size_t i = 0; i < ps.owned(); ++i)
      if (ps.gid[i] >= ins.first_gid && ps.gid[i] < end) add(i);
    // Reduced on rank 0 and broadcast: the replicated rigid side may act on these figures, so
    // every rank must hold the same bits.
    double sums[8] = {P.x(), P.y(), P.z(), L.x(), L.y(), L.z(), ke, count};
    engine.comm().sum_same_everywhere(sums, 8);
    P = Vec3(sums[0], sums[1], sums[2]);
    L = Vec3(sums[3], sums[4], sums[5]);
    ke = sums[6];
    count = sums[7];
  }
  if (count != static_cast<double>(kept.size()))
    throw std::logic_error("convert_block: " + std::to_string(count) + " particles inserted for " +
                           std::to_string(kept.size()) + " lattice sites");
  rep.particles_created = kept.size();
  rep.linear_momentum_after = P;
  rep.angular_momentum_after = L;
  rep.kinetic_energy_after = ke;
  rep.sites = std::move(kept);
  return rep;
}

}  // namespace hs::bridge
