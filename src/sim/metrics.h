// The run metrics (docs/metrics.md), computed from a run file's contents by one function,
// compute_run_metrics: the run summary, `hybridsim metrics`, the studies and tools/metrics.py
// (through `hybridsim metrics --json`) all get them from it. The formulas are in
// analysis/metrics.h; here the file is read, the penetration windows found from the scene, and
// the metrics named, with their units and descriptions.
#pragma once

#include "analysis/metrics.h"

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace hs::sim {

/// A window a study gives: a time range {name, t0, t1} (s), or the range of the structure's
/// waterline front along the drift {name, x0, x1} (m; docs/metrics.md, "Windows").
struct MetricWindow {
  std::string name;
  bool by_position = false;  ///< x0, x1 (m) rather than t0, t1 (s)
  double from = 0.0, to = 0.0;
};

/// [{"name": .., "t0": .., "t1": ..} or {"name": .., "x0": .., "x1": ..}, ...]. InputError at
/// `where` (with the index) for anything else.
std::vector<MetricWindow> metric_windows_from_json(const nlohmann::json& j, const std::string& where);

struct MetricsOptions {
  /// Windows added to the scene's (a name the scene's windows use replaces that window).
  std::vector<MetricWindow> windows;
  double moving_window = 1.0;  ///< s, the width of the moving mean of the peak load (M4)
};

/// Every metric of the run file at `path`, in a fixed order (docs/metrics.md lists them). Reads
/// the per-step load (/load_per_step), the scene (root attribute), the last rows of /series and
/// /analysis when present. InputError naming the file when it is not a run file of a scene with a
/// structure, or has no per-step load.
std::vector<analysis::Metric> compute_run_metrics(const std::string& path, const MetricsOptions& opt = {});

/// The pile at the load peak (analysis/metrics.h, M5): the window of the peak `width` s moving
/// mean of the horizontal load (the whole run when it is shorter) and the means of the pile clock's
/// samples in it (/pile_per_clock; NaN where none is finite: no pile, no pier, or a file without
/// the series).
struct PileAtLoadPeak {
  analysis::PeakWindow window;
  double height_mean, slope_deg, porosity;
};

/// From the run file at `path` (closed); InputError as compute_run_metrics.
PileAtLoadPeak pile_at_load_peak(const std::string& path, double width = 1.0);

/// /analysis/metrics of the run file, in name order; empty when the group is absent.
std::vector<analysis::Metric> read_run_metrics(const std::string& path);

/// Adds /analysis/metrics (one scalar dataset per metric) to the closed run file; /analysis must exist.
void write_run_metrics(const std::string& path, const std::vector<analysis::Metric>& metrics);

/// {"<name>": {"value": v (null for NaN), "unit": .., "description": ..}, ...}.
nlohmann::json metrics_to_json(const std::vector<analysis::Metric>& metrics);

/// kMetricsGroup: where the run file holds them.
inline constexpr const char* kMetricsGroup = "/analysis/metrics";

}  // namespace hs::sim
