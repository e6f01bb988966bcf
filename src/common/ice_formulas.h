// Formulas of the ice model that several layers use, each written once (pure functions, SI units).
// Every layer may include this file (it depends on common/types.h only).
//
// The arithmetic of each function is the exact expression its call sites used before (the order
// of the operations fixes the last bits of the results, and the run outputs are pinned
// bit-for-bit): change an expression here only together with the pinned hashes.
#pragma once

#include "common/types.h"

#include <cmath>

namespace hs {

/// Paper Eq. 1: contact (and bond) spring stiffness of particles of diameter D,
///   K_n = K_t = pi E D / 12,  N/m   (E: Young's modulus, Pa; D: m).
inline double eq1_contact_stiffness(double youngs_modulus, double diameter) {
  return kPi * youngs_modulus * diameter / 12.0;
}

/// Paper Eq. 2: DEM time step
///   dt = alpha D sqrt(rho / E),  s   (alpha = 0.1 in the paper; rho: particle density, kg/m^3).
inline double eq2_time_step(double alpha, double diameter, double density, double youngs_modulus) {
  return alpha * diameter * std::sqrt(density / youngs_modulus);
}

/// Draft of floating ice of thickness h at equilibrium (Archimedes, a uniform slab):
///   d = h rho_i / rho_w,  m (depth of the underside below the water line).
inline double flotation_draft(double thickness, double ice_density, double water_density) {
  return thickness * ice_density / water_density;
}

/// Freeboard of the same slab: f = h (1 - rho_i / rho_w),  m (height of the top above the water line).
inline double flotation_freeboard(double thickness, double ice_density, double water_density) {
  return thickness * (1.0 - ice_density / water_density);
}

/// Characteristic length of a floating elastic plate (ISO 19906 A.8.2.8.3; Hetenyi):
///   L_c = [E h^3 / (12 rho_w g (1 - nu^2))]^(1/4),  m.
inline double characteristic_length(double youngs_modulus, double thickness, double water_density, double gravity,
                                    double poisson_ratio) {
  const double E = youngs_modulus, h = thickness, nu = poisson_ratio;
  return std::pow(E * h * h * h / (12.0 * water_density * gravity * (1.0 - nu * nu)), 0.25);
}

}  // namespace hs
