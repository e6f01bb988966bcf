// A study's statistics over seeds (docs/study.md, "Summary"): per variant the mean of each
// metric and of the cost with a percentile-bootstrap 95 % confidence interval, and against a
// reference variant the relative error and the ratio of means with theirs.
//
// Bootstrap (Efron & Tibshirani 1993, ch. 13, the percentile interval): draw B resamples of the
// seeds with replacement (both variants' seeds, independently, for a comparison), compute the
// statistic on each, and take the 2.5 % and 97.5 % quantiles (linear interpolation between order
// statistics) of the B values. The generator is std::mt19937_64 with a fixed seed and indices
// floor(u n) from its 53-bit uniforms, so the same inputs give the same table on any platform.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace hs::study {

/// Resamples of every interval of a study table.
inline constexpr int kBootstrapResamples = 4000;
/// The generator's seed: fixed, so that a table is reproducible.
inline constexpr std::uint64_t kBootstrapSeed = 20261207;

/// A statistic over n samples with its 95 % interval; NaN where undefined (n = 0; the interval
/// of n = 1 is the value itself: one seed says nothing about the spread).
struct Interval {
  double value = 0.0, low = 0.0, high = 0.0;
  std::size_t n = 0;
};

/// The mean of x and its percentile-bootstrap 95 % interval.
Interval bootstrap_mean(const std::vector<double>& x, int resamples = kBootstrapResamples,
                        std::uint64_t seed = kBootstrapSeed);

/// A variant against the reference: relative error (mean(a) - mean(r)) / |mean(r)| and the ratio
/// mean(a) / mean(r), each with its interval from the same resamples of a and r (n = size of a).
/// NaN where mean(r) = 0; resamples whose reference mean is 0 are left out.
struct Comparison {
  Interval relative_error, ratio;
};
Comparison bootstrap_compare(const std::vector<double>& a, const std::vector<double>& r,
                             int resamples = kBootstrapResamples, std::uint64_t seed = kBootstrapSeed);

/// One metric (or the cost) of one member.
struct Quantity {
  std::string name, unit, description;
  double value = 0.0;
};

/// One member's figures as the summary needs them: its variant and every quantity (metrics and
/// "core_hours"). Only finished members are passed.
struct MemberFigures {
  std::string variant;
  std::vector<Quantity> quantities;
};

/// One row of summary.csv: a quantity of a variant over its seeds.
struct SummaryRow {
  std::string variant, quantity, unit;
  Interval mean;
  bool has_reference = false;  ///< a reference is named and this is not it
  Comparison vs_reference;
};

/// The rows, variant by variant in the order of `variants`, quantities in name order with
/// "core_hours" last. A variant without a finished member gets no rows.
std::vector<SummaryRow> summarise(const std::vector<MemberFigures>& members, const std::vector<std::string>& variants,
                                  const std::string& reference);

/// summary.csv (header + rows; empty cells where NaN) and summary.md (the same as tables: per
/// variant the means, then the errors against the reference with the cost ratio).
std::string summary_csv(const std::vector<SummaryRow>& rows);
std::string summary_markdown(const std::vector<SummaryRow>& rows, const std::string& study_name,
                             const std::string& reference, const std::string& primary_metric);

/// A double as CSV/markdown text: up to 10 significant digits, "" for NaN.
std::string number_text(double x);

/// A CSV cell: the text, quoted (with quotes doubled) when it holds a comma, quote or newline.
std::string csv_cell(const std::string& s);

}  // namespace hs::study
