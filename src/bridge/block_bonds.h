// Freeze bonds between rigid blocks and particles (docs/bridge.md, "Block–particle freeze
// bonds"): e.g. a keel block frozen to the consolidated layer, or what a block's freeze joints
// become when the block they held converts into particles.
//
// Method. A bond joins particle i to a material point of block b, fixed in the block's frame
// when the bond is made: the centre of a *virtual particle* of i's radius r that touches the
// block's surface from inside, at the point p_s of the surface closest to i (x_v = p_s - r n,
// n the outward unit normal at p_s towards i). The bond is the SAME parallel bond as between
// two particles (bond_parallel.h), evaluated with the block end as that virtual particle moving
// rigidly with the block:
//   x_j = c_b + q_b a,   q_j = q_b,   v_j = v_b + w_b x (x_j - c_b),   w_j = w_b
// (a: the anchor in the block frame). The reference state (BondRef::at_rest with radii r, r) is
// taken in the configuration where the bond is made, so it starts stress free; for a particle
// touching the face the bond centre is p_s. Parameters: the engine's BondKind::Freeze bond
// (EngineDef::bond[1]): the stiffness of a particle-particle freeze bond, its own strengths.
// The force on the particle is -F_j (owned particles only); its reaction F_j at x_j and the
// moment (x_j - c_b) x F_j + T_j about the block centre accumulate, times the step's history_dt
// (0 in Engine::compute_forces(), which adds nothing), as impulses on the block, taken by the
// hybrid system at each rigid step (take_impulses). A bond breaks when sigma > sigma_c
// (tension) or tau > tau_c (shear): from then on it exerts nothing.
//
// Blocks are slots of a table the caller owns the numbering of (e.g. the hybrid system's
// initial block order); their state is plain kinematic data the caller sets before each DEM
// step (set_block), no rigid-world types.
//
// MPI rule: the bond list is replicated (built identically on every rank before
// Engine::distribute()); a bond is evaluated only by the rank that owns its particle (looked up
// by global id every evaluation, so reordering and migration are harmless), so its impulse is
// that rank's share and the caller sums impulses over ranks (ImpulseCoupler). A break is seen
// first by the owner; sync_broken() (collective, at each rigid step) removes broken bonds from
// every rank's copy. Bonds made after distribute() must be made alike on every rank, from
// replicated data (add_bond_to, bond_joint_to_particles with a conversion's site list).
#pragma once

#include "bonded/engine.h"
#include "bridge/converter.h"
#include "parallel/comm.h"

#include <cstddef>
#include <cstdint>
#include <vector>

namespace hs::bridge {

/// Kinematic state of a rigid block as the particles see it (world frame, SI units).
struct BlockBody {
  Vec3 position = Vec3::Zero();          ///< centre of mass, m
  Quat orientation = Quat::Identity();   ///< body -> world
  Vec3 velocity = Vec3::Zero();          ///< of the centre, m/s
  Vec3 angular_velocity = Vec3::Zero();  ///< world frame, rad/s
  Vec3 half_extents{0.5, 0.5, 0.5};      ///< box, m (for making bonds)
};

/// One block–particle bond.
struct BlockParticleBond {
  GlobalId gid = 0;             ///< the particle
  std::uint32_t block = 0;      ///< slot in the block table
  Vec3 anchor = Vec3::Zero();   ///< virtual particle centre, block frame, m
  bonded::BondRef ref;          ///< i = particle, j = virtual particle
  bool broken = false;          ///< broken, awaiting sync_broken()
};

/// A bond handed back by release_block(): the particle and where the block end was.
struct ReleasedBond {
  GlobalId gid = 0;
  Vec3 anchor = Vec3::Zero();   ///< virtual particle centre in the world, m
};

struct BlockBondStats {
  /// On this rank, since the start; broken - broken_tension - broken_shear broke in compression.
  std::uint64_t broken = 0, broken_tension = 0, broken_shear = 0;
};

class BlockParticleBonds final : public bonded::ForceSource {
 public:
  /// Sets (and grows the table to hold) block slot `block`. Call before each DEM step with the
  /// block's pose at the time the step's forces are evaluated.
  void set_block(std::uint32_t block, const BlockBody& body);
  const BlockBody& block(std::uint32_t k) const { return blocks_.at(k); }
  std::size_t block_count() const { return blocks_.size(); }

  /// Bonds particle `gid` to block `block` in the current configuration (stress free): the
  /// anchor is the virtual particle at the block surface point closest to the particle.
  /// Throws std::invalid_argument for an unknown particle or block, or a particle centre
  /// inside the block.
  void add_bond(const bonded::ParticleStore& ps, GlobalId gid, std::uint32_t block);
  /// Bonds particle `index` of `ps` to `block` through the given world surface point of the
  /// block and outward unit normal there: the virtual particle is at surface_point - r normal.
  void add_bond_at(const bonded::ParticleStore& ps, std::size_t index, std::uint32_t block,
                   const Vec3& surface_point, const Vec3& normal);

  /// Bonds the owned particles lying against the face patch of `block` through `anchor` with
  /// outward unit `normal` (towards the particles) and area `area` (a disc about the anchor):
  /// centre at 0 < s <= r (1 + rel_tol) from the face plane, in-plane distance from the anchor
  /// <= sqrt(area/pi), foot point on the block's box (grown by r rel_tol). Only particles with
  /// index in [first, last) (default: all owned). Returns the number of bonds made.
  std::size_t bond_patch(const bonded::ParticleStore& ps, std::uint32_t block, const Vec3& anchor,
                         const Vec3& normal, double area, double rel_tol = 0.1, std::size_t first = 0,
                         std::size_t last = SIZE_MAX);
  /// Bonds every owned particle whose centre is outside the block within r (1 + rel_tol) of its
  /// surface. Returns the number of bonds made.
  std::size_t bond_touching(const bonded::ParticleStore& ps, std::uint32_t block, double rel_tol = 0.1);

  /// Bonds particle `gid`, whose state (centre, orientation, radius) is given rather than read
  /// from a store, e.g. one just inserted on another rank; otherwise as add_bond_at. Under MPI
  /// every rank must make the same calls (the list is replicated).
  void add_bond_to(GlobalId gid, const Vec3& x, const Quat& q, double radius, std::uint32_t block,
                   const Vec3& surface_point, const Vec3& normal);

  /// Removes every bond and returns the intact ones, in list order: e.g. held back during a
  /// set-up stage and made again with remake() afterwards (docs/bridge.md, "Relaxation").
  std::vector<BlockParticleBond> take_all();
  /// Makes bond `b` again (its particle, block and block-frame anchor), stress free in the
  /// current configuration. Throws std::invalid_argument for an unknown particle or block, or a
  /// particle centre inside the block.
  void remake(const bonded::ParticleStore& ps, const BlockParticleBond& b);

  /// Block `block`'s intact bonds as release_block() would return them, removing nothing.
  std::vector<ReleasedBond> bonds_of(std::uint32_t block) const;
  /// Conversion hand-over: removes block `block`'s bonds and returns each one's particle and
  /// world anchor (virtual particle centre at the block's current pose), in bond order; they
  /// become convert_block attachments (freeze bonds to the new particles).
  std::vector<ReleasedBond> release_block(std::uint32_t block);

  // ---- bonded::ForceSource ----
  bonded::ForceSourceResult add_forces(bonded::ParticleStore& ps, std::size_t n_owned,
                                       const bonded::ForceSourceContext& ctx) override;
  const char* name() const override { return "a block-particle freeze bond"; }
  bool uses_orientation() const override { return n_intact_ > 0; }

  /// With recording on, every force evaluation also keeps each intact bond's force on its block
  /// at the block end, and its stress over strength in tension and in shear (owned particles
  /// only; replacing the last ones): the hybrid's stress estimates read them (block_stress.h).
  struct PointForce {
    std::uint32_t block;       ///< block slot
    Vec3 point, force;         ///< world point of the block end (m), force on the block (N)
    double u_tension, u_shear; ///< sigma / sigma_c (0 in compression), tau / tau_c
  };
  void set_recording(bool on) { record_ = on; }
  const std::vector<PointForce>& recorded() const { return recorded_; }

  /// Linear (N s) and angular (N m s, about each block's centre) impulses on every block slot
  /// since the last call (this rank's share), written over `linear` and `angular` (resized to
  /// block_count()); clears them.
  void take_impulses(std::vector<Vec3>& linear, std::vector<Vec3>& angular);
  /// Collective: a bond broken on any rank is removed on every rank. Returns the number removed.
  std::size_t sync_broken(const par::Comm& comm);

  std::size_t size() const { return n_intact_; }  ///< intact bonds
  std::size_t count(std::uint32_t block) const;   ///< intact bonds of one block
  const std::vector<BlockParticleBond>& bonds() const { return bonds_; }
  const BlockBondStats& stats() const { return stats_; }
  /// Elastic energy of the intact bonds of owned particles, J (this rank).
  double elastic_energy(const bonded::ParticleStore& ps, const bonded::EngineDef& def) const;

  /// Checkpoint (hybrid_state.cpp): block table, bonds, index cache, pending impulses, counters.
  void save_state(StateArchive& a, const std::string& prefix) const;
  void load_state(const StateArchive& a, const std::string& prefix);
  /// From every saved rank (another rank count): the replicated list from the first with the
  /// broken flags of all, impulses and counters summed (kept only where `keep_sums`, else zero).
  void load_state_union(const std::vector<StateArchive>& all, const std::string& prefix, bool keep_sums);

 private:
  /// A bond at a block-frame anchor, stress free now; `cached` is the particle's index or kNone.
  void push_at_anchor(GlobalId gid, const Vec3& x, const Quat& q, double r, std::uint32_t block, const Vec3& anchor,
                      std::uint32_t cached);
  std::uint32_t lookup(const bonded::ParticleStore& ps, std::size_t n_owned, std::size_t k);
  std::vector<BlockBody> blocks_;
  std::vector<BlockParticleBond> bonds_;
  std::vector<std::uint32_t> cached_index_;  ///< per bond: last local index of its particle
  std::vector<Vec3> impulse_, angular_impulse_;
  std::size_t n_intact_ = 0;
  BlockBondStats stats_;
  bool record_ = false;
  std::vector<PointForce> recorded_;
};

/// A block frozen to another rigid block by a freeze joint (anchor, normal from the remaining
/// block towards the converted one, area) has converted (`converted`: convert_block's report,
/// whose new-particle list every rank holds alike): bonds the remaining block `block` to the
/// layer of those particles nearest the joint face inside the joint's patch (within half an HCP
/// layer spacing, 0.41 D, of the nearest one). Under MPI every rank makes the same bonds, so the
/// replicated list stays replicated. Returns the number of bonds made.
std::size_t bond_joint_to_particles(BlockParticleBonds& bonds, std::uint32_t block, const Vec3& anchor,
                                    const Vec3& normal, double area, const ConversionReport& converted);

}  // namespace hs::bridge
