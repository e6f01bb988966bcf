#include "analysis/metrics.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace hs::analysis {

namespace {
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
}

double window_mean(const std::vector<double>& t, const std::vector<double>& y, double t0, double t1) {
  double sum = 0.0;
  std::size_t n = 0;
  for (std::size_t k = 0; k < t.size() && k < y.size(); ++k)
    if (t[k] > t0 && t[k] <= t1) {
      sum += y[k];
      ++n;
    }
  return n ? sum / static_cast<double>(n) : kNaN;
}

double impulse(const std::vector<double>& t, const std::vector<double>& y, double t_start) {
  double sum = 0.0, before = t_start;
  for (std::size_t k = 0; k < t.size() && k < y.size(); ++k) {
    sum += y[k] * (t[k] - before);
    before = t[k];
  }
  return sum;
}

double percentile(std::vector<double> y, double q) {
  if (y.empty()) return kNaN;
  std::sort(y.begin(), y.end());
  const double r = q * static_cast<double>(y.size() - 1);
  const auto lo = static_cast<std::size_t>(std::floor(r));
  const std::size_t hi = std::min(lo + 1, y.size() - 1);
  return y[lo] + (r - static_cast<double>(lo)) * (y[hi] - y[lo]);
}

double max_moving_mean(const std::vector<double>& t, const std::vector<double>& y, double t_start, double width) {
  // Prefix sums of y dt and dt in long double: a window sum is a difference of two of them.
  const std::size_t n = std::min(t.size(), y.size());
  std::vector<long double> sy(n + 1, 0.0L), st(n + 1, 0.0L);
  double before = t_start;
  for (std::size_t k = 0; k < n; ++k) {
    const double dt = t[k] - before;
    sy[k + 1] = sy[k] + static_cast<long double>(y[k]) * dt;
    st[k + 1] = st[k] + dt;
    before = t[k];
  }
  double best = kNaN;
  std::size_t j = 0;  // first step inside the window ending at step k: t_j > t_k - width
  const double slack = 1e-9 * width;
  for (std::size_t k = 0; k < n; ++k) {
    if (t[k] - t_start < width - slack) continue;
    while (j < k && t[j] <= t[k] - width + slack) ++j;
    const long double span = st[k + 1] - st[j];
    if (!(span > 0.0L)) continue;
    const double m = static_cast<double>((sy[k + 1] - sy[j]) / span);
    if (std::isnan(best) || m > best) best = m;
  }
  return best;
}

TimeWindow penetration_window(const std::string& name, double x0, double x1, double x_start, double speed,
                              double t_start) {
  if (!(speed > 0.0)) return {name, 0.0, -1.0};
  return {name, t_start + (x0 - x_start) / speed, t_start + (x1 - x_start) / speed};
}

}  // namespace hs::analysis
