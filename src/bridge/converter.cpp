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

namespace {

/// The block's mass M (kg) and volume V (m^3) after the input checks (docs/bridge.md).
struct BlockMass {
  double M = 0.0, V = 0.0;
};

BlockMass check_block(const bonded::Engine& engine, const BlockState& block, const IceMaterial& mat) {
  // Under MPI every rank runs the conversion on the same block (the rigid world is replicated)
  // and gets the same sites; the engine keeps each rank's share.
  if (!engine.parallel() && engine.particles().n_ghost != 0)
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
  const bonded::WaterParams& water = engine.def().water;
  if (water.enabled && water.model != mat.buoyancy)
    throw InputError("material/buoyancy",
                     "the engine's water uses a different buoyancy model from the converted ice's; the lattice "
                     "floats like the block only with the model it was made for (docs/bridge.md)");
  return {M, V};
}

/// The block's HCP lattice sites, equal layers, centroid on the block centre (steps 1, 1b, 2).
struct Lattice {
  std::vector<Vec3> sites;
  std::size_t trimmed = 0;  ///< sites removed to equalise the layers
  Vec3 shift = Vec3::Zero();  ///< centroid move onto the block centre
};

/// The block's pose with its orientation normalised, as the lattice is cut.
bonded::Pose lattice_pose(const BlockState& block) {
  bonded::Pose pose = block.pose;
  pose.orientation = block.pose.orientation.normalized();
  return pose;
}

/// The box hcp_fill_box fills for a block of half extents he (step 1 below).
Vec3 fill_half_extents(const Vec3& he, double D) { return {he.x() - 0.25 * D, he.y(), he.z()}; }

Lattice block_lattice(const Vec3& he, const bonded::Pose& pose, double D) {
  // ---- 1. lattice in the block's frame ----
  // hcp_fill_box starts each row D/2 inside the -x face and keeps centres up to the +x face,
  // so rows shifted by D/2 get a site ON each x face: one site too many per row, the lattice
  // overhanging the block by D/2 and its inertia about y and z ~10 % high (2 m x 1.5 m x 1 m,
  // D = 0.25 m). Insetting the fill box by D/4 in x leaves W/D sites in every row (W/D whole),
  // whose cells tile the block's width (docs/bridge.md).
  Lattice lat;
  std::vector<Vec3>& x = lat.sites;
  x = bonded::hcp_fill_box(fill_half_extents(he, D), pose, D);
  if (x.empty())
    throw InputError("block/half_extents", "no HCP site fits in the block " + vec_str(2.0 * he) +
                                               " m with D = " + std::to_string(D) + " m");
  // ---- 1b. same number of sites in every layer ----
  // A and B layers cut from a box can hold different counts; a solid block has the same area
  // at every height, and with Column buoyancy the waterline layer's count sets the waterplane
  // area, so trim every layer to the smallest count (hcp_equalize_layers).
  lat.trimmed = bonded::hcp_equalize_layers(x, pose, D);
  // ---- 2. centroid onto the block centre ----
  const Vec3 c = pose.position;
  Vec3 centroid = Vec3::Zero();
  for (const auto& p : x) centroid += p;
  centroid /= static_cast<double>(x.size());
  lat.shift = c - centroid;
  if (lat.shift.norm() > D)  // cannot happen for hcp_fill_box (margins < D/2 in-plane, < c/4 in z)
    throw std::logic_error("convert_block: lattice centroid is " + std::to_string(lat.shift.norm()) +
                           " m from the block centre, more than one lattice spacing");
  for (auto& p : x) p += lat.shift;
  return lat;
}


/// Step 1 with IceMaterial::world_lattice: the points of one HCP lattice fixed in the world
/// frame whose centres lie inside the block's box (its faces included). The lattice is hcp_fill_box's
/// pattern anchored at the origin: layer k at z = c k, row j at y = row j (+ row/3 in odd layers),
/// x = D i (+ D/2 in odd rows, + D/2 in odd layers), every point computed from its integer
/// indices alone, so that every block gets the same bits for the same point.
Lattice world_lattice(const Vec3& he, const bonded::Pose& pose, double D) {
  const double c = bonded::hcp_layer_spacing(D), row = 0.5 * std::sqrt(3.0) * D;
  const Mat3 R = pose.orientation.toRotationMatrix();
  const Vec3 ext = R.cwiseAbs() * he;  // half sizes of the box's world bounding box
  const Vec3 lo = pose.position - ext, hi = pose.position + ext;
  const auto first = [](double v, double h) { return static_cast<std::int64_t>(std::floor(v / h)) - 1; };
  const auto last = [](double v, double h) { return static_cast<std::int64_t>(std::ceil(v / h)) + 1; };
  const double eps = 1e-9 * D;
  Lattice lat;
  for (std::int64_t k = first(lo.z(), c); k <= last(hi.z(), c); ++k) {
    const bool b_layer = k % 2 != 0;
    for (std::int64_t j = first(lo.y(), row); j <= last(hi.y(), row); ++j) {
      const double x0 = (j % 2 != 0 ? 0.5 * D : 0.0) + (b_layer ? 0.5 * D : 0.0);
      const double y = row * static_cast<double>(j) + (b_layer ? row / 3.0 : 0.0);
      for (std::int64_t i = first(lo.x(), D); i <= last(hi.x(), D); ++i) {
        const Vec3 p(D * static_cast<double>(i) + x0, y, c * static_cast<double>(k));
        const Vec3 l = R.transpose() * (p - pose.position);
        if ((l.cwiseAbs() - he).maxCoeff() <= eps) lat.sites.push_back(p);
      }
    }
  }
  return lat;
}

/// Steps 1-2 as `mat` asks; throws hs::InputError when no site lies in the block.
Lattice make_lattice(const BlockState& block, const IceMaterial& mat) {
  const bonded::Pose pose = lattice_pose(block);
  if (!mat.world_lattice) return block_lattice(block.half_extents, pose, mat.diameter);
  Lattice lat = world_lattice(block.half_extents, pose, mat.diameter);  // (also lattice_sites')
  if (lat.sites.empty())
    throw InputError("block/half_extents", "no site of the world lattice lies in the block " +
                                               vec_str(2.0 * block.half_extents) + " m with D = " +
                                               std::to_string(mat.diameter) + " m");
  return lat;
}

/// Step 3: the sites that overlap no existing particle (on any rank), lie clear of the engine's
/// plane walls and that `blocked` leaves free.
std::vector<Vec3> free_sites(bonded::Engine& engine, const std::vector<Vec3>& x, double D, double test_radius,
                             const SiteBlocked& blocked, std::size_t& dropped) {
  const std::vector<char> drop = engine.overlapping_sites(x, std::vector<double>(x.size(), test_radius));
  dropped = 0;
  std::vector<Vec3> kept;
  kept.reserve(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) {
    if (drop[i] || behind_a_wall(engine, x[i], 0.5 * D) || (blocked && blocked(x[i], 0.5 * D)))
      ++dropped;
    else
      kept.push_back(x[i]);
  }
  if (kept.empty())
    throw InputError("block", "every lattice site of the block overlaps existing particles, another block or a plane wall; nothing to convert");
  return kept;
}

/// Step 5: the particles' common angular velocity, which carries the block's angular momentum
/// about their centre of mass cp (equal there, since both carry M v).
struct LatticeMotion {
  Vec3 cp = Vec3::Zero();   ///< centre of mass of the kept sites
  Mat3 Ib = Mat3::Zero();   ///< the block's inertia tensor (world frame)
  Vec3 wp = Vec3::Zero();   ///< the particles' angular velocity
};

LatticeMotion lattice_motion(const std::vector<Vec3>& kept, double m, double Is, const BlockState& block,
                             const Quat& orientation, double M) {
  const double n = static_cast<double>(kept.size());
  const Vec3 c = block.pose.position;
  LatticeMotion lm;
  Vec3 cp = Vec3::Zero();
  for (const auto& p : kept) cp += p;
  cp /= n;
  Mat3 Ip = Mat3::Zero();
  for (const auto& p : kept) {
    const Vec3 ri = p - cp;
    Ip += m * (ri.squaredNorm() * Mat3::Identity() - ri * ri.transpose());
  }
  Ip += n * Is * Mat3::Identity();
  lm.cp = cp;
  lm.Ib = box_inertia_world(block.half_extents, orientation, M);
  const Vec3& v = block.velocity;
  const Vec3& w = block.angular_velocity;
  const Vec3 L_cp = lm.Ib * w + (c - cp).cross(M * v);
  lm.wp = Ip.ldlt().solve(L_cp);
  return lm;
}

/// Attachments: each to the nearest kept site not yet bonded to the same particle (first in
/// site order on a tie); the kept sites are the same on every rank, so is the choice. None when
/// that site is more than 1.5 D from the attachment point (the sites there were dropped): a
/// bond that long would not be a freeze bond, and under MPI it would widen every rank's halo.
/// Returns the number left unattached.
std::size_t attach_sites(const std::vector<Attachment>& attach, const std::vector<Vec3>& kept, double D,
                         bonded::LatticeInsert& lat) {
  std::size_t unattached = 0;
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
    lat.attach.push_back({a.particle, best, bonded::BondKind::Freeze});
  }
  return unattached;
}

/// What the engine holds of the new particles, measured on them (summed over the ranks).
struct InsertedMotion {
  Vec3 P = Vec3::Zero(), L = Vec3::Zero();
  double ke = 0.0, count = 0.0;
};

InsertedMotion measure_inserted(bonded::Engine& engine, std::size_t n_old, const bonded::LatticeInsertReport& ins,
                                double Is) {
  const bonded::ParticleStore& ps = engine.particles();
  InsertedMotion r;
  auto add = [&](std::size_t i) {
    r.P += ps.mass[i] * ps.v[i];
    r.L += ps.x[i].cross(ps.mass[i] * ps.v[i]) + Is * ps.omega[i];
    r.ke += 0.5 * ps.mass[i] * ps.v[i].squaredNorm() + 0.5 * Is * ps.omega[i].squaredNorm();
    r.count += 1.0;
  };
  if (!engine.parallel()) {
    for (std::size_t i = n_old; i < ps.size(); ++i) add(i);
    return r;
  }
  const GlobalId end = ins.first_gid + ins.particles_created;
  for (std::size_t i = 0; i < ps.owned(); ++i)
    if (ps.gid[i] >= ins.first_gid && ps.gid[i] < end) add(i);
  // Reduced on rank 0 and broadcast: the replicated rigid side may act on these figures, so
  // every rank must hold the same bits.
  double sums[8] = {r.P.x(), r.P.y(), r.P.z(), r.L.x(), r.L.y(), r.L.z(), r.ke, r.count};
  engine.comm().sum_same_everywhere(sums, 8);
  r.P = Vec3(sums[0], sums[1], sums[2]);
  r.L = Vec3(sums[3], sums[4], sums[5]);
  r.ke = sums[6];
  r.count = sums[7];
  return r;
}

}  // namespace

/// Whether a sphere of radius r at `site` lies behind or touches one of the engine's plane walls.
/// Rigid blocks do not meet those walls and may reach past them (a keel under an end or symmetry
/// wall); a particle there would start metres deep in the wall.
bool behind_a_wall(const bonded::Engine& engine, const Vec3& site, double r) {
  for (const bonded::PlaneWall& w : engine.walls())
    if ((site - w.point).dot(w.normal) < r) return true;
  return false;
}

std::vector<Vec3> lattice_sites(const BlockState& block, double D) {
  return block_lattice(block.half_extents, lattice_pose(block), D).sites;
}

std::vector<Vec3> lattice_sites(const BlockState& block, const IceMaterial& material) {
  if (material.world_lattice) return world_lattice(block.half_extents, lattice_pose(block), material.diameter).sites;
  return block_lattice(block.half_extents, lattice_pose(block), material.diameter).sites;
}

double site_test_radius(const IceMaterial& material) {
  return material.world_lattice ? 0.5 * material.diameter * (1.0 - 1e-9) : 0.5 * material.diameter;
}

bool lattice_fits(const Vec3& he, double D) {
  if (!(D > 0.0) || !finite(he) || !(he.minCoeff() > 0.0) || 2.0 * he.minCoeff() < D) return false;
  return !bonded::hcp_fill_box(fill_half_extents(he, D), bonded::Pose{}, D).empty();
}

ConversionReport convert_block(bonded::Engine& engine, const BlockState& block, const IceMaterial& mat,
                               const SiteBlocked& blocked, const std::vector<Attachment>& attach) {
  using namespace hs::bonded;
  const bool distributed = engine.parallel();
  ParticleStore& ps = engine.particles();
  const auto [M, V] = check_block(engine, block, mat);
  const double D = mat.diameter;

  // ---- 1, 2: the lattice; 3: the sites left free ----
  const Pose pose = lattice_pose(block);
  const Lattice lattice = make_lattice(block, mat);
  std::size_t dropped = 0;
  std::vector<Vec3> kept = free_sites(engine, lattice.sites, D, site_test_radius(mat), blocked, dropped);

  // ---- 4. mass and buoyant volume ----
  const double n = static_cast<double>(kept.size());
  const double m = M / n, Vb = V / n, r = 0.5 * D;
  const double Is = 0.4 * m * r * r;  // sphere inertia, as ParticleStore sets it

  // ---- 5. momentum ----
  const LatticeMotion lm = lattice_motion(kept, m, Is, block, pose.orientation, M);
  const Vec3 c = pose.position, cp = lm.cp;
  const Vec3& v = block.velocity;
  const Vec3& w = block.angular_velocity;

  ConversionReport rep;
  rep.first = distributed ? ConversionReport::kNoIndex : ps.size();
  rep.particles_dropped = dropped;
  rep.sites_trimmed = lattice.trimmed;
  rep.mass = M;
  rep.volume = V;
  rep.lattice_shift = lattice.shift;
  rep.com_shift = cp - c;
  rep.linear_momentum_before = M * v;
  rep.angular_momentum_before = lm.Ib * w + c.cross(M * v);
  rep.kinetic_energy_before = 0.5 * M * v.squaredNorm() + 0.5 * w.dot(lm.Ib * w);

  // ---- 6. particles and their lattice bonds (each rank keeps those in its box) ----
  LatticeInsert lat;
  lat.sites.reserve(kept.size());
  for (const auto& p : kept) {
    ParticleInit pi;
    pi.x = p;
    pi.v = v + lm.wp.cross(p - cp);
    pi.omega = lm.wp;
    pi.q = pose.orientation;
    pi.radius = r;
    pi.mass = m;
    pi.buoyant_volume = Vb;
    pi.material = mat.material;
    lat.add_site(pi);
  }
  lat.bonds = touching_pairs(kept, std::vector<double>(kept.size(), r));
  lat.kind = BondKind::Lattice;
  const std::size_t unattached = attach_sites(attach, kept, D, lat);
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

  // ---- what the engine now holds, measured on the particles ----
  const InsertedMotion after = measure_inserted(engine, n_old, ins, Is);
  if (after.count != static_cast<double>(kept.size()))
    throw std::logic_error("convert_block: " + std::to_string(after.count) + " particles inserted for " +
                           std::to_string(kept.size()) + " lattice sites");
  rep.particles_created = kept.size();
  rep.linear_momentum_after = after.P;
  rep.angular_momentum_after = after.L;
  rep.kinetic_energy_after = after.ke;
  rep.sites = std::move(kept);
  return rep;
}

}  // namespace hs::bridge
