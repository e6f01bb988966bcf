#include "app/metrics_command.h"

#include "app/text.h"
#include "common/error.h"
#include "json/reader.h"
#include "sim/metrics.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iomanip>

namespace hs::app {

void print_metrics_table(std::ostream& out, const std::vector<analysis::Metric>& metrics) {
  std::size_t w = 0;
  for (const auto& m : metrics) w = std::max(w, m.name.size());
  out << "  metrics (docs/metrics.md; \"no data\": not defined for this run):\n";
  for (const auto& m : metrics)
    out << "    " << std::left << std::setw(static_cast<int>(w)) << m.name << "  " << std::right << std::setw(11)
        << (std::isnan(m.value) ? std::string("no data") : sci(m.value, 5))
        << (std::isnan(m.value) ? std::string() : " " + m.unit) << "\n";
}

int metrics_command(const MetricsCommandOptions& opt, std::ostream& out) {
  if (!std::filesystem::is_regular_file(opt.run_file))
    throw InputError("RUN.h5", "no run file '" + opt.run_file + "'");
  sim::MetricsOptions mo;
  if (!opt.windows_file.empty()) mo.windows = sim::metric_windows_from_json(read_json_file(opt.windows_file), opt.windows_file);
  if (opt.moving_window > 0) mo.moving_window = opt.moving_window;
  const bool custom = !mo.windows.empty() || opt.moving_window > 0;
  std::vector<analysis::Metric> m = custom ? std::vector<analysis::Metric>{} : sim::read_run_metrics(opt.run_file);
  const bool stored = !m.empty();
  if (!stored) m = sim::compute_run_metrics(opt.run_file, mo);
  if (opt.json) {
    out << sim::metrics_to_json(m).dump(2) << "\n";
  } else {
    out << "hybridsim: metrics of " << opt.run_file << " ("
        << (stored ? "stored in /analysis/metrics" : "computed from the run file") << ")\n";
    print_metrics_table(out, m);
  }
  return 0;
}

}  // namespace hs::app
