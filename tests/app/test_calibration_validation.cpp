// `hybridsim calibrate`'s checks (issue 13, "Done when") on a small lattice: the calibrated
// material's virtual lab tests (src/calib/lab_tests.h) give the target E within 3 %, nu within
// 0.03, flexural strength within 5 % and the Hetenyi characteristic length within 5 %.
// Label `validation`, ~50 s on one core (113 s wall at load 15). Switched off ("paper_eq1":
// k_n = k_t = pi E D / 12) the lattice is E = 0.70 of the target with nu = 0 (hcp_sheet_moduli,
// and the tension test measured 0.955 x 2 sqrt(2) k / D at 3 layers): the E and nu checks fail.
#include "calib/lab_tests.h"
#include "common/ice_formulas.h"
#include "scene/scene.h"
#include "sim/calibrated_ice.h"

#include <gtest/gtest.h>

#include <cstdio>

using namespace hs;

namespace {

// 3 layers of D = 0.2 m (h = 0.49 m), the cone scenes' reduced ice.
scene::Scene small_ice() {
  return scene::parse_scene(nlohmann::json::parse(R"({"name": "calib", "time": {"duration": 1},
      "ice": {"thickness": 0.49, "length": 10, "width": 10},
      "material": {"particle_diameter": 0.2, "youngs_modulus": 1e7, "poisson_ratio": 0.3,
                   "flexural_strength": 5e4}})"),
                            ".");
}

}  // namespace

TEST(CalibrationValidation, SmallLatticeHasTheTargetIce) {
  const scene::Scene s = small_ice();
  const sim::CalibratedIce ci = sim::calibrate_ice(s);
  ASSERT_EQ(ci.layers, 3);
  ASSERT_FALSE(ci.poisson_clamped);
  calib::LabOptions o;
  const calib::TensionResult t = calib::tension_test(s, o);
  const calib::BendingResult b = calib::bending_test(s, o);
  const calib::StripResult st = calib::strip_test(s, t.poisson_ratio, o);
  const double Lc = characteristic_length(1e7, ci.thickness, s.water.density, s.gravity.norm(), 0.3);
  std::printf("[calib] E %.4e (%.4f), nu %.4f (nu_z %.4f), tensile %.4e, flexural %.4e (%.4f), L_c %.4f vs %.4f "
              "(%.4f; strip as a beam %.4f, fit rms %.2e)\n",
              t.youngs_modulus, t.youngs_modulus / 1e7, t.poisson_ratio, t.poisson_ratio_z, t.tensile_strength,
              b.flexural_strength, b.flexural_strength / 5e4, st.characteristic_length, Lc,
              st.characteristic_length / Lc, st.strip_length, st.fit_rms);
  // The issue's limits; measured beside each. E and nu: 10x the measured error. The flexural
  // strength meets its target through the committed table (calibrated_ice.cpp), whose 3-layer
  // point was measured with this very test, so it checks the chain table -> bond strength ->
  // lattice (a wrong row, interpolation or strength scaling fails it), not the table itself. L_c:
  // the lattice's plate rigidity is above E h^3/12(1 - nu^2) (docs/engine.md), +1.3 % here, +4.1 %
  // at 4 layers: the issue's 5 % is kept.
  EXPECT_NEAR(t.youngs_modulus / 1e7, 1.0, 0.03);         // measured 0.9968
  EXPECT_NEAR(t.poisson_ratio, 0.3, 0.03);                 // measured 0.3023
  EXPECT_NEAR(b.flexural_strength / 5e4, 1.0, 0.05);       // measured 1.0000 (+1e-5)
  EXPECT_NEAR(st.characteristic_length / Lc, 1.0, 0.05);   // measured 1.0022 (1.0133 with per-particle heave damping before the one water)
}
