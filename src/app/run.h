// The `hybridsim run` and `hybridsim check` commands.
#pragma once

#include <cstdio>
#include <ostream>
#include <string>
#include <vector>

namespace hs::par {
class Comm;
}

namespace hs::app {

struct RunOptions {
  /// The ranks of an mpirun launch (every rank calls run_scene); nullptr = serial.
  const par::Comm* comm = nullptr;
  std::string scene_path;
  std::string output;                  ///< -o; empty: the scene's "output" ("<name>.h5")
  std::vector<std::string> overrides;  ///< --set path=value, in order
  bool ignore_memory_limit = false;    ///< --ignore-memory-limit: build even past the memory estimate
};

/// Assumed throughput for run-time estimates (one core, Release).
inline constexpr double kParticleStepsPerSecond = 3e6;

/// Loads, builds and runs the scene, writing the HDF5 run file. Under MPI every rank calls this
/// (collective); each builds the scene, keeps its share, and all write the one file. Progress goes to `progress`
/// (a single updating line when it is a terminal, a log line every ~10 s otherwise), the
/// summary to `out`. Returns 0; throws hs::InputError (bad input, nothing run) and
/// hs::SimulationError (unstable; the output written so far is flushed and closed first).
int run_scene(const RunOptions& opt, std::ostream& out, std::FILE* progress);

/// Loads and builds the scene and prints the derived figures (counts, dt, estimates).
/// Returns 0; throws hs::InputError.
int check_scene(const RunOptions& opt, std::ostream& out, std::ostream& err);

/// `hybridsim iso FILE.json`: a scene (has "time" or "ice"; inputs derived from its ice and
/// pier, rubble height from analysis.rubble_height) or a plain object of ISO input keys.
/// Prints the estimate as JSON (iso_to_json plus "inputs"). Throws hs::InputError.
int iso_command(const RunOptions& opt, std::ostream& out);

}  // namespace hs::app
