// The ridge generator's entry points: see ridge.h and docs/ridge.md.
#include "ridge/internal.h"

#include <chrono>

namespace hs::rigid {

std::vector<double> sample_log_aspect(const AspectLognormal& a, std::size_t n, std::uint64_t seed) {
  detail::Rng rng(seed);
  double m, s;
  a.log_params(m, s);
  std::vector<double> out(n);
  for (double& v : out) v = detail::sample_ln_r(rng, m, s);
  return out;
}

RidgeEstimate ridge_estimate(const RidgeDef& d) {
  RidgeEstimate e;
  // The envelopes' cross-sections by the trapezoid rule on 4000 intervals (a bounded cost for
  // any ridge size; generate_ridge integrates on a 2 cm grid).
  auto section = [&](bool keel, double hw) {
    double lo = -hw, hi = hw;
    if (keel && !d.keel_profile.empty()) lo = d.keel_profile.front().position, hi = d.keel_profile.back().position;
    if (!(hi > lo)) return 0.0;
    auto thick = [&](double x) {
      return keel ? std::max(0.0, keel_target_depth(d, x) - ice_draft(d, x))
                  : std::max(0.0, sail_target_height(d, x) - ice_freeboard(d, x));
    };
    const int n = 4000;
    double a = 0.0;
    for (int i = 0; i < n; ++i) {
      const double x0 = lo + (hi - lo) * i / n, x1 = lo + (hi - lo) * (i + 1) / n;
      a += 0.5 * (thick(x0) + thick(x1)) * (x1 - x0);
    }
    return a;
  };
  e.keel_volume = section(true, keel_half_width(d)) * d.length;
  e.sail_volume = d.sail_height > 0.0 ? section(false, sail_half_width(d)) * d.length : 0.0;
  // Blocks are L x B x h with L = h r, ln r ~ N(m, s), B = L U(wmin, wmax): E[L B h] = h^3 E[r^2] E[U].
  double m = 0.0, sd = 0.0;
  d.aspect.log_params(m, sd);
  const double h = d.block_thickness;
  e.mean_block_volume =
      h * h * h * std::exp(2.0 * m + 2.0 * sd * sd) * 0.5 * (d.width_fraction_min + d.width_fraction_max);
  e.blocks = e.mean_block_volume > 0 ? (1.0 - d.fill_porosity) * (e.keel_volume + e.sail_volume) / e.mean_block_volume
                                     : 0.0;
  e.bytes = e.blocks * kRidgeBytesPerBlock;
  return e;
}

// generate_ridge runs the phases in order (docs/ridge.md): the ice sheet, placement (greedy
// deposition into the target envelope), the rigid world, compaction and settling, freeze
// joints, and the report (achieved profile and porosity). The random stream is drawn in
// placement only, in a fixed order, so a seed gives the same ridge bit for bit.
RidgeResult generate_ridge(const RidgeDef& def, const RidgeProgressFn& progress) {
  validate_ridge_def(def, "ridge");
  const auto wall0 = std::chrono::steady_clock::now();
  RidgeResult res;
  res.def = def;
  detail::RidgeRun run(def, progress);
  detail::add_ice_sheet(run, res.ice);
  std::vector<detail::Placed> placed = detail::place_blocks(run, res.stats);
  run.report("place", 0.0, 0.0, placed.size());
  const double ke = detail::settle_blocks(run, placed, res);
  detail::join_and_measure(run, placed, ke, res);
  res.stats.wall_time =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  return res;
}

}  // namespace hs::rigid
