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
//
// The load peak's window (M5): the window (t_k - W, t_k] of the step k at which (M4) peaks (the
// first such step); for a run shorter than W, the whole run (t_0, t_N]. A pile figure "at the
// load peak" is the mean of its finite samples with t in that window.
//
// The pile's shape ahead of the cone (P1, P2), on a grid of square cells of side `cell` in
//   d = u - sqrt(R^2 - v^2)  (horizontal distance ahead of the cone face on the waterline, R its
//                             radius; u, v as for the pile band: along and across `upstream`),
//   v in [-R, R], 0 < d <= ahead;
// per cell the crest c = max(z + r) - water_level over its particles (0 when none is above the
// water) and the particle volume V = sum 4/3 pi r^3 over its particles whose centre lies above
// the water level. The pile's cells: in each strip across (one v), the cells from the face outward
// up to the first with c <= min_height (the pile's toe); ice raised farther ahead is not the pile.
//   (P1) rubble slope angle  theta = atan(-b) (deg), b the least-squares slope of c against the
//        cell's centre d over the pile's cells; NaN with fewer than two distinct d among them.
//   (P2) pile porosity  e = 1 - sum V / sum (cell^2 c) over the pile's cells: the envelope is the
//        column from the waterline up to the crest; NaN without a pile cell.
// Crests combine across ranks by an element-wise max, volumes by a sum.
#pragma once

#include "common/types.h"

#include <cstddef>
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

/// (M5): the window of the load peak, (t0, t1] (s), and the peak moving mean (NaN for a run
/// shorter than `width`, whose window is then the whole run; whole_run says so). t0 = t1 = NaN
/// for an empty series.
struct PeakWindow {
  double value, t0, t1;
  bool whole_run = false;
};
PeakWindow load_peak_window(const std::vector<double>& t, const std::vector<double>& y, double t_start, double width);

/// Mean of the finite y_k with t0 < t_k <= t1; NaN when there is none.
double finite_window_mean(const std::vector<double>& t, const std::vector<double>& y, double t0, double t1);

/// The grid of (P1), (P2).
struct PileShapeGrid {
  Vec3 axis_point = Vec3::Zero();  ///< a point on the vertical pier axis (world), m
  Vec3 upstream = Vec3::UnitX();   ///< horizontal unit vector towards the incoming ice
  double radius = 7.0;             ///< R, the cone's waterline radius, m
  double ahead = 14.0;             ///< d extent ahead of the face, m
  double cell = 0.25;              ///< cell side, m
  double water_level = 0.0;        ///< m
  double min_height = 0.25;        ///< a pile cell's crest exceeds this, m above the water
  std::size_t cells_d() const;     ///< cells along d
  std::size_t cells_v() const;     ///< cells across v
};

/// Per-cell crest (m above the water, >= 0; max-combined) and particle volume (m^3; summed),
/// cells_d() x cells_v(), d-major.
struct PileShapeCells {
  std::vector<double> crest, volume;
};
PileShapeCells pile_shape_cells(const PileShapeGrid& g, const Vec3* x, const double* r, std::size_t n);

/// (P1) slope_deg, (P2) porosity from the combined cells; NaN where not defined.
struct PileShape {
  double slope_deg, porosity;
  std::size_t pile_cells = 0;
};
PileShape pile_shape(const PileShapeGrid& g, const PileShapeCells& c);

/// The time window in which a point moving as x(t) = x_start + speed (t - t_start) lies in
/// [x0, x1] (speed > 0), as (t0, t1]; an empty window (t1 < t0) when speed <= 0.
TimeWindow penetration_window(const std::string& name, double x0, double x1, double x_start, double speed,
                              double t_start);

}  // namespace hs::analysis
