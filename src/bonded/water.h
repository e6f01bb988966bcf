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
//
// Drag: the rigid blocks' face law (src/rigid/box_water.h (5)-(6), docs/engine.md "Water
// drag"), with the same two coefficients, on the part of the body's surface that a particle
// carries. With u = v - u_w the particle's velocity relative to the water and, for a surface
// element of area A and outward normal n, u_n = u . n:
//   linear     F = -c_lin A u_n n                      (c_lin in Pa s/m)
//   quadratic  F = -1/2 rho_w C_d A u_n^2 n, leading elements only (u_n > 0).
// Which surface a particle carries (its exposure, ParticleExposure below) follows from its
// bonds alone. Its lattice cell has 12 faces, one towards each HCP neighbour, all of area
// A_c = D^2 / (2 sqrt 2) (the cell volume D^3/sqrt 2 is 12 pyramids of height D/2, and the
// basal plane's three faces project onto the cell's basal area sqrt(3)/2 D^2, which makes the
// in-plane and out-of-plane face areas equal). The faces towards missing (unbonded)
// neighbours are exposed; since the 12 face vectors of a cell sum to zero, their net area
// vector is
//   a = -A_c sum_{bonds b} d_b         (d_b: unit vector towards the bonded neighbour).
// On a flat face of a lattice body the exposed cell faces zigzag, but their net vector per
// particle is the flat face's area per particle (exact on the basal faces, where the three
// tilted upper cell faces project onto the basal area; on average on the side faces). The net
// is split along the particle's body axes (the lattice axes of a converted block or a built
// sheet, which are the block's or sheet's face normals) into six face areas a_{+x} ... a_{-z}
// (the positive and negative parts of each component), so an edge or corner particle carries
// each of its faces separately. A side of an axis on which the particle has no bonded
// neighbour at all (d_b . (+-e_k) < 0.2 for every bond; the smallest non-zero component of
// an HCP bond direction along a body axis is 0.289) is wholly exposed and gets the cell's
// projected area on that side (sqrt(3)/2 D^2 across the basal plane, 3 A_c along x, 2.887 A_c
// along y): the top and bottom layers of a body, the protruding ends of the lattice rows on a
// side face, both faces of a one-particle-thick plate (where the net would cancel them). The
// downward cell faces that a top-layer edge particle exposes to the side are then not netted
// against its top; measured on a converted 1.2 x 1.2 x 0.49 m block, the areas so obtained are
// its top and bottom exactly and its sides within -5 % ... +14 %, and its drag the block's
// within 4 % (tests/bridge/test_water_consistency.cpp). Faces off the lattice axes are carried
// as a staircase (docs/engine.md).
// A particle without bonds is a loose sphere: F = -s (c_lin (4/3) pi r^2 + 1/2 rho_w C_d pi r^2
// |u|) u (the linear face law integrated over the sphere; the quadratic one with the sphere's
// projected area pi r^2). An interior particle (net zero, no thin axis) feels no drag.
// Wetting: a side face (normal horizontal) is wet over the cell's submerged fraction s; a face
// with vertical normal component n_z sits at the cell's top or bottom: its wet fraction is that
// of a band of height h_c (1 - |n_z|) (at least 0.1 h_c) centred at z + n_z h_c/2. So a floating
// lattice's top face is dry and its bottom face wet, as on a floating block.
// The exposure is recomputed from the bond list at every neighbour rebuild (Engine), so a
// broken bond exposes its two cell faces from the next rebuild on.
// A converted block's particles stand for V_b = V/n of ice rather than their cell's V_cell
// (exposure_from_bonds): their face areas are scaled so the lattice carries the block's faces.
#pragma once

#include "common/types.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>

namespace hs::bonded {

enum class BuoyancyModel { Column, Sphere };

struct WaterParams {
  bool enabled = false;
  double level = 0.0;            ///< z of the water surface, m
  double density = 1025.0;       ///< kg/m^3
  BuoyancyModel model = BuoyancyModel::Column;
  double linear_drag_per_area = 0.0;  ///< c_lin, Pa s/m (N s/m per m^2 of wetted surface)
  double drag_coefficient = 0.0; ///< C_d (quadratic drag on leading faces)
  Vec3 current = Vec3::Zero();   ///< water velocity, m/s
};

/// The part of a body's surface one particle carries (see the header comment).
struct ParticleExposure {
  enum Kind : std::uint8_t { Interior = 0, Surface = 1, Loose = 2 };
  Kind kind = Loose;
  /// Face areas, m^2, along the particle's body axes: [+x, -x, +y, -y, +z, -z].
  std::array<double, 6> area{};
};

/// Area of each of the 12 faces of an HCP cell of spacing D: D^2 / (2 sqrt 2).
inline double hcp_cell_face_area(double D) { return D * D * 0.35355339059327376; }

/// Bond directions are rounded to multiples of 2^-20 before they are summed, so that the sum
/// of at most a few dozen of them is exact and does not depend on the order of summation
/// (serial and MPI runs add the two ends of a bond on different ranks).
inline double exposure_quantize(double c) { return std::nearbyint(c * 1048576.0) / 1048576.0; }

/// Exposure from the bonds of one particle of radius r: `sum` = sum of the (quantized) unit
/// bond directions d_b in the particle's body frame; `reach_pos`, `reach_neg` = per body axis
/// the largest d_b . e_k and -d_b . e_k (0 when none is positive); `count` = number of bonds;
/// `buoyant_volume` = the volume of ice it stands for (V_b).
inline ParticleExposure exposure_from_bonds(const Vec3& sum, const Vec3& reach_pos, const Vec3& reach_neg,
                                            unsigned count, double r, double buoyant_volume) {
  ParticleExposure e;
  if (count == 0) return e;  // Loose
  const double D = 2.0 * r, Ac = hcp_cell_face_area(D);
  // A particle that stands for V_b != V_cell (a converted block's lattice, whose sites do not
  // tile the block exactly: the converter gives each V_b = V / n) carries the block's surface:
  // its cell stretched in the layer plane by rho = V_b / V_cell (layers are exact), i.e. basal
  // (z) faces scaled by rho and side faces by sqrt(rho).
  const double vc = D * D * D * 0.70710678118654752;
  const double rho = buoyant_volume > 0.0 ? buoyant_volume / vc : 1.0;
  const double scale[3] = {std::sqrt(rho), std::sqrt(rho), rho};
  // The HCP cell's projected area along each body axis (sum over its faces of A_c max(n . e_k, 0)).
  const double full[3] = {3.0 * Ac, 2.8867513459481287 * Ac, 0.86602540378443865 * D * D};
  bool any = false;
  for (int k = 0; k < 3; ++k) {
    const double a = -Ac * sum[k];
    // A side with no bonded neighbour at all (no d_b . (+-e_k) > 0.2) is wholly exposed: the
    // cell's projection (top layer, bottom layer, the protruding end of a row, both faces of
    // a one-particle-thick plate). Else the net, which cancels the zigzag of the cell faces.
    double p = reach_pos[k] < 0.2 ? full[k] : std::max(a, 0.0);
    double n = reach_neg[k] < 0.2 ? full[k] : std::max(-a, 0.0);
    // A net below a hundredth of a cell face is round-off of a full neighbour set.
    if (p < 0.01 * Ac) p = 0.0;
    if (n < 0.01 * Ac) n = 0.0;
    e.area[2 * k] = p * scale[k];
    e.area[2 * k + 1] = n * scale[k];
    any = any || p > 0.0 || n > 0.0;
  }
  e.kind = any ? ParticleExposure::Surface : ParticleExposure::Interior;
  return e;
}

/// Submerged fraction s in [0,1] of a particle at height z with radius r.
inline double submerged_fraction(const WaterParams& w, double z, double r) {
  if (w.model == BuoyancyModel::Column) {
    const double hc = 2.0 * r * 0.81649658092772603;
    return std::clamp((w.level - (z - 0.5 * hc)) / hc, 0.0, 1.0);
  }
  const double t = std::clamp((w.level - z + r) / (2.0 * r), 0.0, 1.0);
  return t * t * (3.0 - 2.0 * t);
}

/// Wet fraction of a cell face with world normal n on a particle at height z (radius r).
inline double face_wet_fraction(const WaterParams& w, double z, double r, double nz) {
  const double hc = 2.0 * r * 0.81649658092772603;
  const double band = std::max(hc * (1.0 - std::abs(nz)), 0.1 * hc);
  const double zc = z + 0.5 * hc * nz;
  return std::clamp((w.level - (zc - 0.5 * band)) / band, 0.0, 1.0);
}

/// Drag on one particle (see the header comment); R = the particle's orientation matrix.
inline Vec3 water_drag(const WaterParams& w, const Vec3& x, const Vec3& v, double r, const Mat3& R,
                       const ParticleExposure& e, double s) {
  const Vec3 u = v - w.current;
  const double cq = 0.5 * w.density * w.drag_coefficient;
  if (e.kind == ParticleExposure::Loose) {
    const double A = kPi * r * r;
    return -s * (w.linear_drag_per_area * (4.0 / 3.0) * A + cq * A * u.norm()) * u;
  }
  Vec3 f = Vec3::Zero();
  if (e.kind == ParticleExposure::Interior) return f;
  for (int k = 0; k < 3; ++k) {
    for (int sgn = 0; sgn < 2; ++sgn) {
      const double A = e.area[2 * k + sgn];
      if (A == 0.0) continue;
      const Vec3 n = sgn == 0 ? Vec3(R.col(k)) : Vec3(-R.col(k));
      const double wet = face_wet_fraction(w, x.z(), r, n.z());
      if (wet == 0.0) continue;
      const double un = u.dot(n);
      double t = w.linear_drag_per_area * un;
      if (un > 0.0) t += cq * un * un;
      f -= (wet * A * t) * n;
    }
  }
  return f;
}

/// Buoyancy + drag force on one particle; gravity magnitude g acts along -z.
inline Vec3 water_force(const WaterParams& w, double g, const Vec3& x, const Vec3& v, double r,
                        double buoyant_volume, const Quat& q, const ParticleExposure& e) {
  const double s = submerged_fraction(w, x.z(), r);
  // Dry: no cell face reaches the water (the lowest face band ends 0.55 h_c below the centre).
  if (s == 0.0 && (e.kind == ParticleExposure::Loose || x.z() - 2.0 * r * 0.44907311951024931 >= w.level))
    return Vec3::Zero();
  Vec3 f(0.0, 0.0, w.density * g * buoyant_volume * s);
  if (w.linear_drag_per_area > 0.0 || w.drag_coefficient > 0.0) {
    if (e.kind == ParticleExposure::Loose)
      f += water_drag(w, x, v, r, Mat3::Identity(), e, s);
    else if (e.kind == ParticleExposure::Surface)
      f += water_drag(w, x, v, r, q.toRotationMatrix(), e, s);
  }
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
