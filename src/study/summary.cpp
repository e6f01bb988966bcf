#include "study/summary.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <random>
#include <sstream>

namespace hs::study {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

double mean(const std::vector<double>& x) {
  double s = 0.0;
  for (const double v : x) s += v;
  return x.empty() ? kNaN : s / static_cast<double>(x.size());
}

/// Uniform index in [0, n) from the generator's 53-bit uniform (platform-independent, unlike
/// std::uniform_int_distribution).
std::size_t draw(std::mt19937_64& g, std::size_t n) {
  const double u = static_cast<double>(g() >> 11) * 0x1p-53;
  return std::min(n - 1, static_cast<std::size_t>(u * static_cast<double>(n)));
}

/// The mean of a resample of x with replacement.
double resampled_mean(const std::vector<double>& x, std::mt19937_64& g) {
  double s = 0.0;
  for (std::size_t k = 0; k < x.size(); ++k) s += x[draw(g, x.size())];
  return s / static_cast<double>(x.size());
}

/// Quantile q of sorted values, linear between order statistics (Hyndman & Fan type 7).
double quantile(const std::vector<double>& sorted, double q) {
  if (sorted.empty()) return kNaN;
  const double h = q * static_cast<double>(sorted.size() - 1);
  const auto lo = static_cast<std::size_t>(std::floor(h));
  const std::size_t hi = std::min(lo + 1, sorted.size() - 1);
  return sorted[lo] + (h - static_cast<double>(lo)) * (sorted[hi] - sorted[lo]);
}

Interval interval(double value, std::vector<double> stats, std::size_t n) {
  std::sort(stats.begin(), stats.end());
  return {value, quantile(stats, 0.025), quantile(stats, 0.975), n};
}

}  // namespace

Interval bootstrap_mean(const std::vector<double>& x, int resamples, std::uint64_t seed) {
  if (x.empty()) return {kNaN, kNaN, kNaN, 0};
  std::mt19937_64 g(seed);
  std::vector<double> stats(static_cast<std::size_t>(resamples));
  for (double& s : stats) s = resampled_mean(x, g);
  return interval(mean(x), std::move(stats), x.size());
}

Comparison bootstrap_compare(const std::vector<double>& a, const std::vector<double>& r, int resamples,
                             std::uint64_t seed) {
  const double ma = mean(a), mr = mean(r);
  if (a.empty() || r.empty() || mr == 0.0) return {{kNaN, kNaN, kNaN, a.size()}, {kNaN, kNaN, kNaN, a.size()}};
  std::mt19937_64 g(seed);
  std::vector<double> err, ratio;
  for (int k = 0; k < resamples; ++k) {
    const double sa = resampled_mean(a, g), sr = resampled_mean(r, g);
    if (sr == 0.0) continue;
    err.push_back((sa - sr) / std::abs(sr));
    ratio.push_back(sa / sr);
  }
  return {interval((ma - mr) / std::abs(mr), std::move(err), a.size()), interval(ma / mr, std::move(ratio), a.size())};
}

std::vector<SummaryRow> summarise(const std::vector<MemberFigures>& members, const std::vector<std::string>& variants,
                                  const std::string& reference) {
  // variant -> quantity -> values over seeds (members in study order); units by quantity.
  std::map<std::string, std::map<std::string, std::vector<double>>> values;
  std::map<std::string, std::string> units;
  for (const MemberFigures& m : members)
    for (const Quantity& q : m.quantities) {
      if (std::isfinite(q.value)) values[m.variant][q.name].push_back(q.value);
      units[q.name] = q.unit;
    }
  std::vector<std::string> names;
  for (const auto& [name, unit] : units)
    if (name != "core_hours") names.push_back(name);
  if (units.count("core_hours")) names.push_back("core_hours");
  const auto ref = values.find(reference);
  std::vector<SummaryRow> rows;
  for (const std::string& v : variants) {
    const auto it = values.find(v);
    if (it == values.end()) continue;
    for (const std::string& q : names) {
      const auto qv = it->second.find(q);
      if (qv == it->second.end()) continue;
      SummaryRow row{v, q, units[q], bootstrap_mean(qv->second), false, {}};
      if (!reference.empty() && v != reference && ref != values.end() && ref->second.count(q)) {
        row.has_reference = true;
        row.vs_reference = bootstrap_compare(qv->second, ref->second.at(q));
      }
      rows.push_back(std::move(row));
    }
  }
  return rows;
}

std::string number_text(double x) {
  if (!std::isfinite(x)) return "";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.10g", x);
  return buf;
}

std::string csv_cell(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string q = "\"";
  for (const char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}

std::string summary_csv(const std::vector<SummaryRow>& rows) {
  std::ostringstream s;
  s << "variant,quantity,unit,n,mean,mean_ci_low,mean_ci_high,rel_error,rel_error_ci_low,rel_error_ci_high,"
       "ratio,ratio_ci_low,ratio_ci_high\n";
  for (const SummaryRow& r : rows) {
    s << csv_cell(r.variant) << "," << csv_cell(r.quantity) << "," << csv_cell(r.unit) << "," << r.mean.n << "," << number_text(r.mean.value) << ","
      << number_text(r.mean.low) << "," << number_text(r.mean.high);
    const Comparison& c = r.vs_reference;
    if (r.has_reference)
      s << "," << number_text(c.relative_error.value) << "," << number_text(c.relative_error.low) << ","
        << number_text(c.relative_error.high) << "," << number_text(c.ratio.value) << "," << number_text(c.ratio.low)
        << "," << number_text(c.ratio.high) << "\n";
    else
      s << ",,,,,,\n";
  }
  return s.str();
}

namespace {

std::string short_number(double x) {
  if (!std::isfinite(x)) return "-";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.4g", x);
  return buf;
}

std::string with_interval(const Interval& i, double scale = 1.0, const char* suffix = "") {
  return short_number(i.value * scale) + suffix + " [" + short_number(i.low * scale) + ", " +
         short_number(i.high * scale) + "]";
}

}  // namespace

std::string summary_markdown(const std::vector<SummaryRow>& rows, const std::string& study_name,
                             const std::string& reference, const std::string& primary_metric) {
  std::ostringstream s;
  s << "# Study " << study_name << "\n\nMeans over seeds with bootstrap 95 % intervals [low, high] ("
    << kBootstrapResamples << " resamples; docs/study.md).\n\n"
    << "| variant | quantity | unit | n | mean [95 % CI] |\n|---|---|---|---|---|\n";
  for (const SummaryRow& r : rows)
    s << "| " << r.variant << " | " << r.quantity << " | " << r.unit << " | " << r.mean.n << " | "
      << with_interval(r.mean) << " |\n";
  if (reference.empty()) return s.str();
  s << "\n## Against the reference `" << reference << "`\n\nRelative error (mean - reference mean) / |reference "
    << "mean| in %, and the cost ratio (mean core-hours / the reference's), with 95 % intervals."
    << (primary_metric.empty() ? "" : " The front (front.png) plots `" + primary_metric + "`.") << "\n\n"
    << "| variant | quantity | n | relative error, % [95 % CI] |\n|---|---|---|---|\n";
  for (const SummaryRow& r : rows)
    if (r.has_reference && r.quantity != "core_hours")
      s << "| " << r.variant << " | " << r.quantity << " | " << r.mean.n << " | "
        << with_interval(r.vs_reference.relative_error, 100.0) << " |\n";
  s << "\n| variant | cost ratio [95 % CI] |\n|---|---|\n";
  for (const SummaryRow& r : rows)
    if (r.has_reference && r.quantity == "core_hours")
      s << "| " << r.variant << " | " << with_interval(r.vs_reference.ratio) << " |\n";
  return s.str();
}

}  // namespace hs::study
