// Recorders: what a run writes to its /series (and /snapshots), one small class per family of
// series, all registered in one list (recorders.cpp, make_recorders). A new output series is
// one Recorder subclass plus one line in that list.
//
// Per run: declare() once (the series appear in the run file), then write() for row 0 (the
// initial state), then after every DEM step after_step() (sums and peaks over the output
// interval) and, when due(), write(). Each recorder keeps its own sums; a row holds the mean
// over the steps since the previous row (row 0: the instantaneous value).
#pragma once

#include "common/types.h"
#include "sim/simulation.h"

#include <cstdint>
#include <memory>
#include <vector>

namespace hs {
class StateArchive;
}
namespace hs::io {
class RunFile;
}
namespace hs::par {
class Comm;
}

namespace hs::sim {

/// What the recorders saw over the run, for the end-of-run summary and analysis.
struct RunFigures {
  std::vector<double> wall_peak, wall_peak_time;  ///< N, s: largest single-step |F| per wall
  double peak_h = 0.0, peak_h_time = 0.0;         ///< structure, horizontal |F| of the row means
  double peak_step = 0.0, peak_step_time = 0.0;   ///< structure, horizontal |F| of single steps
  Vec3 mean_force = Vec3::Zero();                 ///< structure, mean over all steps
  double max_pile = 0.0, max_pile_time = 0.0;     ///< m, s
  bool has_pile_mean = false;                     ///< /series/pile_height_mean was recorded (pier)
  double max_pile_mean = 0.0, max_pile_mean_time = 0.0;  ///< m, s: its peak
  double max_overlap = 0.0, max_overlap_time = 0.0;      ///< contact overlap / radius, s: its peak
  std::uint64_t rows = 0, snapshots = 0;         ///< written to the run file
  /// The at-rest figures of a run with blocks (recorders.cpp, RestWindow): the largest mean speed of
  /// a block, and of a particle, over the run's last rest_window s (m/s); rest_window 0: no blocks,
  /// or the run did not reach its end.
  double rest_window = 0.0, final_mean_block_speed = 0.0, final_mean_particle_speed = 0.0;
};

/// s: the window over which the at-rest check takes each block's mean speed (RestWindow):
/// about 100 rigid steps of a keel scene (a contact hiccup lasts 1-3 of them), and 1/15 of a
/// floating block's heave period (~1.5 s), so a block that bobs still reads its speed.
inline constexpr double kRestWindow = 0.1;

/// The group of the structure's per-step load (recorders.cpp, LoadPerStepRecorder): `time` (s) and
/// `force` (N, n x 3), one row per DEM step whatever the output interval; the run metrics come
/// from it (docs/metrics.md). A checkpoint at step k counts k of its rows.
inline constexpr const char* kLoadPerStepGroup = "/load_per_step";

/// The group of the pile heights on a fixed clock (recorders.cpp, PileClockRecorder): `time` (s),
/// `height_top` and `height_mean` (m), every kPileClock s of simulated time from t = 0 whatever
/// the output interval; the pile metrics' peaks come from it (docs/metrics.md).
inline constexpr const char* kPileClockGroup = "/pile_per_clock";
inline constexpr double kPileClock = 0.05;  ///< s
/// Steps between rows of kPileClockGroup (at least 1); a checkpoint at step k counts k / it + 1 rows.
std::uint64_t pile_clock_every(const Schedule& sc);

class Recorder {
 public:
  virtual ~Recorder() = default;
  /// Adds this recorder's series to the run file.
  virtual void declare(io::RunFile& file) = 0;
  /// After every DEM step: accumulate what the rows average (default: nothing).
  virtual void after_step(const Simulation& sim) {}
  /// Whether step k (1..total) ends a row of this recorder: every output interval and the last step.
  virtual bool due(std::uint64_t k, const Schedule& sc) const {
    return k % sc.output_every == 0 || k == sc.total_steps;
  }
  /// Writes one row (collective under MPI: every rank calls it).
  virtual void write(Simulation& sim, io::RunFile& file) = 0;
  /// Adds what this recorder saw to the run's figures (default: nothing).
  virtual void figures(RunFigures& f) const {}
  /// Checkpoint: this recorder's sums, counts and peaks under prefix + "..." (default: none;
  /// a recorder that keeps anything between rows must save it, or a restarted run's rows differ).
  virtual void save(StateArchive& a, const std::string& prefix) const {}
  virtual void load(const StateArchive& a, const std::string& prefix) {}
};

/// The run's recorders in their fixed order.
class Recorders {
 public:
  Recorders(const Simulation& sim, const scene::Scene& s, const par::Comm& comm);
  ~Recorders();
  void declare(io::RunFile& file);
  /// Row 0: the initial state (forces are zero until the first step).
  void write_initial(Simulation& sim, io::RunFile& file);
  /// After DEM step k: every recorder accumulates, then those due write their row; the state
  /// of step k is kept as the last good one.
  void after_step(std::uint64_t k, Simulation& sim, io::RunFile& file);
  /// The run stops early after step k (SIGINT/SIGTERM): every recorder not due at k writes its
  /// row now (the mean over the steps since its last row), the snapshot recorder its snapshot,
  /// so the file ends at step k as a finished run ends at its last step.
  void write_stop(std::uint64_t k, Simulation& sim, io::RunFile& file);
  /// After a step failed (SimulationError, collective): writes the kept state of the last
  /// completed step as one more snapshot, whether or not the scene asked for snapshots (the
  /// failed step's state is not written: it may hold non-finite numbers). Returns its step.
  std::uint64_t write_last_good(io::RunFile& file);
  /// Time [s] of the kept last good state.
  double last_good_time() const;
  RunFigures figures() const;
  /// Checkpoint: every recorder's state (collective-free; each rank its own, all alike).
  void save_state(StateArchive& a) const;
  /// Restores the recorders after a restart; the restored simulation becomes the last good state.
  void load_state(const StateArchive& a, const Simulation& sim);

 private:
  class LastGood;
  std::vector<std::unique_ptr<Recorder>> list_;
  std::unique_ptr<LastGood> last_good_;
};

/// The list: every recorder of a run with this simulation and scene (recorders.cpp).
std::vector<std::unique_ptr<Recorder>> make_recorders(const Simulation& sim, const scene::Scene& s,
                                                      const par::Comm& comm);

}  // namespace hs::sim
