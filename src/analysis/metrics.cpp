#include "analysis/metrics.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

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
  return load_peak_window(t, y, t_start, width).value;
}

PeakWindow load_peak_window(const std::vector<double>& t, const std::vector<double>& y, double t_start, double width) {
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
  PeakWindow w{kNaN, kNaN, kNaN};
  double best = kNaN;
  std::size_t j = 0;  // first step inside the window ending at step k: t_j > t_k - width
  const double slack = 1e-9 * width;
  for (std::size_t k = 0; k < n; ++k) {
    if (t[k] - t_start < width - slack) continue;
    while (j < k && t[j] <= t[k] - width + slack) ++j;
    const long double span = st[k + 1] - st[j];
    if (!(span > 0.0L)) continue;
    const double m = static_cast<double>((sy[k + 1] - sy[j]) / span);
    if (std::isnan(best) || m > best) {
      best = m;
      w = {m, t[k] - width, t[k]};
    }
  }
  if (std::isnan(best) && n > 0) w = {kNaN, t_start, t[n - 1], true};
  return w;
}

double finite_window_mean(const std::vector<double>& t, const std::vector<double>& y, double t0, double t1) {
  double sum = 0.0;
  std::size_t n = 0;
  for (std::size_t k = 0; k < t.size() && k < y.size(); ++k)
    if (t[k] > t0 && t[k] <= t1 && std::isfinite(y[k])) {
      sum += y[k];
      ++n;
    }
  return n ? sum / static_cast<double>(n) : kNaN;
}

std::size_t PileShapeGrid::cells_d() const {
  return static_cast<std::size_t>(std::max(1.0, std::ceil(ahead / cell)));
}

std::size_t PileShapeGrid::cells_v() const {
  return static_cast<std::size_t>(std::max(1.0, std::ceil(2.0 * radius / cell)));
}

PileShapeCells pile_shape_cells(const PileShapeGrid& g, const Vec3* x, const double* r, std::size_t n) {
  const std::size_t nd = g.cells_d(), nv = g.cells_v();
  PileShapeCells c{std::vector<double>(nd * nv, 0.0), std::vector<double>(nd * nv, 0.0)};
  const Vec3 up = Vec3(g.upstream.x(), g.upstream.y(), 0.0).normalized();
  const double ax = up.x(), ay = up.y();  // across = (-ay, ax)
  for (std::size_t i = 0; i < n; ++i) {
    const double dx = x[i].x() - g.axis_point.x(), dy = x[i].y() - g.axis_point.y();
    const double u = dx * ax + dy * ay, v = -dx * ay + dy * ax;
    if (u <= 0.0 || std::abs(v) > g.radius) continue;
    const double d = u - std::sqrt(std::max(0.0, g.radius * g.radius - v * v));
    if (d <= 0.0 || d > g.ahead) continue;
    const std::size_t kd = std::min(nd - 1, static_cast<std::size_t>(std::floor(d / g.cell)));
    const std::size_t kv = std::min(nv - 1, static_cast<std::size_t>(std::floor((v + g.radius) / g.cell)));
    const std::size_t k = kd * nv + kv;
    c.crest[k] = std::max(c.crest[k], x[i].z() + r[i] - g.water_level);
    if (x[i].z() > g.water_level) c.volume[k] += 4.0 / 3.0 * std::numbers::pi * r[i] * r[i] * r[i];
  }
  return c;
}

PileShape pile_shape(const PileShapeGrid& g, const PileShapeCells& c) {
  const std::size_t nv = g.cells_v();
  // Least squares in long double over the pile's cells: sums of d, c, d^2, d c.
  long double n = 0, sd = 0, sc = 0, sdd = 0, sdc = 0, vol = 0, env = 0;
  double d_lo = kNaN, d_hi = kNaN;
  const std::size_t nd = std::min(c.crest.size(), c.volume.size()) / std::max<std::size_t>(nv, 1);
  std::vector<bool> open(nv, true);  // per strip across: no cell at most min_height met yet
  for (std::size_t k = 0; k < nd * nv; ++k) {
    const double h = c.crest[k];
    if (!(h > g.min_height)) open[k % nv] = false;
    if (!open[k % nv]) continue;
    const double d = (static_cast<double>(k / nv) + 0.5) * g.cell;
    n += 1;
    sd += d;
    sc += h;
    sdd += static_cast<long double>(d) * d;
    sdc += static_cast<long double>(d) * h;
    vol += c.volume[k];
    env += static_cast<long double>(g.cell) * g.cell * h;
    d_lo = std::isnan(d_lo) ? d : std::min(d_lo, d);
    d_hi = std::isnan(d_hi) ? d : std::max(d_hi, d);
  }
  PileShape s{kNaN, kNaN, static_cast<std::size_t>(n)};
  if (n > 0) s.porosity = static_cast<double>(1.0L - vol / env);
  const long double sxx = sdd - sd * sd / n;
  if (n > 1 && d_hi > d_lo && sxx > 0) {
    const double b = static_cast<double>((sdc - sd * sc / n) / sxx);
    s.slope_deg = std::atan(-b) * 180.0 / std::numbers::pi;
  }
  return s;
}

TimeWindow penetration_window(const std::string& name, double x0, double x1, double x_start, double speed,
                              double t_start) {
  if (!(speed > 0.0)) return {name, 0.0, -1.0};
  return {name, t_start + (x0 - x_start) / speed, t_start + (x1 - x_start) / speed};
}

}  // namespace hs::analysis
