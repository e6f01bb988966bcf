// `hybridsim calibrate`'s checks (issue 13, "Done when"; issue 48 item 3 for 2 to 8 layers): the
// calibrated material's virtual lab tests (src/calib/lab_tests.h) give the target E within 3 %,
// nu within 0.03, flexural strength within 5 % and the Hetenyi characteristic length within 5 %,
// on lattices of D = 0.2 m, E = 1e7 Pa, nu = 0.3, sigma_f = 5e4 Pa.
//
// Two executables from this file: test_calib_validation (2, 3 and 4 layers; label `validation`,
// 43 s of CPU) and, with HS_CALIB_THICK, test_calib_validation_thick (6 and 8 layers;
// labels `validation` and `slow`, 4.4 min of CPU).
//
// What fails when a part is switched off:
// - "paper_eq1" (k_n = k_t = pi E D / 12): E = 0.70 of the target with nu = 0 (hcp_sheet_moduli;
//   the tension test measured 0.955 x 2 sqrt(2) k / D at 3 layers): the E and nu checks fail.
// - the floating strip 6 rows wide at every thickness (calib::strip_rows returning 6): a strip
//   narrower than ~0.8 h is unstable in roll; at 8 layers (h = 1.31 m, W = 1.04 m) it heels during
//   the test and L_c reads +55 % (+2.4 % at 6 layers, inside the limit).
// - the flexural table without its 6- and 8-layer rows (the 4-layer row used above 4 layers): the
//   table check (0.5 %) fails at 6 and 8 layers (sigma_f measured +1.05 % and +1.87 %).
#include "calib/lab_tests.h"
#include "common/hcp_geometry.h"
#include "common/ice_formulas.h"
#include "scene/scene.h"
#include "sim/calibrated_ice.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <string>

using namespace hs;

namespace {

// `layers` layers of D = 0.2 m, the cone scenes' reduced ice.
scene::Scene ice_of(int layers) {
  const double h = layers * hcp_layer_spacing(0.2);
  return scene::parse_scene(nlohmann::json::parse(R"({"name": "calib", "time": {"duration": 1},
      "ice": {"thickness": )" + std::to_string(h) + R"(, "length": 10, "width": 10},
      "material": {"particle_diameter": 0.2, "youngs_modulus": 1e7, "poisson_ratio": 0.3,
                   "flexural_strength": 5e4}})"),
                            ".");
}

struct Measured {
  double E, nu, flex, Lc;  // E, sigma_f and L_c as ratios to their targets
};

Measured measure(int layers) {
  const scene::Scene s = ice_of(layers);
  const sim::CalibratedIce ci = sim::calibrate_ice(s);
  EXPECT_EQ(ci.layers, layers);
  EXPECT_FALSE(ci.poisson_clamped);
  calib::LabOptions o;
  const calib::TensionResult t = calib::tension_test(s, o);
  const calib::BendingResult b = calib::bending_test(s, o);
  const calib::StripResult st = calib::strip_test(s, t.poisson_ratio, o);
  const double Lc = characteristic_length(1e7, ci.thickness, s.water.density, s.gravity.norm(), 0.3);
  std::printf("[calib] %d layers: E %.4e (%.4f), nu %.4f (nu_z %.4f), tensile %.4e, flexural %.4e (%.4f), "
              "L_c %.4f vs %.4f (%.4f; strip as a beam %.4f, fit rms %.2e, softening %.3f)\n",
              layers, t.youngs_modulus, t.youngs_modulus / 1e7, t.poisson_ratio, t.poisson_ratio_z,
              t.tensile_strength, b.flexural_strength, b.flexural_strength / 5e4, st.characteristic_length, Lc,
              st.characteristic_length / Lc, st.strip_length, st.fit_rms, st.softening);
  EXPECT_NEAR(t.poisson_ratio, 0.3, 0.03);
  return {t.youngs_modulus / 1e7, t.poisson_ratio, b.flexural_strength / 5e4, st.characteristic_length / Lc};
}

}  // namespace

// The issue's limits (E 3 %, sigma_f and L_c 5 %) on each lattice, the measured values beside.
// sigma_f meets its target through the committed table (calibrated_ice.cpp), whose points were
// measured with this very bending test, so the 0.5 % check is of the chain table -> bond strength
// -> lattice (a wrong or missing row, the interpolation or the strength scaling fails it), not of
// the table itself.
#ifndef HS_CALIB_THICK
TEST(CalibrationValidation, SmallLatticeHasTheTargetIce) {
  const Measured m = measure(3);
  EXPECT_NEAR(m.E, 1.0, 0.03);      // measured 0.9968
  EXPECT_NEAR(m.flex, 1.0, 0.005);  // measured 1.0000 (+1e-5)
  EXPECT_NEAR(m.Lc, 1.0, 0.05);     // measured 1.0022
}

TEST(CalibrationValidation, TwoLayersHaveTheTargetIce) {
  const Measured m = measure(2);
  EXPECT_NEAR(m.E, 1.0, 0.03);      // measured 0.9965
  EXPECT_NEAR(m.flex, 1.0, 0.005);  // measured 1.0000 (-3e-5)
  EXPECT_NEAR(m.Lc, 1.0, 0.05);     // measured 0.9995 (fit rms 3.8e-3)
}

TEST(CalibrationValidation, FourLayersHaveTheTargetIce) {
  const Measured m = measure(4);
  EXPECT_NEAR(m.E, 1.0, 0.03);      // measured 0.9969
  EXPECT_NEAR(m.flex, 1.0, 0.005);  // measured 1.0000 (+9e-6)
  EXPECT_NEAR(m.Lc, 1.0, 0.05);     // measured 1.0033 (fit rms 5.3e-4)
}
#else
TEST(CalibrationValidationThick, SixLayersHaveTheTargetIce) {
  const Measured m = measure(6);
  EXPECT_NEAR(m.E, 1.0, 0.03);      // measured 0.9970
  EXPECT_NEAR(m.flex, 1.0, 0.005);  // measured 1.0000
  EXPECT_NEAR(m.Lc, 1.0, 0.05);     // measured 1.0030 (fit rms 4.6e-4)
}

TEST(CalibrationValidationThick, EightLayersHaveTheTargetIce) {
  const Measured m = measure(8);
  EXPECT_NEAR(m.E, 1.0, 0.03);      // measured 0.9971
  EXPECT_NEAR(m.flex, 1.0, 0.005);  // measured 1.0000
  EXPECT_NEAR(m.Lc, 1.0, 0.05);     // measured 0.9988 (fit rms 7.2e-4)
}
#endif
