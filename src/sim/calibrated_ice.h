// The ice a scene describes (target E, nu, strengths) turned into lattice springs and bond
// strengths: material.stiffness_model "calibrated" (the default) or "paper_eq1"
// (docs/engine.md, "Calibrated ice"; docs/scene.md, "material").
//
//   calibrated:  bond (and contact) normal/shear stiffness k_n, k_s chosen so that the relaxed
//                linear-elastic moduli of the scene's HCP sheet (its layer count, c-axis vertical,
//                infinite in plane) are the target E and nu (hcp_sheet_moduli); the bond strength
//                is material.flexural_strength / (the lattice's flexural strength per unit bond
//                strength, from the committed table flexural_ratio()).
//   paper_eq1:   k_n = k_s = pi E D / 12 (or material.stiffness), bond strengths = bonds.*,
//                exactly as before this model existed; the sheet's E, nu and flexural strength
//                that result are reported (not targets).
//
// Pure functions of the scene (no engine): engine_def, the blocks, ISO and `hybridsim calibrate`
// all call calibrate_ice() and get the same numbers.
#pragma once

#include "scene/scene.h"

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace hs::sim {

/// In-plane (basal-plane) elastic moduli of an HCP sheet of `layers` close-packed layers of
/// spheres of diameter D, bonded by parallel bonds (normal k_n, shear k_s, bond radius R,
/// bending k_n R^2/4, twisting k_s R^2/2), infinite in plane, free top and bottom faces, every
/// particle's translation and rotation relaxed (static condensation of the periodic cell):
/// plane-stress E and nu with the sheet thickness h = layers c (c = D sqrt(2/3)).
struct SheetModuli {
  double youngs_modulus = 0;  ///< Pa
  double poisson_ratio = 0;   ///< -
  double thickness = 0;       ///< m, layers x c
};
SheetModuli hcp_sheet_moduli(int layers, double D, double kn, double ks, double bond_radius);

/// Lattice strength per unit bond tensile strength (bond shear strength = tensile strength),
/// measured by `hybridsim calibrate`'s virtual tests (src/calib/lab_tests.h) and committed as a
/// table over the layer count and k_s/k_n (calibrated_ice.cpp); interpolated, clamped at the
/// table's edges. flexural: 3-point bending, sigma_f = 3 F L / (2 b h^2), span L = 8 h.
double flexural_ratio(int layers, double ks_over_kn);
/// ... uniaxial tension in the basal plane (peak force / section).
double tensile_ratio(int layers, double ks_over_kn);

/// Smallest k_s/k_n the calibrated model uses (nu is largest there); below it the twisting
/// springs (k_s R^2/2) vanish and the lattice's shear waves become too slow to settle.
inline constexpr double kMinShearRatio = 0.02;

/// What the scene's ice is in the lattice: the springs and strengths the engine gets and the
/// properties they give (predicted; `hybridsim calibrate` measures them).
struct CalibratedIce {
  std::string model;              ///< "calibrated" or "paper_eq1"
  int layers = 0;                 ///< level-ice layers the calibration used
  double thickness = 0;           ///< m, layers x c (the lattice's thickness)
  double kn = 0, ks = 0;          ///< bond and contact stiffness, N/m
  // Targets (the scene's) and what the lattice gives.
  double target_youngs_modulus = 0, target_poisson_ratio = 0;
  double target_flexural_strength = 0;  ///< Pa; 0 = none given (paper_eq1 / explicit bonds)
  double target_tensile_strength = 0;   ///< Pa; 0 = none given
  double youngs_modulus = 0;      ///< Pa, the sheet's (hcp_sheet_moduli)
  double poisson_ratio = 0;       ///< -, the sheet's
  double poisson_min = 0, poisson_max = 0;  ///< reachable range at this layer count
  bool poisson_clamped = false;   ///< the target lay outside [poisson_min, poisson_max]
  double flexural_strength = 0;   ///< Pa, bond strength x flexural_ratio
  double tensile_strength = 0;    ///< Pa, bond strength x tensile_ratio
  double bond_tensile_strength = 0, bond_shear_strength = 0;      ///< lattice bonds, Pa
  double freeze_tensile_strength = 0, freeze_shear_strength = 0;  ///< freeze bonds, Pa
  std::string strength_source;    ///< where the bond strength came from (a scene path)
  std::vector<std::string> warnings;  ///< "path: message"
};

/// The scene's ice as the lattice has it (see the file comment).
CalibratedIce calibrate_ice(const scene::Scene& s);

/// Every field, for the run file's root attribute "calibrated_ice" and `hybridsim check`.
nlohmann::json calibrated_ice_to_json(const CalibratedIce& ci);

/// k_s/k_n that gives the sheet Poisson ratio `nu` (bisection on hcp_sheet_moduli, clamped to
/// [kMinShearRatio, 1]).
double shear_ratio_for_poisson(int layers, double nu);

}  // namespace hs::sim
