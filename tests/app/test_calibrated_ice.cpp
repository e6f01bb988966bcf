// The calibrated stiffness model (sim/calibrated_ice.h): the sheet moduli against the bulk lattice
// derived by hand, the inversion to target E and nu, the reachable nu range, the strength rules
// and the scene keys that choose them.
#include "common/error.h"
#include "common/hcp_geometry.h"
#include "common/ice_formulas.h"
#include "scene/scene.h"
#include "sim/blocks.h"
#include "sim/build.h"
#include "sim/calibrated_ice.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

using namespace hs;

namespace {

scene::Scene scene_from(const std::string& text) { return scene::parse_scene(nlohmann::json::parse(text), "."); }

const char* kBase = R"({"name": "t", "time": {"duration": 0.1},
  "ice": {"thickness": 0.6, "length": 2, "width": 2},
  "material": {"particle_diameter": 0.2, "youngs_modulus": 1e7, "poisson_ratio": 0.3 %s}
  %s})";

std::string fill(const std::string& material_extra, const std::string& rest = "") {
  char buf[2048];
  std::snprintf(buf, sizeof buf, kBase, material_extra.c_str(), rest.c_str());
  return buf;
}

}  // namespace

// k_n = k_s: every bond is an isotropic spring on the bond-centre opening, the affine field is
// exact and the bulk lattice is E = 2 sqrt(2) k / D, nu = 0 (tests/bonded/test_validation.cpp). A
// thick sheet's in-plane modulus tends to it (its free faces miss half their inter-layer bonds:
// E(n) = E_bulk (1 - 1/(4n)) for this isotropic case: the in-plane bonds carry half the stiffness
// in every layer, the inter-layer bonds the other half over n - 1 of n interfaces... measured
// below against the bulk directly at 40 layers).
TEST(CalibratedIce, SheetModuliMatchBulkLatticeForEqualSprings) {
  const double D = 0.2, k = 1e6;
  const sim::SheetModuli m = sim::hcp_sheet_moduli(40, D, k, k, 0.5 * D);
  EXPECT_NEAR(m.poisson_ratio, 0.0, 1e-12);
  EXPECT_NEAR(m.youngs_modulus / (2.0 * std::sqrt(2.0) * k / D), 1.0, 0.01);  // 1/(4 n) ~ 0.6 %
  EXPECT_DOUBLE_EQ(m.thickness, 40 * hcp_layer_spacing(D));
}

// k_s < k_n: the relaxed bulk moduli of the two-site HCP cell (static condensation of the sublattice
// shift and the rotations, worked out independently in numpy, see docs/engine.md): in-plane
// E D / k_n = 1.6243 and nu = 0.2691 at k_s/k_n = 0.1; the affine values would be 1.6746 / 0.2465.
TEST(CalibratedIce, SheetModuliMatchRelaxedBulkForSoftShear) {
  const sim::SheetModuli m = sim::hcp_sheet_moduli(60, 1.0, 1.0, 0.1, 0.5);
  EXPECT_NEAR(m.poisson_ratio, 0.2691, 0.003);
  EXPECT_NEAR(m.youngs_modulus, 1.6243, 0.02);
}

TEST(CalibratedIce, HitsTargetModulusAndPoissonRatio) {
  const scene::Scene s = scene_from(fill(""));
  const sim::CalibratedIce ci = sim::calibrate_ice(s);
  EXPECT_EQ(ci.model, "calibrated");
  EXPECT_EQ(ci.layers, 4);
  EXPECT_FALSE(ci.poisson_clamped);
  EXPECT_NEAR(ci.youngs_modulus / 1e7, 1.0, 1e-9);
  EXPECT_NEAR(ci.poisson_ratio, 0.3, 1e-9);
  EXPECT_LT(ci.ks, 0.2 * ci.kn);
  // The bond strength follows the flexural target through the committed table.
  EXPECT_NEAR(ci.flexural_strength, 0.5e6, 1e-6);
  EXPECT_EQ(ci.strength_source, "/material/flexural_strength");
}

TEST(CalibratedIce, PoissonRatioOutsideReachableRangeIsClampedWithAWarning) {
  nlohmann::json j = nlohmann::json::parse(fill(""));
  j["material"]["poisson_ratio"] = 0.45;
  const scene::Scene s = scene::parse_scene(j, ".");
  const sim::CalibratedIce ci = sim::calibrate_ice(s);
  EXPECT_TRUE(ci.poisson_clamped);
  EXPECT_NEAR(ci.poisson_ratio, ci.poisson_max, 1e-12);
  ASSERT_EQ(ci.warnings.size(), 1u);
  EXPECT_NE(ci.warnings[0].find("/material/poisson_ratio"), std::string::npos);
  EXPECT_NEAR(ci.youngs_modulus / 1e7, 1.0, 1e-9);  // E is still hit
}

// paper_eq1 is the model as it was: k_n = k_s = pi E D / 12 and the bonds' strengths as given.
TEST(CalibratedIce, PaperEq1KeepsEquationOneAndTheBondStrengths) {
  const scene::Scene s = scene_from(fill(", \"stiffness_model\": \"paper_eq1\"",
                                         ", \"bonds\": {\"tensile_strength\": 5e4, \"shear_strength\": 4e4}"));
  const sim::CalibratedIce ci = sim::calibrate_ice(s);
  EXPECT_EQ(ci.model, "paper_eq1");
  EXPECT_EQ(ci.kn, eq1_contact_stiffness(1e7, 0.2));
  EXPECT_EQ(ci.ks, ci.kn);
  EXPECT_EQ(ci.bond_tensile_strength, 5e4);
  EXPECT_EQ(ci.bond_shear_strength, 4e4);
  const auto d = sim::engine_def(s);
  EXPECT_EQ(d.bond[0].kn, eq1_contact_stiffness(1e7, 0.2));
  EXPECT_EQ(d.bond[0].ks, d.bond[0].kn);
  EXPECT_EQ(d.bond[0].sigma_c, 5e4);
  EXPECT_EQ(d.contact.kt, d.contact.kn);
}

// Explicit bond strengths under "calibrated" are used as given (the stiffness is still calibrated).
TEST(CalibratedIce, ExplicitBondStrengthWinsWithoutAFlexuralTarget) {
  const scene::Scene s = scene_from(fill("", ", \"bonds\": {\"tensile_strength\": 5e4}"));
  const sim::CalibratedIce ci = sim::calibrate_ice(s);
  EXPECT_EQ(ci.bond_tensile_strength, 5e4);
  EXPECT_EQ(ci.strength_source, "/bonds/tensile_strength");
  EXPECT_GT(ci.kn, eq1_contact_stiffness(1e7, 0.2));
}

TEST(CalibratedIce, BondStrengthAndFlexuralTargetTogetherAreRefused) {
  try {
    scene_from(fill(", \"flexural_strength\": 5e4", ", \"bonds\": {\"tensile_strength\": 5e4}"));
    FAIL() << "accepted both";
  } catch (const InputError& e) {
    EXPECT_EQ(e.path(), "/bonds/tensile_strength");
    EXPECT_NE(std::string(e.what()).find("/material/flexural_strength"), std::string::npos);
  }
}

TEST(CalibratedIce, ExplicitStiffnessNeedsPaperEq1) {
  try {
    scene_from(fill(", \"stiffness\": 1e6"));
    FAIL() << "accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.path(), "/material/stiffness");
    EXPECT_NE(std::string(e.what()).find("paper_eq1"), std::string::npos);
  }
  EXPECT_NO_THROW(scene_from(fill(", \"stiffness\": 1e6, \"stiffness_model\": \"paper_eq1\"")));
}

TEST(CalibratedIce, FreezeStrengthAsAFractionOfTheLatticeBond) {
  const scene::Scene s = scene_from(fill(", \"flexural_strength\": 5e4", ", \"bonds\": {\"freeze_strength_fraction\": 0.1}"));
  const sim::CalibratedIce ci = sim::calibrate_ice(s);
  EXPECT_DOUBLE_EQ(ci.freeze_tensile_strength, 0.1 * ci.bond_tensile_strength);
  EXPECT_DOUBLE_EQ(ci.freeze_shear_strength, 0.1 * ci.bond_shear_strength);
  EXPECT_DOUBLE_EQ(sim::engine_def(s).bond[1].sigma_c, ci.freeze_tensile_strength);
  try {
    scene_from(fill("", ", \"bonds\": {\"freeze_strength_fraction\": 0.1, \"freeze_tensile_strength\": 2e4}"));
    FAIL() << "accepted both";
  } catch (const InputError& e) {
    EXPECT_EQ(e.path(), "/bonds/freeze_tensile_strength");
  }
}

// bonds.crushed_set_depth: the depth h beyond which a broken bond's contact keeps a permanent set
// (docs/engine.md, "The contact after a crushed bond") reaches the engine, 0.25 r when absent
// whatever stability.max_overlap_ratio is; outside (0, 1) it is refused naming the field.
TEST(CalibratedIce, CrushedSetDepthReachesTheEngineAndIsNotTheOverlapLimit) {
  const auto d = sim::engine_def(scene_from(fill("", ", \"bonds\": {\"crushed_set_depth\": 0.3}")));
  EXPECT_EQ(d.crushed_set_depth, 0.3);
  const auto e = sim::engine_def(scene_from(fill("", ", \"stability\": {\"max_overlap_ratio\": 0.8}")));
  EXPECT_EQ(e.crushed_set_depth, 0.25);
  EXPECT_EQ(e.limits.max_overlap_ratio, 0.8);
  for (const char* bad : {"0", "1"}) {
    try {
      scene_from(fill("", std::string(", \"bonds\": {\"crushed_set_depth\": ") + bad + "}"));
      ADD_FAILURE() << "accepted " << bad;
    } catch (const InputError& ex) {
      EXPECT_EQ(ex.path(), "/bonds/crushed_set_depth");
    }
  }
}

// bonds.compressive_strength_ratio: the lattice bonds' compressive strength is that multiple of
// their (calibrated) tensile strength, and freeze bonds get the same (crushing is the ice's, not
// the interface's); absent, no bond fails in compression; zero or negative is refused naming the field.
TEST(CalibratedIce, CompressiveStrengthAsAMultipleOfTheLatticeBondsTensile) {
  const scene::Scene s =
      scene_from(fill(", \"flexural_strength\": 5e4", ", \"bonds\": {\"compressive_strength_ratio\": 3}"));
  const sim::CalibratedIce ci = sim::calibrate_ice(s);
  const auto d = sim::engine_def(s);
  EXPECT_DOUBLE_EQ(d.bond[0].sigma_cc, 3.0 * ci.bond_tensile_strength);
  EXPECT_DOUBLE_EQ(d.bond[1].sigma_cc, d.bond[0].sigma_cc) << "freeze bonds crush as the ice does";
  EXPECT_EQ(sim::engine_def(scene_from(fill(", \"flexural_strength\": 5e4"))).bond[0].sigma_cc, INFINITY);
  // The blocks' crushing criterion: the force that crushes one lattice bond (compressive strength
  // x bond area); none when bonds do not crush.
  EXPECT_DOUBLE_EQ(sim::block_setup(s, nullptr, 0.0).def.contact_crushing_force, d.bond[0].sigma_cc * d.bond[0].area());
  EXPECT_EQ(sim::block_setup(scene_from(fill(", \"flexural_strength\": 5e4")), nullptr, 0.0).def.contact_crushing_force,
            INFINITY);
  try {
    scene_from(fill("", ", \"bonds\": {\"compressive_strength_ratio\": 0}"));
    FAIL() << "accepted 0";
  } catch (const InputError& e) {
    EXPECT_EQ(e.path(), "/bonds/compressive_strength_ratio");
  }
}
