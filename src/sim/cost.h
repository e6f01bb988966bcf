// Where a run's wall time goes, by phase (docs/output.md, "/analysis/cost"): every run records it,
// writes it to /analysis/cost and prints it in its summary.
//
// Who measures what (a steady clock; a few reads per step, none per particle or block):
//   - the set-up: `hybridsim run` (scene and checkpoint read, calibration) and build_simulation
//     (ridge read, build, the relaxation's stages, the freeze), into CostLedger;
//   - the step: the engine (force evaluation, MPI waits: bonded::ParallelStats) and the hybrid
//     system (engine step, rigid world, bridge parts: bridge::HybridReport), read by Simulation::cost;
//   - the loop around the step (rows, snapshots, checkpoints, flushes, progress lines, the loop's
//     MPI poll) and the end-of-run analysis: `hybridsim run`, into CostLedger.
// A checkpoint carries the ledger and the step's figures, so that a restarted run's file describes
// the whole run: every process that made it, each up to its last checkpoint (work a killed process
// did after its last checkpoint is done again and counted once).
#pragma once

#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>

namespace hs {
class StateArchive;
}
namespace hs::par {
class Comm;
}

namespace hs::sim {

/// The phases of a run. The set-up ones come first (kFirstStepPhase marks the end).
enum class Phase : int {
  Read,              ///< scene file, ridge file, a restart's checkpoint
  Calibration,       ///< the calibrated ice (calibrate_ice)
  Build,             ///< ice lattice, walls, structure, blocks, hybrid system, spreading over the ranks
  RelaxRigid,        ///< relaxation before the freeze: the stage without joints
  RelaxJointed,      ///< ... the jointed stage (blocks.relax.jointed_time)
  RelaxLattice,      ///< ... the lattice stage, its conversion included (blocks.relax.lattice_time)
  Freeze,            ///< joints and freeze bonds made at the relaxed geometry (a restart: restored)
  ParticleForces,    ///< the engine's force evaluation: contacts, bonds, walls, particle-block contact
  ParticleOther,     ///< the rest of the engine's step: integration, neighbour lists, ghost packing
  RigidWorld,        ///< the rigid world's step (Bullet: water, contact, joints, solver)
  BridgeCoupling,    ///< block poses for the particles, impulses onto the blocks
  BridgeStress,      ///< conversion policy: the blocks' loads and stress estimates
  BridgePolicy,      ///< ... filtered utilisations and decisions
  BridgeConversion,  ///< blocks turned into particles
  Output,            ///< run file, rows, snapshots, checkpoints, flushes, progress lines
  MpiWait,           ///< MPI collectives and halo exchanges (engine, bridge, the loop's poll)
  Analysis,          ///< the end-of-run analysis (pieces, ISO 19906)
  kCount
};
constexpr std::size_t kPhaseCount = static_cast<std::size_t>(Phase::kCount);
constexpr std::size_t kFirstStepPhase = static_cast<std::size_t>(Phase::ParticleForces);

struct PhaseInfo {
  const char* name;         ///< dataset name under /analysis/cost
  const char* label;        ///< in the summary
  const char* description;  ///< the dataset's "description" attribute
};
/// Every phase's name, label and description, indexed by Phase.
const std::array<PhaseInfo, kPhaseCount>& phase_info();

using CostClock = std::chrono::steady_clock;
inline double seconds_since(CostClock::time_point t0) {
  return std::chrono::duration<double>(CostClock::now() - t0).count();
}

/// The phases measured outside the step (set-up, the loop around the step, analysis), on this
/// rank, with what the processes before a restart recorded (added from the checkpoint).
struct CostLedger {
  std::array<double, kPhaseCount> seconds{};  ///< s; the step's phases are in the engine and hybrid system
  double particle_steps = 0.0;                ///< owned particles summed over this rank's steps
  double wall_before = 0.0;                   ///< s: the processes before this one (restarts)
  std::uint64_t processes_before = 0;
  CostClock::time_point start = CostClock::now();  ///< this process's start (`hybridsim run` sets it)
  /// Set while the run writes a checkpoint: the output phase's lap since then, which the
  /// checkpoint counts up to its own moment (the wall time it saves runs to that moment too).
  std::optional<CostClock::time_point> output_lap;

  void add(Phase p, double s) { seconds[static_cast<std::size_t>(p)] += s; }
  /// "cost/..." entries: the phases, the particle-steps, the wall time of every process up to now.
  void save(StateArchive& a) const;
  /// Adds the saved figures (one archive: this rank's; several: their mean, particle steps summed
  /// onto rank `rank` 0). A checkpoint without them adds nothing.
  void add_saved(const StateArchive& a);
  void add_saved_union(const StateArchive* all, std::size_t n, int rank);
};

/// A run's cost on one rank, or reduced over the ranks (reduce_cost).
struct RunCost {
  std::array<double, kPhaseCount> seconds{};  ///< s; reduced: the mean over the ranks
  std::array<double, kPhaseCount> max{};      ///< s; reduced: the largest rank's
  double wall = 0.0;                          ///< s, every process of the run (mean over the ranks)
  double wall_max = 0.0;
  std::uint64_t steps = 0, rigid_steps = 0;
  double particle_steps = 0.0;                ///< all ranks (after reduce_cost)
  int ranks = 1;
  std::uint64_t processes = 1;                ///< 1 + the restarts that made the run

  double phase(Phase p) const { return seconds[static_cast<std::size_t>(p)]; }
  double sum() const;           ///< of every phase
  double setup() const;         ///< of the set-up phases
};

/// Mean and max of every phase and of the wall time over the ranks, particle steps summed
/// (collective; serial: as it is).
RunCost reduce_cost(const RunCost& mine, const par::Comm& comm);

/// What `hybridsim check` estimates a run's wall time from (one core, no MPI).
struct CostInputs {
  double particles = 0.0;           ///< at the start
  std::uint64_t steps = 0;          ///< DEM steps of the run
  double dt = 0.0;                  ///< s, the DEM step
  std::size_t movable_blocks = 0;   ///< rigid blocks that are not fixed
  double rigid_dt = 0.0;            ///< s, the rigid step
  int solver_iterations = 0;        ///< the rigid world's, per rigid step
  double relax_time = 0.0;          ///< s simulated, the relaxation's stages of rigid blocks at their longest
  /// all_at_start: the particles the blocks become at the start (their volume / (D^3/sqrt 2)). The run
  /// then steps them with the sheet's and no movable block.
  double converted_particles = 0.0;
  double relax_lattice_time = 0.0;  ///< s simulated, all_at_start's stage of the converted lattices at its longest
};

/// The per-unit costs of the estimate: one core of the dev box (2-core VM, GCC 12 -O3 native,
/// AVX-512), measured from /analysis/cost of short runs (docs/output.md, "Estimated run time");
/// another machine scales them all by its speed.
struct CostRates {
  double particle_step = 1.0 / 4.4e6;    ///< s per particle-step: the particles' phases
  double block_iteration = 0.0;          ///< s per movable block, rigid step and solver iteration
  double output_share = 0.0;             ///< output, bridge and the rest, as a fraction of the above
};
CostRates default_cost_rates();

/// The estimate by phase, s (one core).
struct CostEstimate {
  double particles = 0.0, rigid = 0.0, other = 0.0;  ///< the run: particles, rigid world, the rest
  double relax_particles = 0.0, relax_rigid = 0.0;   ///< the relaxation at its longest
  double rigid_steps = 0.0, relax_steps = 0.0, relax_rigid_steps = 0.0;
  double run() const { return particles + rigid + other; }
  double relaxation() const { return relax_particles + relax_rigid; }
  double total() const { return run() + relaxation(); }
};
/// particles x steps x particle_step; movable blocks x rigid steps x iterations x block_iteration;
/// the same for the relaxation's relax_time (relax_time / dt DEM steps of the sheet, relax_time /
/// rigid_dt rigid steps); the rest as output_share of the run's two. With converted_particles
/// (all_at_start) the run steps particles + converted_particles and no block, and the lattice stage
/// adds relax_lattice_time / dt DEM steps of them.
CostEstimate estimate_cost(const CostInputs& in, const CostRates& rates = default_cost_rates());

/// The summary's table: each phase's seconds and share of the wall time, grouped (set-up,
/// particles, rigid world, bridge, output, MPI wait, analysis), and one line of the step's shares.
std::string cost_table(const RunCost& c);

}  // namespace hs::sim
