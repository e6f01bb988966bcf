// The figures of a run that `hybridsim run` prints (its set-up lines and its summary) and
// `hybridsim check` shows, gathered from the engine, the hybrid system and its rigid world by
// Simulation::run_stats(): the command reads these, not the objects behind them.
#pragma once

#include "bridge/hybrid.h"

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace hs::sim {

/// The hybrid system's counts and timings (conversions, rigid steps, freeze bonds) and its
/// relaxation before the freeze: plain records of the bridge, passed on as they are.
using BlockReport = bridge::HybridReport;
using RelaxReport = bridge::RelaxReport;

/// What a progress line shows after a step: this rank's figures, no communication.
struct Progress {
  double time = 0.0;                ///< s
  std::uint64_t bonds_broken = 0;   ///< since the start
};

struct RunStats {
  // ---- the particles (counts over all ranks) ----
  long long particles = 0, bonds = 0;
  std::uint64_t step = 0;   ///< steps completed
  double time = 0.0;        ///< s
  double dt = 0.0;          ///< s, the DEM step
  std::uint64_t bonds_broken = 0, bonds_broken_tension = 0, bonds_broken_shear = 0, bonds_broken_compression = 0;

  // ---- the blocks (has_blocks) ----
  bool has_blocks = false;
  const char* conversion = "";  ///< the conversion mode, as the scene names it
  BlockReport blocks;
  RelaxReport relax;
  std::size_t freeze_joints = 0;  ///< joints between blocks, as built
  std::size_t ice_joints = 0;     ///< ridge joints to the ice sheet, as built
  std::uint64_t conversions_crushing = 0;  ///< conversions governed by the crushing criterion
  std::size_t freeze_joints_broken = 0;
  std::uint64_t block_particle_bonds_broken = 0;
  bool far_sleep = false;
  std::size_t awake_blocks = 0;             ///< far sleep: awake at the last rigid step
  std::size_t sleepers_woken_by_solve = 0;  ///< far sleep: since this process started
  std::size_t solves_repeated = 0;          ///< far sleep: sub-step solves done again
  /// The rigid world's solves and their velocity iterations since this process started
  /// (relaxation included; rigid::RigidWorld::solver_stats), and the iteration cap.
  std::uint64_t solver_solves = 0, solver_iterations = 0;
  int solver_max_iterations = 0, solver_iteration_cap = 0;
  double solver_tolerance = 0.0;            ///< m/s, blocks.solver_tolerance

  // ---- MPI (this rank's; the caller reduces) ----
  double force_seconds = 0.0, comm_seconds = 0.0;
  std::uint64_t exchanges = 0, migrated = 0, balances = 0;
  std::array<int, 3> boxes{};               ///< ranks along x, y, z
  std::array<std::vector<double>, 3> cuts;  ///< the boxes' boundaries along x, y, z
};

}  // namespace hs::sim
