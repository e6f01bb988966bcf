// Scatter of lattice bond strengths (scene bonds.strength_spread, docs/engine.md "Bond strength
// spread"): each lattice bond's tensile, shear and compressive strengths are the kind's
// (ParallelBondParams sigma_c, tau_c, sigma_cc) times one factor s drawn for that bond,
//
//   s = exp(mu + sigma_ln z),   sigma_ln^2 = ln(1 + c^2),   mu = -sigma_ln^2 / 2,   z ~ N(0, 1),
//
// a lognormal with E[s] = 1 and sd(s) = c (c = strength_spread), so the mean strength is the
// scene's (and the calibration's) and c is the relative standard deviation. Lognormal rather than
// a truncated normal: s > 0 at any spread with no truncation to state, and the right-skewed
// scatter usual for the strength of a brittle material.
//
// z is a function of (seed, the bond's two global particle ids) alone: a counter-based hash
// (splitmix64, Steele et al. 2014) gives two uniforms, Box-Muller gives z. No sequential random
// stream, so the factor of a bond is the same whatever the rank count, the order bonds are made
// in, a migration or a restart that makes the bond again from its ids.
#pragma once

#include "common/types.h"

#include <cmath>
#include <cstdint>

namespace hs::bonded {

struct BondStrengthSpread {
  double spread = 0.0;     ///< c: relative standard deviation of the strength; 0 = every factor 1 exactly
  std::uint64_t seed = 0;  ///< the scene's seed
};

/// splitmix64's finaliser: a bijective mix of 64 bits.
inline std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

/// The standard normal z of the pair (a, b) (either order) under `seed`.
inline double bond_normal_draw(std::uint64_t seed, GlobalId a, GlobalId b) {
  const GlobalId lo = a < b ? a : b, hi = a < b ? b : a;
  const std::uint64_t h1 = splitmix64(splitmix64(splitmix64(seed) ^ lo) ^ hi);
  const std::uint64_t h2 = splitmix64(h1);
  // Uniforms in (0, 1): 53 bits, offset by half a unit, so that log(u1) is finite.
  const double u1 = (static_cast<double>(h1 >> 11) + 0.5) * 0x1.0p-53;
  const double u2 = (static_cast<double>(h2 >> 11) + 0.5) * 0x1.0p-53;
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * kPi * u2);
}

/// The strength factor s of the bond (a, b); exactly 1 when the spread is 0.
inline double bond_strength_factor(const BondStrengthSpread& d, GlobalId a, GlobalId b) {
  if (d.spread == 0.0) return 1.0;
  const double var_ln = std::log1p(d.spread * d.spread);
  return std::exp(-0.5 * var_ln + std::sqrt(var_ln) * bond_normal_draw(d.seed, a, b));
}

}  // namespace hs::bonded
