// Virtual laboratory tests on a scene's bonded HCP lattice (`hybridsim calibrate`, docs/engine.md
// "Calibrated ice"): the lattice is built with the springs and bond strengths the scene's run
// gets (sim::engine_def), c-axis vertical as in the scene's sheet, and loaded quasi-statically:
//
//   tension_test   a bar along x (40 D x 12 rows x the scene's layers), one end held, the other
//                  pulled: E and nu from the middle third (unbreakable bonds, strain 1e-4), then
//                  the tensile strength (peak force / section) with the scene's bonds.
//   bending_test   three-point bending of a beam of the scene's thickness h (span 8 h, 4 rows):
//                  free spheres (contact only, no friction) under the bottom layer at the
//                  supports and above the top layer at mid-span, the loader moving down;
//                  sigma_f = 3 F L / (2 b h^2) as ISO 19906 uses a flexural strength, F the load
//                  when the first bond breaks (in the bottom fibre at mid-span): a brittle beam
//                  fails there, while the lattice's load after it depends on the dynamics of the
//                  bond cascade (peak / first 1.3 ... 1.7 with the bond damping and the loading
//                  rate), so only the first failure is a property of the material.
//   strip_test     a floating strip (6 L_c long, at least 2 h wide: strip_rows, gravity, Column
//                  buoyancy) loaded at one end: the deflection profile is fitted with the
//                  semi-infinite beam on an elastic
//                  foundation, w = e^(-lambda s)(A cos lambda s + B sin lambda s), and
//                  L_c = 1 / (sqrt(2) lambda) is turned into the plate's (Hetenyi) value with the
//                  measured nu: L_c,plate = L_c,strip (1 - nu^2)^(-1/4).
//
// Times are set in units of the lattice's own wave transits (tension), fundamental bending period
// (bending) and heave period (strip), so the step counts do not depend on E. A strip whose step
// count would exceed `max_strip_steps` runs with every spring softened by a factor s (linear
// elasticity: L_c scales exactly as s^(-1/4), reported).
#pragma once

#include "bonded/engine.h"
#include "scene/scene.h"
#include "sim/calibrated_ice.h"

#include <functional>
#include <string>

namespace hs::calib {

/// Called with the test's name and its progress in [0, 1].
using Progress = std::function<void(const std::string& test, double fraction)>;

struct TensionResult {
  double youngs_modulus = 0;    ///< Pa
  double poisson_ratio = 0;     ///< -nu_yx: lateral in-plane strain / axial
  double poisson_ratio_z = 0;   ///< -strain_zz / strain_xx (across the sheet)
  double tensile_strength = 0;  ///< Pa, peak force / section
  std::size_t particles = 0;
  double area = 0;              ///< m^2
};

struct BendingResult {
  double flexural_strength = 0;  ///< Pa, at the first bond failure
  double peak_force = 0;         ///< N
  double first_break_force = 0;  ///< N, the load one step before the first bond broke
  double peak_strength = 0;      ///< Pa, 3 F_peak L / (2 b h^2) (not the flexural strength: see above)
  double first_break_time = 0;   ///< in fundamental periods T1
  double strength_scale = 1;     ///< bond strengths x this in the test (sigma_f/E = 1.2e-4), result / this
  double span = 0, width = 0, thickness = 0;  ///< m
  std::size_t particles = 0;
};

struct StripResult {
  double characteristic_length = 0;  ///< m, plate (Hetenyi) equivalent
  double strip_length = 0;           ///< m, L_c of the strip as a beam
  double softening = 1;              ///< s: springs divided by s in the test, L_c scaled back by s^(1/4)
  double fit_rms = 0;                ///< rms residual of the profile fit / max deflection
  std::size_t particles = 0;
};

struct LabOptions {
  double max_strip_steps = 6e4;  ///< DEM steps of the strip test above which it is softened
  /// Bending test with the bond strengths scaled to sigma_f/E = 1.2e-4 and the result scaled back
  /// (true), or at the scene's own strengths (false: `calibrate --scene-strength`).
  bool linear_regime = true;
  Progress progress;
};

TensionResult tension_test(const scene::Scene& s, const LabOptions& o);
BendingResult bending_test(const scene::Scene& s, const LabOptions& o);
/// Rows of the floating strip: max(6, ceil(2 h / row spacing)), a width of at least 2 h. A floating
/// box of width W, thickness h and draft d = 0.88 h is stable in roll only while its metacentric
/// height W^2 / (12 d) - (h - d) / 2 is positive, W > 0.8 h; the HCP B layers' row shift
/// (0.29 D in y) also sets its centre of mass off the middle. Six rows (W = 1.04 m at D = 0.2 m)
/// heeled and rolled at 7 layers (h = 1.14 m: the sides 5 cm apart in z after 2 heave periods) and
/// L_c read +34 %; 14 rows give +0.02 %. At W = 2 h the metacentric height is 0.32 h and the
/// strip is still narrow beside L_c, so it bends as a beam (the plate conversion below).
int strip_rows(double h, double D);
/// `poisson_ratio`: the lattice's (from tension_test), for the plate conversion.
StripResult strip_test(const scene::Scene& s, double poisson_ratio, const LabOptions& o);

}  // namespace hs::calib
