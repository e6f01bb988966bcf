// `hybridsim metrics RUN.h5 [--json]`: the run metrics (docs/metrics.md), from /analysis/metrics,
// or computed from the run file (sim::compute_run_metrics) when the group is absent (a run
// stopped before its end) or when windows or a moving-mean width are given.
#pragma once

#include "analysis/metrics.h"

#include <ostream>
#include <string>
#include <vector>

namespace hs::app {

struct MetricsCommandOptions {
  std::string run_file;
  bool json = false;
  std::string windows_file;    ///< JSON array of windows (sim::metric_windows_from_json); "" none
  double moving_window = 0.0;  ///< s; 0: the default (1 s)
};

/// Returns the exit code; InputError (exit 2) for a missing or unreadable file or bad windows.
int metrics_command(const MetricsCommandOptions& opt, std::ostream& out);

/// The metrics as a table: name, value and unit ("no data" for a NaN); one line each.
void print_metrics_table(std::ostream& out, const std::vector<analysis::Metric>& metrics);

}  // namespace hs::app
