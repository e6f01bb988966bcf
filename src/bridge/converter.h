// Block -> particle converter (docs/bridge.md): turns a rigid ice block into a bonded HCP
// lattice of particles inside an hs::bonded::Engine (serial or distributed over MPI ranks),
// conserving the block's mass, displaced volume, linear momentum and angular momentum exactly.
//
// Method, in order:
//   1. Lattice: hs::bonded::hcp_fill_box(half_extents - (D/4, 0, 0), pose, D) in the block's own
//      frame (the x inset gives every in-plane row W/D sites instead of W/D + 1, see the .cpp);
//      every layer is then trimmed to the smallest layer's count (a solid block has the same
//      area at every height; with Column buoyancy the waterline layer sets the waterplane).
//   2. Centre of mass: the lattice is translated by s = c - (mean of the centres) so its
//      centroid sits on the block centre c (|s| < D always for a box; larger is refused).
//   3. Overlap: a new centre closer than r_j + D/2 to an existing particle j (i.e. in contact
//      overlap with it), or closer than D/2 to one of the engine's plane walls or behind it, is
//      dropped, so no contact spring starts compressed; the count is reported. Nothing is
//      shifted after this step.
//   4. Mass and buoyancy: each kept particle gets m = M/n and V_b = V_block/n (n kept): the
//      lattice weighs exactly M and displaces exactly V_block (docs/bridge.md, vs rho_i V_cell).
//   5. Momentum: with c' the kept particles' centre of mass and r_i = x_i - c',
//        v_i = v + omega' x r_i,  omega_i = omega',  where  (sum_i m_i (|r_i|^2 1 - r_i r_i^T) + sum_i I_i 1) omega' = I_block omega + M (c - c') x v,
//      I_block = R diag(M/3 (b^2+c^2), ...) R^T. Linear momentum is M v and angular momentum
//      about any point equals the block's (sum m_i r_i = 0). Kinetic energy is not conserved in
//      general (the lattice's inertia differs from the box's); the change is reported.
//   6. Insertion: the kept sites and their lattice bonds (every pair D apart, BondKind::Lattice,
//      stress free) go into the engine through Engine::insert_lattice, with a freeze bond from
//      each attachment's particle to its nearest kept site (chosen from the replicated site
//      list, so every rank chooses alike).
// Global ids come from the engine's counter: same engine state and inputs, same ids.
//
// Under MPI (docs/parallel.md, "Conversion under MPI") every rank calls convert_block with the
// same block (the rigid world is replicated) and computes the same sites; the overlap test runs
// against every rank's particles (one reduction), and Engine::insert_lattice keeps on each rank
// the particles in its box and the bonds whose lower id it owns. Ids do not depend on the rank
// count; the report's figures are summed over the ranks and identical on every rank.
#pragma once

#include "bonded/engine.h"
#include "bonded/hcp_lattice.h"

#include <cstddef>
#include <functional>
#include <vector>

namespace hs::bridge {

/// State of the rigid block at the moment of conversion (world frame, SI units).
struct BlockState {
  Vec3 half_extents{0.5, 0.5, 0.5};   ///< m, all > 0
  bonded::Pose pose;                  ///< centre (m) and orientation (body -> world)
  Vec3 velocity = Vec3::Zero();       ///< of the centre, m/s
  Vec3 angular_velocity = Vec3::Zero();  ///< world frame, rad/s
  double density = 0.0;               ///< rho_i, kg/m^3 (used when mass == 0)
  double mass = 0.0;                  ///< M, kg; > 0 overrides density (both set: must agree)
};

/// The particle material the block becomes.
struct IceMaterial {
  double diameter = 0.5;              ///< D, m
  /// Buoyancy model the lattice is meant for; must match the engine's water model when the
  /// engine has water (Column: the lattice floats like the solid, docs/engine.md).
  bonded::BuoyancyModel buoyancy = bonded::BuoyancyModel::Column;
  bonded::MaterialIndex material = 0;
  /// How the sites are cut (docs/bridge.md, "One lattice for a keel converted at once"): false
  /// (default) from the block's own lattice, aligned with its faces (steps 1, 1b, 2 below); true
  /// from one HCP lattice fixed in the world frame, the same points for every block, keeping the
  /// sites whose centres lie inside the block (no layer trimming, no centroid shift). Blocks
  /// converted with it fill their union like one lattice: where two boxes touch, their particles
  /// meet at lattice spacing, with neither the gap nor the overlap two face-aligned lattices leave
  /// (all_at_start's reference keel, `blocks.lattice` = "world").
  bool world_lattice = false;
};

/// The radius convert_block tests a site's sphere with against existing particles: D/2, or for a
/// world lattice a hair less (1e-9 relative), so that two sites of that lattice one spacing apart,
/// whose distance rounds either side of D, count as touching, not overlapping.
double site_test_radius(const IceMaterial& material);

/// An existing particle to freeze-bond (BondKind::Freeze, stress free) to the new particle
/// nearest `point`, e.g. a block-particle bond that held the converted block, `point` its block
/// end; a new particle already bonded to the same particle is passed over for the next nearest,
/// and none is bonded when the nearest is more than 1.5 D from `point` (counted).
struct Attachment {
  GlobalId particle = 0;
  Vec3 point = Vec3::Zero();  ///< world, m
};

struct ConversionReport {
  static constexpr std::size_t kNoIndex = ~std::size_t{0};
  /// Serial: index of the first new particle in the store, the new ones being
  /// [first, first + particles_created). Under MPI kNoIndex: they are spread over the ranks and
  /// the store is re-sorted; find them by id.
  std::size_t first = 0;
  std::size_t particles_created = 0;  ///< over all ranks
  std::size_t particles_dropped = 0;  ///< lattice sites dropped for overlapping existing particles
  std::size_t sites_trimmed = 0;      ///< lattice sites trimmed to give every layer the same count
  std::size_t bonds_created = 0;     ///< lattice bonds among the new particles
  std::size_t bonds_attached = 0;    ///< freeze bonds made from the attachments
  std::size_t attachments_skipped = 0;  ///< attachments with no kept site within 1.5 D
  GlobalId first_gid = 0;     ///< ids are first_gid, first_gid + 1, ... in lattice-site order
  /// The new particles as inserted, on every rank alike (whichever rank owns each): centre of
  /// the particle with id first_gid + k, and the orientation and radius of all.
  std::vector<Vec3> sites;
  Quat orientation = Quat::Identity();
  double radius = 0.0;
  double mass = 0.0;                  ///< M, kg (= sum of the new particles' masses)
  double volume = 0.0;                ///< V_block, m^3 (= sum of their buoyant volumes)
  Vec3 lattice_shift = Vec3::Zero();  ///< translation applied to the lattice (step 2), m
  Vec3 com_shift = Vec3::Zero();      ///< final centre of mass of the particles - block centre, m
  Vec3 linear_momentum_before = Vec3::Zero(), linear_momentum_after = Vec3::Zero();    ///< kg m/s
  /// About the world origin, kg m^2/s.
  Vec3 angular_momentum_before = Vec3::Zero(), angular_momentum_after = Vec3::Zero();
  double kinetic_energy_before = 0.0, kinetic_energy_after = 0.0;  ///< J
};

/// Inertia tensor (world frame, about its centre) of a solid box of mass M, kg m^2.
Mat3 box_inertia_world(const Vec3& half_extents, const Quat& orientation, double mass);

/// Whether convert_block can make a lattice of a block of these half extents at diameter D: not
/// thinner than one particle along any axis and at least one HCP site inside (the shape checks
/// of convert_block, which refuses the block otherwise; overlaps are not considered).
bool lattice_fits(const Vec3& half_extents, double D);

/// Whether a sphere of radius r at `site` lies behind or touches one of the engine's plane walls
/// (convert_block drops such sites).
bool behind_a_wall(const bonded::Engine& engine, const Vec3& site, double r);

/// The lattice sites convert_block starts from for `block` at diameter D (steps 1, 1b, 2 below:
/// before any site is dropped for an overlap), bit for bit. Throws hs::InputError when
/// !lattice_fits.
std::vector<Vec3> lattice_sites(const BlockState& block, double D);
/// The same for `material` (its diameter, and the world lattice when it asks for one; then empty,
/// not a throw, when no site of it lies in the block).
std::vector<Vec3> lattice_sites(const BlockState& block, const IceMaterial& material);

/// Optional extra obstacle test for lattice sites: true drops the site (e.g. it would start inside
/// another rigid block). Called with the site centre and the particle radius D/2; under MPI it
/// must give the same answer on every rank (it sees replicated data, e.g. the rigid world).
using SiteBlocked = std::function<bool(const Vec3& site, double radius)>;
/// Converts `block` into bonded particles added to `engine`, serial or distributed (then
/// collective: every rank passes the same block, material and attachments; an attachment's
/// particle may live on any rank). Throws hs::InputError (path "block" or "material") on bad
/// input, on every rank alike, and adds nothing then.
ConversionReport convert_block(bonded::Engine& engine, const BlockState& block, const IceMaterial& material,
                               const SiteBlocked& blocked = {}, const std::vector<Attachment>& attach = {});

}  // namespace hs::bridge
