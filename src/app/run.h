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
  /// --flush-interval: wall-clock seconds between flushes of the series (and of anything else
  /// buffered) to the file, whether or not snapshots are on; > 0.
  double flush_interval = 60.0;
  bool fsync = false;  ///< --fsync: fsync(2) after every flush (serial; MPI-IO syncs itself)
  bool ignore_memory_limit = false;    ///< --ignore-memory-limit: build even past the memory estimate
  /// --restart: continue the run of this run file (or of its checkpoint file) from its last
  /// checkpoint (docs/output.md, "Checkpoints"); empty = start from t = 0.
  std::string restart;
  /// --relaxation: the relaxation file of the scene (docs/bridge.md, "The relaxation cache"):
  /// loaded when it exists (refused, exit 2, when it holds another scene's or build's), else the
  /// run relaxes and writes it; empty = the shared cache directory.
  std::string relaxation;
  bool no_cache = false;  ///< --no-cache: neither look up nor write the shared relaxation cache
  // `hybridsim calibrate` only (calibrate_command.h)
  std::string calibrate_tests = "tension,bending,strip";  ///< --tests: which virtual tests to run
  double max_strip_steps = 6e4;        ///< --max-strip-steps: above it the strip test is softened
  bool calibrate_scene_strength = false;  ///< --scene-strength: bending at the scene's sigma_f/E, not scaled
};

/// Exit code of a run stopped by SIGINT/SIGTERM: 128 + the signal (130, 143).
inline int stopped_exit_code(int sig) { return 128 + sig; }

/// Loads, builds and runs the scene, writing the HDF5 run file. Under MPI every rank calls this
/// (collective); each builds the scene, keeps its share, and all write the one file. Progress goes to `progress`
/// (a single updating line when it is a terminal, a log line every ~10 s otherwise), the
/// summary to `out`. Returns 0, or 128 + signal when SIGINT/SIGTERM stopped the run (the step
/// under way is finished, the rows up to it and a final snapshot, if snapshots are on, written,
/// the file closed; no /analysis). Throws hs::InputError (bad input, nothing run) and
/// hs::SimulationError (unstable; the output written so far and a snapshot of the last good
/// step are flushed and closed first).
int run_scene(const RunOptions& opt, std::ostream& out, std::FILE* progress);

/// The run-time estimate `check` prints, in core-seconds (sim::estimate_cost: the particles, the
/// rigid world and the relaxation at its longest; particles made by conversions are not in it).
/// Loads and builds the scene as `check` does (blocks not converted, no relaxation run). Throws
/// hs::InputError.
double estimated_core_seconds(const RunOptions& opt);

/// Loads and builds the scene and prints the derived figures (counts, dt, estimates).
/// Returns 0; throws hs::InputError.
int check_scene(const RunOptions& opt, std::ostream& out, std::ostream& err);

/// `hybridsim iso FILE.json`: a scene (has "time" or "ice"; inputs derived from its ice and
/// pier, rubble height from analysis.rubble_height) or a plain object of ISO input keys.
/// Prints the estimate as JSON (iso_to_json plus "inputs"). Throws hs::InputError.
int iso_command(const RunOptions& opt, std::ostream& out);

}  // namespace hs::app
