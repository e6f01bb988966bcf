// Run metrics (docs/metrics.md): the figures a study compares between runs, each a formula on the
// structure's per-step load (/load_per_step) or on the state at the end of the run, so that
// none depends on the output interval. Pure functions on plain arrays; sim/metrics.h reads a run
// file and calls them (one function for the run summary, `hybridsim metrics` and the studies).
//
// Per-step series: t_k is the time at the end of DEM step k (k = 1..N), y_k the value of that
// step; the run starts at t_0 (the time before step 1). Step k covers (t_{k-1}, t_k].
//   mean over a window (a, b]:   mean of the y_k with a < t_k <= b              (M1)
//   impulse:                     I = sum_k y_k (t_k - t_{k-1})                   (M2)
//   95th percentile:             P95 = y_(r) interpolated linearly between ranks,
//                                r = 0.95 (N - 1) over the sorted y (numpy's default)  (M3)
//   peak of the W moving mean:   max over k with t_k - t_0 >= W of
//                                sum_{j: t_j > t_k - W} y_j dt_j / sum dt_j      (M4)
// A window with no step, a run shorter than W, an empty series: NaN (never 0).
#pragma once

#include <string>
#include <vector>

namespace hs::analysis {

/// One metric as stored in /analysis/metrics and printed: a scalar with its unit and meaning.
struct Metric {
  std::string name;  ///< dataset name, e.g. "load_h_mean_level_ice"
  double value = 0.0;  ///< NaN: no data (an empty window, a run shorter than the moving window)
  std::string unit;
  std::string description;
};

/// A named time window (t0, t1] of a run, s.
struct TimeWindow {
  std::string name;
  double t0 = 0.0, t1 = 0.0;
};

/// (M1): mean of y_k over the steps with t0 < t_k <= t1; NaN when there is none.
double window_mean(const std::vector<double>& t, const std::vector<double>& y, double t0, double t1);

/// (M2): sum of y_k (t_k - t_{k-1}) with t_{-1} = t_start (the time before the first step).
double impulse(const std::vector<double>& t, const std::vector<double>& y, double t_start);

/// (M3): the q-quantile (0 <= q <= 1) of y, linear between the closest ranks; NaN when empty.
double percentile(std::vector<double> y, double q);

/// (M4): the largest time-weighted mean of y over a trailing window of `width` s that lies
/// within the run (t_k - t_start >= width, up to 1e-9 width of round-off); NaN when the run is
/// shorter than `width`.
double max_moving_mean(const std::vector<double>& t, const std::vector<double>& y, double t_start, double width);

/// The time window in which a point moving as x(t) = x_start + speed (t - t_start) lies in
/// [x0, x1] (speed > 0), as (t0, t1]; an empty window (t1 < t0) when speed <= 0.
TimeWindow penetration_window(const std::string& name, double x0, double x1, double x_start, double speed,
                              double t_start);

}  // namespace hs::analysis
