// The run metrics' formulas (analysis/metrics.h, M1-M4; docs/metrics.md) on synthetic per-step
// series with known answers: a constant force, a ramp, a square pulse. 300 steps of dt = 0.01 s
// (t_k = k dt, t_0 = 0); the expected values are the closed forms below.
#include "analysis/metrics.h"

#include <gtest/gtest.h>

#include <cmath>
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

}  // namespace
