// Water: buoyancy and drag on the submerged part of a particle.
//
// Buoyancy.  A particle carries the buoyant volume V_b of the solid it stands for.
// For bonded ice in HCP that is its lattice cell, V_b = V_cell = D^3/sqrt(2) (and its
// mass is rho_i V_cell), so the lattice weighs and floats like solid ice. The submerged
// fraction s(z) depends on the buoyancy model:
//   Column (default for lattice ice): V_b is spread uniformly over a height
//     h_c = D sqrt(2/3) (the HCP layer spacing) centred on the particle:
//     s = clamp((z_w - (z - h_c/2)) / h_c, 0, 1).
//     A slab of n layers is then exactly a column of height n h_c whose buoyancy is
//     rho_w g A (submerged depth): it floats at freeboard h (1 - rho_i/rho_w) and heaves
//     with period 2 pi sqrt(rho_i h / (rho_w g)), like the solid slab (added mass
//     neglected). This is the documented choice behind the engine's floating tests.
//   Sphere: the exact spherical-cap fraction, s = t^2 (3 - 2 t) with t = clamp((z_w - z +
//     r)/(2r), 0, 1); for loose spherical particles (rubble) whose V_b is the sphere.
//   F_b = rho_w g V_b s  (against gravity).
// Drag on the submerged part, relative to the water velocity u_w:
//   F_d = -s (c_lin + 1/2 rho_w C_d pi r^2 |v - u_w|) (v - u_w)
// c_lin (N s/m per particle) is the linear term that damps heave; C_d the quadratic one.
#pragma once

#include "common/types.h"

#include <algorithm>

namespace hs::bonded {

enum class BuoyancyModel { Column, Sphere };

struct WaterParams {
  bool enabled = false;
  double level = 0.0;            ///< z of the water surface, m
  double density = 1025.0;       ///< kg/m^3
  BuoyancyModel model = BuoyancyModel::Column;
  double linear_drag = 0.0;      ///< c_lin, N s/m per particle
  double drag_coefficient = 0.0; ///< C_d (quadratic drag)
  Vec3 current = Vec3::Zero();   ///< water velocity, m/s
};

/// Submerged fraction s in [0,1] of a particle at height z with radius r.
inline double submerged_fraction(const WaterParams& w, double z, double r) {
  if (w.model == BuoyancyModel::Column) {
    const double hc = 2.0 * r * 0.81649658092772603;
    return std::clamp((w.level - (z - 0.5 * hc)) / hc, 0.0, 1.0);
  }
  const double t = std::clamp((w.level - z + r) / (2.0 * r), 0.0, 1.0);
  return t * t * (3.0 - 2.0 * t);
}

/// Buoyancy + drag force on one particle; gravity magnitude g acts along -z.
inline Vec3 water_force(const WaterParams& w, double g, const Vec3& x, const Vec3& v, double r,
                        double buoyant_volume) {
  const double s = submerged_fraction(w, x.z(), r);
  if (s == 0.0) return Vec3::Zero();
  Vec3 f(0.0, 0.0, w.density * g * buoyant_volume * s);
  const Vec3 vr = v - w.current;
  const double cq = 0.5 * w.density * w.drag_coefficient * kPi * r * r;
  f -= s * (w.linear_drag + cq * vr.norm()) * vr;
  return f;
}

/// Potential energy of buoyancy (its negative work) for the Column model, J, such that
/// gravity + buoyancy energy is conserved without drag: U_b = -rho_w g V_b * int_0^z s.
inline double buoyancy_potential(const WaterParams& w, double g, double z, double r,
                                 double buoyant_volume) {
  // Integral of s(z') dz' from a deep reference zr (s=1) to z; only differences matter.
  const double hc = (w.model == BuoyancyModel::Column) ? 2.0 * r * 0.81649658092772603 : 2.0 * r;
  const double zlo = w.level - 0.5 * hc;  // below: s = 1
  const double zhi = w.level + 0.5 * hc;  // above: s = 0
  double integral;
  if (z <= zlo) {
    integral = z - zlo;
  } else if (z >= zhi) {
    integral = 0.5 * hc;
  } else if (w.model == BuoyancyModel::Column) {
    const double t = z - zlo;
    integral = t - t * t / (2.0 * hc);
  } else {
    // s(t) with t = 1 - (z - zlo)/hc in [0,1]: int s dz = hc * int_{t}^{1} (3u^2 - 2u^3) du
    const double u = 1.0 - (z - zlo) / hc;
    integral = hc * (0.5 - (u * u * u - 0.5 * u * u * u * u));
  }
  return -w.density * g * buoyant_volume * integral;
}

}  // namespace hs::bonded
