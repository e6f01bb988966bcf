// The study's statistics (src/study/summary.h): the percentile-bootstrap intervals on synthetic
// seeds with a known answer, their reproducibility, and the summary rows against a reference.
#include <gtest/gtest.h>

#include "study/summary.h"

#include <cmath>
#include <random>
#include <vector>

using hs::study::bootstrap_compare;
using hs::study::bootstrap_mean;

namespace {

/// n normal samples of mean mu and standard deviation sd from a fixed generator.
std::vector<double> normal(std::size_t n, double mu, double sd, unsigned seed) {
  std::mt19937_64 g(seed);
  std::vector<double> x(n);
  // Box-Muller from the generator's 53-bit uniforms (std::normal_distribution is not portable).
  for (std::size_t k = 0; k < n; ++k) {
    const double u1 = (static_cast<double>(g() >> 11) + 0.5) * 0x1p-53, u2 = static_cast<double>(g() >> 11) * 0x1p-53;
    x[k] = mu + sd * std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
  }
  return x;
}

double sample_sd(const std::vector<double>& x) {
  double m = 0.0, s = 0.0;
  for (const double v : x) m += v;
  m /= static_cast<double>(x.size());
  for (const double v : x) s += (v - m) * (v - m);
  return std::sqrt(s / static_cast<double>(x.size() - 1));
}

}  // namespace

// The interval of the mean holds the sample mean, is about +-1.96 s/sqrt(n) wide (the bootstrap's
// normal limit), and shrinks as 1/sqrt(n): 16x the samples, a quarter of the width.
TEST(StudyBootstrap, MeanIntervalIsTheNormalOneAndShrinksWithTheSamples) {
  const auto small = normal(10, 5.0, 1.0, 1), large = normal(160, 5.0, 1.0, 2);
  const auto a = bootstrap_mean(small), b = bootstrap_mean(large);
  EXPECT_EQ(a.n, 10u);
  EXPECT_LT(a.low, a.value);
  EXPECT_GT(a.high, a.value);
  EXPECT_LT(b.low, 5.0);  // the true mean inside (160 samples)
  EXPECT_GT(b.high, 5.0);
  // The percentile interval of the mean is the plug-in one, s sqrt((n-1)/n) / sqrt(n): measured
  // width / (2 x 1.96 x that) 1.015 (n = 10) and 0.987 (n = 160); 10 % allowed.
  const auto normal_width = [](const std::vector<double>& x) {
    const double n = static_cast<double>(x.size());
    return 2.0 * 1.959964 * sample_sd(x) * std::sqrt((n - 1.0) / n) / std::sqrt(n);
  };
  EXPECT_NEAR((a.high - a.low) / normal_width(small), 1.0, 0.1);
  EXPECT_NEAR((b.high - b.low) / normal_width(large), 1.0, 0.1);
  EXPECT_LT(b.high - b.low, 0.5 * (a.high - a.low));
}

// A variant 10 % above the reference: the relative error's interval holds 0.10 (known shift, same
// noise) and excludes 0; with 16x the seeds it is narrower; the ratio is 1 + the error.
TEST(StudyBootstrap, RelativeErrorIntervalHoldsTheKnownShiftAndShrinks) {
  const auto ref = normal(8, 100.0, 2.0, 3), var = normal(8, 110.0, 2.0, 4);
  const auto c = bootstrap_compare(var, ref);
  EXPECT_LT(c.relative_error.low, 0.10);
  EXPECT_GT(c.relative_error.high, 0.10);
  EXPECT_GT(c.relative_error.low, 0.0);
  EXPECT_DOUBLE_EQ(c.ratio.value, 1.0 + c.relative_error.value);
  EXPECT_NEAR(c.ratio.low, 1.0 + c.relative_error.low, 1e-12);
  const auto c16 = bootstrap_compare(normal(128, 110.0, 2.0, 5), normal(128, 100.0, 2.0, 6));
  EXPECT_LT(c16.relative_error.low, 0.10);
  EXPECT_GT(c16.relative_error.high, 0.10);
  EXPECT_LT(c16.relative_error.high - c16.relative_error.low,
            0.5 * (c.relative_error.high - c.relative_error.low));
}

// The table is reproducible (fixed generator seed): the same inputs give the same bits; another
// generator seed moves the interval a little, not the mean.
TEST(StudyBootstrap, IntervalsAreReproducible) {
  const auto x = normal(6, 1.0, 0.3, 7);
  const auto a = bootstrap_mean(x), b = bootstrap_mean(x), c = bootstrap_mean(x, 4000, 99);
  EXPECT_EQ(a.low, b.low);
  EXPECT_EQ(a.high, b.high);
  EXPECT_EQ(a.value, c.value);
  EXPECT_NE(a.low, c.low);
}

// Degenerate input: one seed gives a zero-width interval at the value; none gives NaN; a
// reference mean of zero gives a NaN error (never a division by zero in the table).
TEST(StudyBootstrap, OneSeedNoSeedAndAZeroReference) {
  const auto one = bootstrap_mean({3.5});
  EXPECT_EQ(one.value, 3.5);
  EXPECT_EQ(one.low, 3.5);
  EXPECT_EQ(one.high, 3.5);
  EXPECT_TRUE(std::isnan(bootstrap_mean({}).value));
  EXPECT_TRUE(std::isnan(bootstrap_compare({1.0, 2.0}, {0.0, 0.0}).relative_error.value));
}

// summarise: one row per (variant, quantity), core_hours last; the reference has no comparison;
// the CSV has the documented header and empty cells where there is none.
TEST(StudySummary, RowsPerVariantAndQuantityWithTheReferenceComparison) {
  using hs::study::MemberFigures;
  std::vector<MemberFigures> m;
  for (int s = 0; s < 3; ++s) {
    m.push_back({"ref", {{"peak", "N", "", 100.0 + s}, {"core_hours", "h", "", 2.0}}});
    m.push_back({"fast", {{"peak", "N", "", 90.0 + s}, {"core_hours", "h", "", 0.5}}});
  }
  const auto rows = hs::study::summarise(m, {"fast", "ref", "absent"}, "ref");
  ASSERT_EQ(rows.size(), 4u);
  EXPECT_EQ(rows[0].variant, "fast");
  EXPECT_EQ(rows[0].quantity, "peak");
  EXPECT_EQ(rows[1].quantity, "core_hours");
  EXPECT_TRUE(rows[0].has_reference);
  EXPECT_FALSE(rows[2].has_reference);
  EXPECT_NEAR(rows[0].vs_reference.relative_error.value, (91.0 - 101.0) / 101.0, 1e-15);
  EXPECT_DOUBLE_EQ(rows[1].vs_reference.ratio.value, 0.25);
  const std::string csv = hs::study::summary_csv(rows);
  EXPECT_EQ(csv.substr(0, csv.find('\n')),
            "variant,quantity,unit,n,mean,mean_ci_low,mean_ci_high,rel_error,rel_error_ci_low,rel_error_ci_high,"
            "ratio,ratio_ci_low,ratio_ci_high");
  EXPECT_NE(csv.find("\nref,peak,N,3,101,100,102,,,,,,\n"), std::string::npos) << csv;
}
