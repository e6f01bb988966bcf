// The run metrics' formulas (analysis/metrics.h, M1-M4; docs/metrics.md) on synthetic per-step
// series with known answers: a constant force, a ramp, a square pulse. 300 steps of dt = 0.01 s
// (t_k = k dt, t_0 = 0); the expected values are the closed forms below.
#include "analysis/metrics.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <vector>

namespace {

using namespace hs::analysis;

constexpr double kDt = 0.01;
constexpr int kSteps = 300;  // 3 s

std::vector<double> times() {
  std::vector<double> t(kSteps);
  for (int k = 0; k < kSteps; ++k) t[k] = (k + 1) * kDt;
  return t;
}

/// y_k = f(t_k) for every step.
template <class F>
std::vector<double> series(F f) {
  std::vector<double> y;
  for (double t : times()) y.push_back(f(t));
  return y;
}

// Round-off of sums over 300 steps: measured at most 7.1e-16 relative (the pulse's impulse; the
// ramp's 5.9e-16); the tolerance, 1e-14 relative, is ~14x that.
constexpr double kRel = 1e-14;

TEST(Metrics, ConstantForce) {
  const auto t = times();
  const auto y = series([](double) { return 5.0e5; });
  EXPECT_NEAR(window_mean(t, y, 0.495, 1.505), 5.0e5, 5.0e5 * kRel);
  EXPECT_NEAR(impulse(t, y, 0.0), 5.0e5 * 3.0, 1.5e6 * kRel);  // F T
  EXPECT_NEAR(percentile(y, 0.95), 5.0e5, 5.0e5 * kRel);
  EXPECT_NEAR(max_moving_mean(t, y, 0.0, 1.0), 5.0e5, 5.0e5 * kRel);
}

TEST(Metrics, Ramp) {
  const auto t = times();
  const auto y = series([](double s) { return s; });  // F = t (N, t in s)
  // (M1) mean of t_1..t_N = (N + 1) dt / 2; over (1.005, 2.005]: steps 101..200, mean 1.505.
  EXPECT_NEAR(window_mean(t, y, -1.0, 10.0), (kSteps + 1) * kDt / 2, 1.505 * kRel);
  EXPECT_NEAR(window_mean(t, y, 1.005, 2.005), 1.505, 1.505 * kRel);
  // (M2) sum t_k dt = dt^2 N (N + 1) / 2 = 4.515 N s (the rectangle rule of the steps, not t^2/2).
  EXPECT_NEAR(impulse(t, y, 0.0), kDt * kDt * kSteps * (kSteps + 1) / 2, 4.515 * kRel);
  // (M3) rank r = 0.95 (N - 1) = 284.05 between t_285 = 2.85 and t_286 = 2.86: 2.8505.
  EXPECT_NEAR(percentile(y, 0.95), 2.8505, 2.85 * kRel);
  // (M4) the last full second, steps 201..300: mean (2.01 + 3.00) / 2 = 2.505.
  EXPECT_NEAR(max_moving_mean(t, y, 0.0, 1.0), 2.505, 2.505 * kRel);
}

TEST(Metrics, SquarePulse) {
  const auto t = times();
  // 10 N for steps 101..150 (1.0 s < t <= 1.5 s), 0 otherwise.
  std::vector<double> y(kSteps, 0.0);
  for (int k = 100; k < 150; ++k) y[k] = 10.0;
  EXPECT_NEAR(window_mean(t, y, 0.0, 3.0), 10.0 * 50 / kSteps, 10.0 * kRel);
  EXPECT_NEAR(window_mean(t, y, 1.005, 1.505), 10.0, 10.0 * kRel);
  EXPECT_NEAR(impulse(t, y, 0.0), 10.0 * 0.5, 5.0 * kRel);     // height x duration
  EXPECT_NEAR(percentile(y, 0.95), 10.0, 10.0 * kRel);           // 50 of 300 steps (17 %) at 10 N
  EXPECT_NEAR(percentile(y, 0.80), 0.0, 10.0 * kRel);            // rank 239.2: both neighbours 0
  EXPECT_NEAR(max_moving_mean(t, y, 0.0, 1.0), 5.0, 5.0 * kRel);  // the whole pulse in a 1 s window
  EXPECT_NEAR(max_moving_mean(t, y, 0.0, 0.25), 10.0, 10.0 * kRel);
}

TEST(Metrics, NoDataIsNaN) {
  const auto t = times();
  const auto y = series([](double) { return 1.0; });
  EXPECT_TRUE(std::isnan(window_mean(t, y, 5.0, 6.0)));         // a window after the run
  EXPECT_TRUE(std::isnan(window_mean(t, y, 1.0, 0.5)));         // an empty window
  EXPECT_TRUE(std::isnan(percentile({}, 0.95)));
  EXPECT_TRUE(std::isnan(max_moving_mean(t, y, 0.0, 3.5)));     // a run shorter than the width
  EXPECT_FALSE(std::isnan(max_moving_mean(t, y, 0.0, 3.0)));    // exactly the run: one window
  EXPECT_EQ(impulse({}, {}, 0.0), 0.0);
}

// The window in which the pier's front (x = -0.5 m at t = 0.2 s, 0.4 m/s) lies over the ice
// from x = 0 to x = 10 m: from 0.2 + 0.5 / 0.4 = 1.45 s to 0.2 + 10.5 / 0.4 = 26.45 s.
TEST(Metrics, PenetrationWindow) {
  const TimeWindow w = penetration_window("level_ice", 0.0, 10.0, -0.5, 0.4, 0.2);
  EXPECT_EQ(w.name, "level_ice");
  EXPECT_NEAR(w.t0, 1.45, 1e-14);
  EXPECT_NEAR(w.t1, 26.45, 1e-13);
  const TimeWindow none = penetration_window("x", 0.0, 10.0, -0.5, 0.0, 0.0);  // not moving
  EXPECT_LT(none.t1, none.t0);
}

// (M5): a triangle pulse peaking at t = 2 s: the 1 s moving mean peaks for the window centred on
// it, (1.5, 2.5] s (the windows ending at 2.49 and 2.50 s tie: each drops one end of the
// symmetric pulse, so either may win, one step apart); a run shorter than the width gives the
// whole run.
TEST(Metrics, LoadPeakWindow) {
  const auto t = times();
  const auto y = series([](double s) { return std::max(0.0, 1.0 - std::abs(s - 2.0)); });
  const PeakWindow w = load_peak_window(t, y, 0.0, 1.0);
  EXPECT_NEAR(w.t1, 2.5, kDt + 1e-12);
  EXPECT_NEAR(w.t1 - w.t0, 1.0, 1e-12);
  EXPECT_FALSE(w.whole_run);
  EXPECT_EQ(w.value, max_moving_mean(t, y, 0.0, 1.0));
  const PeakWindow all = load_peak_window(t, y, 0.0, 3.5);
  EXPECT_TRUE(all.whole_run);
  EXPECT_TRUE(std::isnan(all.value));
  EXPECT_EQ(all.t0, 0.0);
  EXPECT_EQ(all.t1, 3.0);
  // The mean of the finite samples in the window: y = t on (1.5, 2.5] with a NaN at 2 s.
  std::vector<double> ts{1.0, 1.5, 2.0, 2.25, 2.5, 3.0}, ys{1.0, 1.5, std::nan(""), 2.25, 2.5, 3.0};
  EXPECT_DOUBLE_EQ(finite_window_mean(ts, ys, 1.5, 2.5), (2.25 + 2.5) / 2.0);
  EXPECT_TRUE(std::isnan(finite_window_mean(ts, ys, 1.9, 2.1)));
}

/// A packed wedge of rubble ahead of a cone of waterline radius 7 m: equal spheres (r = a/2) on a
/// simple cubic lattice of spacing a = the grid's cell, one column per cell, its top at the
/// surface H(d) = (d_toe - d) tan(theta) (rounded to whole particles), standing on a submerged
/// sheet that reaches past the toe and on the cone (d < 0) where nothing counts. Its porosity is
/// 1 - pi/6 exactly; its slope theta.
struct Wedge {
  std::vector<hs::Vec3> x;
  std::vector<double> r;
};
Wedge packed_wedge(const PileShapeGrid& g, double theta_deg, double d_toe) {
  Wedge w;
  const double a = g.cell, R = g.radius, tan_t = std::tan(theta_deg * std::numbers::pi / 180.0);
  for (std::size_t j = 0; j < g.cells_v(); ++j) {
    const double v = -R + (j + 0.5) * a;
    for (int i = -10; i < static_cast<int>(g.cells_d()); ++i) {
      const double d = (i + 0.5) * a, u = d + std::sqrt(R * R - v * v);
      const hs::Vec3 at = g.axis_point + u * hs::Vec3::UnitX() + v * hs::Vec3::UnitY();
      w.x.push_back(at + hs::Vec3(0, 0, g.water_level - a / 2));  // the sheet, below the water
      w.r.push_back(a / 2);
      const long columns = d > 0 ? std::lround(std::max(0.0, (d_toe - d) * tan_t) / a) : 3;
      for (long k = 0; k < columns; ++k) {
        w.x.push_back(at + hs::Vec3(0, 0, g.water_level + a / 2 + k * a));
        w.r.push_back(a / 2);
      }
    }
  }
  return w;
}

TEST(Metrics, PileSlopeAndPorosityOfAPackedWedge) {
  PileShapeGrid g;
  g.axis_point = hs::Vec3(3.0, -1.0, 0.0);
  g.water_level = 0.5;
  g.cell = 0.1;
  g.min_height = 0.1;
  g.ahead = 10.0;
  for (const double theta : {20.0, 35.0, 45.0}) {
    const Wedge w = packed_wedge(g, theta, 6.0);
    const PileShapeCells c = pile_shape_cells(g, w.x.data(), w.r.data(), w.x.size());
    const PileShape s = pile_shape(g, c);
    // Measured: the slope within 0.025 deg (whole particles per column), the porosity to 1.7e-16.
    EXPECT_NEAR(s.slope_deg, theta, 0.25) << theta;
    EXPECT_NEAR(s.porosity, 1.0 - std::numbers::pi / 6.0, 2e-15) << theta;
    EXPECT_GT(s.pile_cells, 100u);
  }
  // Cells split between ranks combine to the same figures (crest: max, volume: sum).
  const Wedge w = packed_wedge(g, 35.0, 6.0);
  const std::size_t half = w.x.size() / 2;
  PileShapeCells a = pile_shape_cells(g, w.x.data(), w.r.data(), half);
  const PileShapeCells b = pile_shape_cells(g, w.x.data() + half, w.r.data() + half, w.x.size() - half);
  for (std::size_t k = 0; k < a.crest.size(); ++k) {
    a.crest[k] = std::max(a.crest[k], b.crest[k]);
    a.volume[k] += b.volume[k];
  }
  const PileShape whole = pile_shape(g, pile_shape_cells(g, w.x.data(), w.r.data(), w.x.size()));
  EXPECT_NEAR(pile_shape(g, a).slope_deg, whole.slope_deg, 1e-12);
  EXPECT_NEAR(pile_shape(g, a).porosity, whole.porosity, 1e-15);
}

TEST(Metrics, NoPileIsNaN) {
  PileShapeGrid g;
  const Wedge w = packed_wedge(g, 30.0, 0.0);  // the sheet alone (and particles on the cone)
  const PileShape s = pile_shape(g, pile_shape_cells(g, w.x.data(), w.r.data(), w.x.size()));
  EXPECT_EQ(s.pile_cells, 0u);
  EXPECT_TRUE(std::isnan(s.slope_deg));
  EXPECT_TRUE(std::isnan(s.porosity));
  // Ice raised above min_height beyond open water ahead of the face (a sheet lifted by a keel) is
  // not a pile: the pile starts at the face.
  Wedge raised = w;
  for (double d = 3.0; d < 6.0; d += g.cell)
    for (double v = -2.0; v < 2.0; v += g.cell) {
      raised.x.push_back(g.axis_point + hs::Vec3(d + std::sqrt(g.radius * g.radius - v * v), v, g.water_level + 0.4));
      raised.r.push_back(g.cell / 2);
    }
  EXPECT_EQ(pile_shape(g, pile_shape_cells(g, raised.x.data(), raised.r.data(), raised.x.size())).pile_cells, 0u);
  const PileShape none = pile_shape(g, pile_shape_cells(g, nullptr, nullptr, 0));
  EXPECT_TRUE(std::isnan(none.slope_deg) && std::isnan(none.porosity));
}

}  // namespace
