// The hybrid system: bonded particles (hs::bonded::Engine) and rigid ice blocks
// (hs::rigid::RigidWorld) advanced together, with blocks turning into particles near the
// structure (docs/bridge.md).
//
// One DEM step (data flows one way, DESIGN.md):
//   1. the blocks' poses for the particles: kinematic extrapolation from the last rigid step,
//        x(t) = x_r + v_r (t - t_r),   q(t) = exp(w_r (t - t_r)) q_r;
//   2. Engine::step(): particle–block contact forces act on the particles (same contact law as
//      particle–particle) and their reactions accumulate as impulses on the blocks;
//   3. every k-th DEM step (the rigid step h_r = k dt): the accumulated impulses are summed over
//      the MPI ranks and applied to the blocks (the one sync point), the rigid world advances by
//      h_r (water, block–block and block–structure contact, freeze joints), the blocks' new
//      states become the kinematic reference, and the conversion policy runs.
// The rigid step obeys a stated stability rule (max_rigid_step); larger steps are refused.
#pragma once

#include "bonded/engine.h"
#include "bridge/block_stress.h"
#include "bridge/converter.h"
#include "bridge/coupling.h"
#include "rigid/rigid_world.h"

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace hs {
class StateArchive;
}

namespace hs::bridge {

enum class ConversionMode { Hybrid, AllAtStart, Never };

/// Parses "hybrid" | "all_at_start" | "never"; throws hs::InputError(path, ...) otherwise.
ConversionMode conversion_mode_from_string(const std::string& s, const std::string& path = "/blocks/conversion");
const char* to_string(ConversionMode m);

/// Stability rule for the explicit impulse coupling (docs/bridge.md, "Multi-rate stepping").
/// Between rigid steps a block moves at constant velocity while particles press on it; the
/// accumulated impulse changes its velocity once per rigid step. For a block of mass m held by
/// n contact springs of stiffness k this is symplectic Euler on an oscillator of angular
/// frequency omega = sqrt(n k / m), stable for h < 2 / omega. The most contacts a block can
/// carry is n = A / (sqrt(3)/2 D^2) on its largest face A (particles in close-packed contact),
/// so m / n = (m / A) (sqrt(3)/2) D^2, and for a box m / A = 2 rho c with c its smallest half
/// extent: the thinnest block governs. The rule keeps a factor `safety` below the bound:
///     h_r <= safety * 2 sqrt((m/A)_min (sqrt(3)/2) D^2 / k).
/// Rotation about a face's centre has omega_rot^2 <= n k / m for a box, so the translational
/// bound governs.
struct RigidStepInputs {
  double min_mass_per_face_area = 0.0;  ///< min over blocks of m / (largest face area), kg/m^2
  double particle_diameter = 0.0;       ///< D, m
  double contact_stiffness = 0.0;       ///< k (normal), N/m
  double safety = 0.2;                  ///< fraction of the stability bound used
};
double max_rigid_step(const RigidStepInputs& in);

/// Deepest overlap (m) of an oriented box with the owned particles (0 when clear).
double block_particle_overlap(const bonded::ParticleStore& ps, const Vec3& half_extents, const Vec3& centre,
                              const Quat& orientation);
/// Shortest axis-aligned move (m, along +-x, +-y or +-z) that clears a block from the engine's
/// particles (+1 mm); zero if already clear.
Vec3 clearing_shift(const bonded::Engine& engine, const Vec3& half_extents, const Vec3& centre,
                    const Quat& orientation);

/// Outcome counters of a hybrid run (printed at the end and stored in the run file).
struct HybridReport {
  std::uint64_t conversions = 0;          ///< blocks turned into particles
  std::uint64_t particles_created = 0;
  std::uint64_t bonds_created = 0;
  std::uint64_t sites_dropped = 0;        ///< lattice sites dropped for overlap
  std::int64_t peak_particles = 0;        ///< most particles at any rigid step (all ranks)
  std::uint64_t rigid_steps = 0;
  std::uint64_t conversions_freeze = 0;   ///< conversions governed by the freeze-bond estimate
  std::uint64_t conversions_flexure = 0;  ///< ... by the flexural estimate
  /// Conversions by governing criterion, indexed like conversion_criteria() (empty before the first).
  std::vector<std::uint64_t> conversions_by_criterion;
  /// Conversions governed by criterion c (0 when none yet).
  std::uint64_t conversions_by(std::size_t c) const {
    return c < conversions_by_criterion.size() ? conversions_by_criterion[c] : 0;
  }
  std::uint64_t joints_released = 0;      ///< freeze joints removed with converted blocks
  double max_utilisation = 0.0;           ///< largest utilisation (any criterion) seen in the region
  std::uint64_t conversions_refused = 0;   ///< blocks the converter could not fill (thinner than
                                          ///< D, or every site overlapping particles): stay rigid
  std::size_t blocks_moved_clear = 0;     ///< blocks shifted at the start to clear the particles
  double max_clearing_shift = 0.0;        ///< m, the largest of those shifts
  std::size_t blocks_initial = 0, blocks_now = 0;
  double rigid_dt = 0.0;                  ///< s
  std::uint64_t steps_per_rigid_step = 0; ///< k
  double rigid_dt_limit = 0.0;            ///< the stability rule's bound, s
  // Wall time of the step's parts on this rank since the freeze (the run's t = 0), s: a steady
  // clock, a few reads per step (the run's cost breakdown, sim/cost.h). seconds_bonded is the
  // engine's step, of it seconds_bonded_force its force evaluation and seconds_bonded_mpi its MPI
  // waits (Engine::parallel_stats() before and after); seconds_rigid the rigid world's step;
  // seconds_bridge the whole bridge, of it the conversion policy's stress estimates (the blocks'
  // loads and criteria), its decisions, the conversions, and the bridge's MPI collectives.
  double seconds_rigid = 0.0, seconds_bonded = 0.0, seconds_bridge = 0.0;
  double seconds_bonded_force = 0.0, seconds_bonded_mpi = 0.0;
  double seconds_stress = 0.0, seconds_policy = 0.0, seconds_conversion = 0.0, seconds_bridge_mpi = 0.0;
  double kinetic_energy_change = 0.0;     ///< sum over conversions of KE after - before, J
  std::uint64_t ice_bonds_created = 0;    ///< block-particle freeze bonds made at the start
  std::uint64_t block_bonds_handed_over = 0;  ///< block-particle bonds that became particle bonds
  std::uint64_t block_bonds_unmatched = 0;    ///< ... released with no new particle within 1.5 D
  std::uint64_t joints_to_bonds = 0;      ///< block-particle bonds made from joints of converted blocks
};

/// The relaxation before the freeze (docs/bridge.md, "Relaxation"): the blocks and the particle
/// sheet (its lattice bonds intact) are released in water under gravity, buoyancy and drag only
/// (no freeze joints, no block-particle freeze bonds, the structure parked, no conversions) until
/// they are at rest; the joints and bonds are then made at that geometry, stress free.
struct RelaxDef {
  double max_time = 30.0;  ///< s of simulated set-up at most
  double speed = 0.002;    ///< m/s: at rest when every block and particle is slower ...
  double hold = 1.0;       ///< s: ... for this long without a break
  /// 1/s: velocities scaled by exp(-damping dt) every step of the relaxation (blocks every rigid
  /// step); a set-up device that speeds the rest up, not physics. 0 = none.
  double damping = 0.0;
  /// s: after the relaxation above, a second stage of at most this long (0 = none) with the
  /// joints between blocks made, stress free at the poses it starts from, and unbreakable (the
  /// damping and the rest test as above): it stops the blocks friction alone cannot hold in a
  /// keel steeper than the friction angle, which creep through the joint-free stage. The joints
  /// stay as they are at its end and become breakable at the freeze (their load then is the
  /// keel's static one); the block-particle bonds are made at the freeze as without it
  /// (docs/bridge.md, "Relaxation").
  double jointed_time = 0.0;
  /// s, all_at_start only: > 0 relaxes the rigid blocks first, as in hybrid mode (both stages
  /// above), then converts every block at its relaxed pose against the relaxed sheet and lets
  /// the lattices relax for at most this long (a third stage, the freeze bonds the conversion
  /// made held back until the freeze, or held in place: hold_freeze_bonds); 0 converts before the relaxation (docs/bridge.md,
  /// "Relaxation", "Converting after a rigid relaxation").
  double lattice_time = 0.0;
  /// 1/s: the lattice stage's damping (as `damping` above); < 0 (default): `damping`.
  double lattice_damping = -1.0;
  /// all_at_start's lattice stage: 1 keeps the particle freeze bonds the conversion made (the
  /// ridge's joints and its bonds to the sheet, handed over) in place through the stage,
  /// unbreakable, as the jointed stage holds the joints, and leaves them at the freeze as they
  /// are, breakable, with the load they carry; 0 (default) holds them back until the freeze and
  /// makes them there, stress free (docs/bridge.md, "Relaxation"). (An integer: RelaxReport, which
  /// holds this definition, goes into checkpoints as bytes, and a bool would add padding.)
  std::uint64_t hold_freeze_bonds = 0;
  /// The damping the lattice stage uses (lattice_damping, or damping when that is < 0).
  double lattice_stage_damping() const { return lattice_damping >= 0.0 ? lattice_damping : damping; }
};

/// Where a relaxation is (every rigid step, for progress lines).
struct RelaxProgress {
  double time = 0.0;                 ///< s of relaxation
  double max_block_speed = 0.0;      ///< m/s: centre speed + |omega| x half diagonal
  double max_particle_speed = 0.0;   ///< m/s
  Vec3 fastest_block = Vec3::Zero();     ///< m, centre of the fastest block (where the relaxation still moves)
  Vec3 fastest_particle = Vec3::Zero();  ///< m, centre of the fastest particle
  double block_kinetic_energy = 0.0; ///< J
  double quiet_time = 0.0;           ///< s for which both speeds have been below RelaxDef::speed
  /// Lattice bonds broken since the relaxation began (a sheet too weak for the keel's load breaks
  /// here, and each break kicks its particles: docs/bridge.md, "Relaxation").
  std::uint64_t lattice_bonds_broken = 0;
  /// 1: without joints; 2: the jointed stage (RelaxDef::jointed_time); 3: the lattice stage
  /// (RelaxDef::lattice_time)
  int stage = 1;
};
/// Called every rigid step of the relaxation; return true to stop it there (a SIGINT).
using RelaxProgressFn = std::function<bool(const RelaxProgress&)>;

/// What a relaxation did (stored in the run file's /analysis/relaxation).
struct RelaxReport {
  std::uint64_t ran = 0;         ///< 1 when a relaxation ran (or was restored from a checkpoint)
  std::uint64_t converged = 0;   ///< 1: at rest (RelaxDef::speed held for RelaxDef::hold) before max_time
  std::uint64_t stopped = 0;     ///< 1: stopped by the progress callback (nothing frozen)
  std::uint64_t steps = 0, rigid_steps = 0;
  std::uint64_t lattice_bonds_broken = 0;  ///< particle bonds broken during the relaxation
  double time = 0.0;                       ///< s simulated
  double max_block_speed = 0.0, max_particle_speed = 0.0, block_kinetic_energy = 0.0;  ///< at the end
  double sheet_mean_dz = 0.0;   ///< m: mean vertical displacement of the sheet's particles at the end
  double sheet_max_dz = 0.0;    ///< m: largest |vertical displacement| of a particle at the end
  double sheet_peak_mean_dz = 0.0;  ///< m: largest |mean vertical displacement| during the relaxation
  // The jointed stage (RelaxDef::jointed_time); time above includes it, converged is the first stage's.
  double jointed_time = 0.0;          ///< s of it run (0: none)
  std::uint64_t jointed_converged = 0;  ///< 1: at rest before jointed_time
  std::uint64_t jointed_joints = 0;     ///< joints between blocks it held
  std::uint64_t joints_overloaded = 0;  ///< of those, loaded beyond their strength at its end
  /// The lattice stage with RelaxDef::hold_freeze_bonds: the particle freeze bonds it held, and
  /// those loaded beyond their strength at its end (they break in the run's first step).
  std::uint64_t freeze_bonds_held = 0, freeze_bonds_overloaded = 0;
  double unjointed_max_block_speed = 0.0;  ///< m/s: fastest block when it began
  // The lattice stage (RelaxDef::lattice_time, all_at_start); time above includes it.
  double lattice_time = 0.0;            ///< s of it run (0: none)
  std::uint64_t lattice_converged = 0;  ///< 1: at rest before lattice_time
  double rigid_max_block_speed = 0.0;   ///< m/s: fastest block when the rigid stages ended
  /// At rest at the freeze: the verdict of the last stage that ran.
  bool at_rest() const {
    if (lattice_time > 0.0) return lattice_converged != 0;
    return jointed_time > 0.0 ? jointed_converged != 0 : converged != 0;
  }
  RelaxDef def;                 ///< the settings
};

/// Everything the hybrid system needs besides the engine and the blocks.
struct HybridDef {
  ConversionMode mode = ConversionMode::Hybrid;
  rigid::RigidWorldDef world;             ///< its dt is replaced by the chosen rigid step
  double rigid_dt = 0.0;                  ///< s; 0 = the stability rule's limit
  double rigid_dt_safety = 0.2;           ///< see max_rigid_step
  IceMaterial ice;                        ///< what converted blocks become
  double block_density = 920.0;           ///< kg/m^3
  double block_friction = 0.3;            ///< particle–block Coulomb coefficient
  bool has_structure = false;
  rigid::KinematicMeshDef structure;      ///< the structure's mesh for block contact
  // Conversion policy (Hybrid mode): a block converts when it lies in the region and
  // max(u_freeze, u_flex) x safety_factor >= 1 (block_stress.h).
  ConversionRegion region;
  double safety_factor = 1.0;
  double flexural_strength = 0.5e6;       ///< Pa
  /// N: one particle contact's force that crushes a block's face (ConversionStrengths); infinite = never.
  double contact_crushing_force = INFINITY;
  /// Time constant of the low-pass filter on each block's utilisation, s (0 = none). Bullet
  /// resolves a collision in one step with an impulse whose force (impulse / step) is far above
  /// the sustained load; the filter lets a load count only when it lasts (docs/bridge.md).
  double stress_time_constant = 0.05;
  /// Freeze joints between blocks: false (default) springs as stiff per unit area as the
  /// particles' freeze bonds (unless world.joint_stiffness is set), true Bullet's rigid joints.
  bool rigid_joints = false;
  /// true: the constructor adds the blocks only (no freeze joints, no block-particle freeze
  /// bonds, no structure in the rigid world, no conversion); relax() (or restore_relaxation())
  /// releases them and then makes all of those at the relaxed geometry.
  bool defer_freeze = false;
};

/// One block to start with.
struct BlockInit {
  rigid::BlockDef def;
};

/// A freeze joint from a starting block to the particle ice (e.g. the keel frozen to the
/// consolidated layer): bonds the particles against the block's face patch (block_bonds.h).
struct IceJointInit {
  std::size_t block = 0;        ///< index into the BlockInit list
  Vec3 anchor = Vec3::Zero();   ///< world point on the block face, m
  Vec3 normal = Vec3::UnitZ();  ///< unit, out of the block towards the ice
  double area = 0.0;            ///< m^2
};

/// A freeze joint between two starting blocks (indices into the BlockInit list).
struct JointInit {
  std::size_t a = 0, b = 0;
  Vec3 anchor = Vec3::Zero();   ///< world point on the common face, m
  Vec3 normal = Vec3::UnitZ();  ///< unit, from a to b
  double area = 0.0;            ///< m^2
};

class HybridSystem {
 public:
  /// Builds the rigid world (only when `blocks` is not empty: a scene pays only for what it
  /// uses), adds the structure as a kinematic mesh and the blocks, chooses the rigid step
  /// (throws hs::InputError at /blocks/rigid_dt if def.rigid_dt exceeds the rule) and, in
  /// AllAtStart mode, converts every block. Call before Engine::distribute().
  HybridSystem(bonded::Engine& engine, const HybridDef& def, const std::vector<BlockInit>& blocks,
               const std::vector<JointInit>& joints = {}, const std::vector<IceJointInit>& ice_joints = {});
  ~HybridSystem();
  HybridSystem(const HybridSystem&) = delete;
  HybridSystem& operator=(const HybridSystem&) = delete;

  /// One DEM step of the engine; a rigid step every steps_per_rigid_step() of them.
  void step();

  bool has_rigid() const { return world_ != nullptr; }
  rigid::RigidWorld* world() { return world_.get(); }
  const rigid::RigidWorld* world() const { return world_.get(); }
  /// Load of the blocks on the structure over the last rigid step (zero without blocks).
  Vec3 structure_force() const;
  Vec3 structure_moment() const;
  /// Per structure part (same parts as the engine's mesh wall); empty without blocks.
  const std::vector<Vec3>& structure_part_force() const;
  const std::vector<Vec3>& structure_part_moment() const;
  /// Block-particle freeze bonds in the replicated list (intact as of the last rigid step's
  /// sync, the same on every rank) and how many broke (all ranks, synced).
  std::size_t block_particle_bonds() const;
  std::uint64_t block_particle_bonds_broken() const;
  /// Elastic energy in particle-block contacts and block-particle bonds (this rank), J.
  double coupling_elastic_energy() const;
  /// Kinetic energy of the rigid blocks, J.
  double rigid_kinetic_energy() const;

  const HybridReport& report() const { return report_; }

  // ---- relaxation before the freeze (HybridDef::defer_freeze; relax.cpp) ----
  /// Whether the freeze joints and bonds wait for relax() or restore_relaxation().
  bool freeze_pending() const;
  /// Releases the blocks and the sheet (see RelaxDef) until they are at rest or def.max_time has
  /// passed, then freezes: the structure into the rigid world, the freeze joints (each ridge
  /// anchor and normal carried with its first block's motion) and the block-particle freeze bonds
  /// (patches carried with their block) made stress free at the relaxed geometry, clocks to t = 0
  /// (all_at_start: converted before the release, its bonds made again stress free here; docs/
  /// bridge.md, "Relaxation"). Walls parked meanwhile (Engine::set_walls_parked). If `progress`
  /// asks to stop, returns at once with `stopped` set and nothing frozen. Before distribute().
  const RelaxReport& relax(const RelaxDef& def, const RelaxProgressFn& progress = {});
  /// Instead of relax() when restarting from a checkpoint of a run that relaxed: the rigid world
  /// as the relaxation left it (saved with every checkpoint) and the same freeze, so that joints
  /// and bonds are made exactly as in the original run (all_at_start: the same conversion first).
  void restore_relaxation(const StateArchive& a, const std::string& prefix);
  const RelaxReport& relax_report() const;
  /// Elastic energy of the block-particle freeze bonds of this rank's particles, J.
  double block_bond_elastic_energy() const;
  /// Far sleep: the margin the wake box around the conversion region grows by beyond
  /// far_sleep.wake_distance, m: the largest half diagonal of a block that can move (fixed boxes
  /// never enter the region), with or without the relaxation.
  double far_sleep_reach() const;
  /// Converts block `id` now (removes it from the rigid world and appends its particles);
  /// the policy calls it, tests may too. Returns the converter's report.
  ConversionReport convert(rigid::BlockId id);
  std::uint64_t steps_per_rigid_step() const { return report_.steps_per_rigid_step; }

  // ---- checkpoint (hybrid_state.cpp; docs/output.md, "Checkpoints") ----
  /// Saves the rigid world, the particle-block contacts (loads, pending impulses, tangential
  /// springs of this rank's particles), the block-particle bonds (replicated list with reference
  /// states and broken flags, this rank's pending impulses), the blocks' kinematic reference,
  /// the filtered utilisations, the refused blocks, the DEM steps since the last rigid step and
  /// the report's counters.
  void save_state(StateArchive& a, const std::string& prefix) const;
  /// Restores into a system built from the same scene (the engine is restored separately).
  /// Returns the contact points the rigid world could not place (rigid::RigidWorld::load_state).
  std::size_t load_state(const StateArchive& a, const std::string& prefix);
  /// The same from a checkpoint written at another rank count (`all`: every saved rank's
  /// archive; call before Engine::load_state_union, collective): the replicated parts from rank
  /// 0, the per-rank parts merged (tangential springs united, impulses accumulated since the last
  /// rigid step summed onto rank 0, broken flags of the block-particle bonds united).
  std::size_t load_state_union(const std::vector<StateArchive>& all, const std::string& prefix);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  void apply_policy();
  /// The starting blocks (moved clear of the particles) and their joints into the world, and
  /// every block into the particle contact; returns the blocks' ids in `blocks` order.
  std::vector<rigid::BlockId> add_blocks(const std::vector<BlockInit>& blocks, const std::vector<JointInit>& joints);
  /// The structure, the joints, the block-particle bonds and all_at_start's conversion (or, when
  /// it came before the relaxation, the bonds it made, again), made now (relax.cpp); clocks to zero.
  void freeze();
  /// The pending freeze joints into the rigid world and the pending ice joints as block-particle
  /// bonds, carried to the blocks' current poses (relax.cpp).
  void make_pending_joints();
  /// The ridge's joints between blocks (pending_joints) at the blocks' poses now; none pending after.
  void make_pending_block_joints();
  /// A point / direction given at block k's starting pose, carried with its motion since.
  Vec3 pending_point(std::size_t k, const Vec3& point) const;
  Vec3 pending_direction(std::size_t k, const Vec3& dir) const;
  /// The relaxation's jointed stage (RelaxDef::jointed_time): the world saved for checkpoints,
  /// the block joints made, unbreakable until the freeze.
  void begin_jointed_stage();
  /// all_at_start with a relaxation: the joints made at the blocks' poses now, every block
  /// converted (their joints becoming freeze bonds as at any conversion), then those bonds and
  /// the joints left between blocks that stay rigid held back for freeze() (relax.cpp).
  void convert_before_relaxation();
  /// The lattice stage's start (RelaxDef::lattice_time): the rigid stages' joints removed, both
  /// clocks to 0, the engine and the world saved for restarts, then convert_before_relaxation()
  /// at the relaxed poses against the relaxed sheet.
  void convert_after_rigid_relaxation(const std::vector<JointInit>& ridge_joints);
  void convert_all_at_start();
  /// Which blocks the lattice stage's batch leaves rigid (Impl::batch_rigid): the fixed ones,
  /// those no lattice fits, and those whose every site the blocks before them would take.
  std::vector<char> plan_lattice_batch() const;
  bonded::Engine& engine_;
  std::unique_ptr<rigid::RigidWorld> world_;
  HybridReport report_;
};

}  // namespace hs::bridge
