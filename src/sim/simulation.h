// One simulation, built from a scene: the particle engine (bonded ice, walls, the structure),
// the rigid blocks and the hybrid system that steps both, and the schedule of steps, rows and
// snapshots. The run pipeline (README, "Architecture"):
//
//   scene::load_scene_file -> sim::build_simulation -> loop { Simulation::step, Recorders } -> sim::analyse_run
//
// build_simulation is the only place that turns definitions into objects: the structure's
// mesh is built once, here, for both the particles' mesh wall and the blocks' contact.
#pragma once

#include "bonded/engine.h"
#include "bridge/hybrid.h"
#include "scene/scene.h"
#include "sim/blocks.h"
#include "sim/build.h"
#include "sim/relaxation_cache.h"
#include "sim/cost.h"
#include "sim/run_stats.h"

#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace hs {
class StateArchive;
}
namespace hs::io {
struct CheckpointMeta;
class RunFile;
}
namespace hs::par {
class Comm;
}

namespace hs::sim {

class Recorders;

/// What the relaxation before the freeze reports after each rigid step (BuildOptions::relax_progress).
using RelaxProgress = bridge::RelaxProgress;

/// Steps of a run and the steps between its outputs.
struct Schedule {
  double dt = 0;
  std::uint64_t total_steps = 0;
  std::uint64_t output_every = 1;    ///< steps between series rows
  std::uint64_t snapshot_every = 0;  ///< 0 = no snapshots
  std::uint64_t checkpoint_every = 0;  ///< steps between checkpoints; 0 = none
};
Schedule schedule(const scene::TimeDef& t, double dt);

/// The load of the ice on the structure: particles (this DEM step) + blocks (mean over the
/// current rigid step). Moments about the structure's mesh origin.
struct StructureLoad {
  Vec3 force = Vec3::Zero();
  Vec3 moment = Vec3::Zero();
  std::vector<Vec3> part_force, part_moment;  ///< per mesh part (structure_parts())
};

struct BuildOptions {
  bool check_dt = true;  ///< InputError at /time/dt if dt exceeds the critical step
  bool convert = true;   ///< false: blocks stay rigid whatever the scene says (`hybridsim check`)
  /// false: InputError at /ice, before anything is allocated, when memory_estimate (times the
  /// ranks) exceeds the machine's available memory (check_memory). --ignore-memory-limit.
  bool ignore_memory_limit = false;
  /// false: no relaxation before the freeze whatever the scene says (`hybridsim check`).
  bool relax = true;
  /// Restart: the checkpoint's state (one rank's), whose relaxed rigid world replaces the
  /// relaxation (HybridSystem::restore_relaxation).
  const StateArchive* restart_state = nullptr;
  /// The scene's calibrate_ice when the caller has computed it already (once per run); computed
  /// by build_simulation when null. Kept as Built::calibrated.
  const CalibratedIce* calibrated = nullptr;
  /// Called every rigid step of the relaxation (progress lines); true stops it: build_simulation
  /// then throws RelaxationStopped.
  bridge::RelaxProgressFn relax_progress{};
  /// The relaxation cache (relaxation_cache.h): where a relaxed state is looked up instead of
  /// relaxing, and written after relaxing. Off by default (`hybridsim run` turns it on).
  RelaxationCacheDef relaxation_cache{};
};

/// build_simulation was asked to stop during the relaxation (relax_progress returned true).
struct RelaxationStopped : std::runtime_error {
  explicit RelaxationStopped(double t) : std::runtime_error("stopped during the relaxation"), time(t) {}
  double time;  ///< s of relaxation done
};

class Simulation {
 public:
  /// One DEM step of the particles; the blocks advance every steps_per_rigid_step() of them.
  void step() {
    hybrid_->step();
    cost_ledger_.particle_steps += static_cast<double>(engine().particles().owned());
  }

  bonded::Engine& engine() { return *built_.engine; }
  const bonded::Engine& engine() const { return *built_.engine; }
  bridge::HybridSystem& hybrid() { return *hybrid_; }
  const bridge::HybridSystem& hybrid() const { return *hybrid_; }
  const Schedule& schedule() const { return schedule_; }
  /// What was built: particle and bond counts at build time, ice layers, the structure.
  const Built& built() const { return built_; }
  /// What the blocks came from (ridge file, list), the hybrid settings and the joints.
  const BlockSetup& blocks() const { return blocks_; }
  /// Warnings found while building (for the user; not errors).
  const std::vector<std::string>& warnings() const { return blocks_.warnings; }
  /// Where the relaxation before the freeze came from (computed, loaded from a relaxation file,
  /// or a restart's checkpoint); source "" without one.
  const RelaxationOrigin& relaxation_origin() const { return relaxation_origin_; }

  bool has_structure() const { return built_.structure >= 0; }
  bool has_blocks() const { return hybrid_->has_rigid(); }
  const std::vector<std::string>& structure_parts() const { return built_.structure_parts; }
  double structure_radius() const { return built_.structure_radius; }
  const Vec3& structure_position() const;
  /// Total load on the structure (particles + blocks) into `out` (its vectors are reused:
  /// called every step); requires has_structure().
  void structure_load(StructureLoad& out) const;

  // ---- figures for the command's lines (run_stats.cpp) ----
  std::uint64_t step_count() const { return engine().step_count(); }  ///< steps completed
  double time() const { return engine().time(); }                     ///< s
  double dt() const { return engine().dt(); }                         ///< s, the DEM step
  /// The stable DEM step of the stiffest spring, s; check_time_step throws hs::InputError at
  /// /time/dt when dt exceeds it.
  double critical_time_step() const { return engine().critical_time_step(); }
  void check_time_step() const { engine().check_time_step(); }
  /// The ranks the particles are spread over.
  const par::Comm& comm() const { return engine().comm(); }
  /// This rank's figures for a progress line (no communication).
  Progress progress() const;
  /// The figures of the run so far (particles, bonds, blocks, relaxation, MPI). Collective under
  /// MPI: the particle and bond counts are summed over the ranks.
  RunStats run_stats() const;

  // ---- cost (sim/cost.h) ----
  /// The phases timed outside the step (set-up, output, the loop's MPI poll, analysis): the
  /// builder and the run add to it; checkpoints carry it.
  CostLedger& cost_ledger() { return cost_ledger_; }
  const CostLedger& cost_ledger() const { return cost_ledger_; }
  /// This rank's cost of the run so far: the ledger's phases with the step's parts from the
  /// engine and the hybrid system; the wall time of every process, this one's up to now.
  RunCost cost() const;

  // ---- checkpoints (simulation_checkpoint.cpp; docs/output.md, "Checkpoints") ----
  /// Writes the checkpoint of the state after the current step to `path`: every part's state
  /// (engine, hybrid system with its rigid world, recorders). Collective under MPI: rank 0
  /// gathers every rank's state and writes the file. `identity` carries what ties it to the
  /// scene (scene_hash, scene_text, restart_changes); the step, time, ranks, series rows,
  /// snapshots, version and run file are filled in here. Flushes `file` first, so that it holds
  /// every row the checkpoint counts.
  void save_checkpoint(const std::string& path, const io::CheckpointMeta& identity, const Recorders& rec,
                       io::RunFile& file, const par::Comm& comm) const;
  /// Restores the state this rank saved (same rank count: the continuation is bit-identical).
  /// Returns the saved rigid contact points that found no contact manifold.
  std::size_t load_checkpoint(const StateArchive& state, Recorders& rec);
  /// Restores the union of every saved rank's state, spread over this run's ranks (another rank
  /// count; collective). Returns as above.
  std::size_t load_checkpoint(const std::vector<StateArchive>& all, Recorders& rec);

 private:
  friend Simulation build_simulation(const scene::Scene&, const par::Comm&, const BuildOptions&);
  friend void relax_or_load(Simulation&, const scene::Scene&, const par::Comm&, const BuildOptions&);
  Built built_;
  BlockSetup blocks_;
  RelaxationOrigin relaxation_origin_;
  std::unique_ptr<bridge::HybridSystem> hybrid_;
  Schedule schedule_;
  CostLedger cost_ledger_;
};

/// The relaxation before the freeze of a built simulation whose hybrid system waits for it: loaded
/// from the relaxation cache when it holds the scene's key (the engine's and the hybrid system's
/// state at t = 0, as the relaxation left them), else run (and written to the cache). Adds the
/// warnings of a relaxation that did not end at rest. Throws RelaxationStopped.
void relax_or_load(Simulation& sim, const scene::Scene& s, const par::Comm& comm, const BuildOptions& opt);

/// The relaxation before the freeze as the scene gives it (blocks.relax), for HybridSystem::relax.
bridge::RelaxDef relax_def(const scene::Scene& s);
/// How the engine spreads over the ranks (the scene's "parallel"), for Engine::distribute.
bonded::ParallelDef parallel_def(const scene::Scene& s);

/// Builds the scene: the engine (particles, walls, structure), the blocks and the hybrid system
/// (all_at_start converts them here), then spreads the particles over the ranks of `comm`
/// (every rank builds the whole scene and keeps its share). Throws hs::InputError.
Simulation build_simulation(const scene::Scene& s, const par::Comm& comm, const BuildOptions& opt = {});

}  // namespace hs::sim
