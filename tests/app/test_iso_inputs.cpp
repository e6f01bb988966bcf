// The ISO 19906 inputs of a run and their sources (sim/iso_inputs.h): which value each input
// takes from the scene, the run's measurements, the ridge file or the calibration; the keel
// depth below the consolidated layer; the pier width the keel meets; the lattice's measured
// thickness; and a run's /analysis/iso/inputs, recomputed by tools/iso_reference.py.
#include "cli_fixtures.h"

#include "common/hcp_geometry.h"
#include "io/ridge_file.h"
#include "scene/scene.h"
#include "sim/blocks.h"
#include "sim/build.h"
#include "sim/iso_inputs.h"
#include "sim/ridge_sheet.h"

#include <gtest/gtest.h>
#include <hdf5.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <set>
#include <string>

namespace {

using hs::sim::IsoAssembly;
using hs::sim::IsoMeasured;
using hs::sim::IsoSource;
using hs::sim::RidgeKeel;
using nlohmann::json;
namespace fs = std::filesystem;

/// A pier scene: level ice 0.6 m, the default pier (14 m waterline, 52 deg, cone base at
/// z = -4 m, 10 m shaft) with its axis at the waterline, E and flexural strength given.
json pier_scene() {
  return json::parse(R"({
    "name": "iso_inputs",
    "time": {"duration": 0.01},
    "material": {"youngs_modulus": 2e7, "particle_diameter": 0.2},
    "ice": {"thickness": 0.6, "length": 4, "width": 4},
    "structure": {"type": "pier", "position": [-12, 2, 0]},
    "analysis": {"flexural_strength": 6e4}
  })");
}

IsoAssembly assemble(const json& j, const IsoMeasured& m) {
  return hs::sim::assemble_iso_inputs(hs::scene::parse_scene(j), m);
}

/// The ridge of the keel scene's file (scenes/ridge_keel_8m_ridge.h5, rounded): keel 7.85 m
/// below the waterline, the consolidated layer's underside 0.80 m below it, porosity 0.42.
RidgeKeel keel_8m() {
  RidgeKeel k;
  k.path = "ridge.h5";
  k.keel_depth = 7.85;
  k.layer_bottom_depth = 0.80;
  k.porosity = 0.42;
  return k;
}

const std::set<std::string> kSources = {"scene", "measured", "default", "ridge_file", "calibrated"};

void expect_complete(const IsoAssembly& a) {
  const auto& keys = hs::analysis::iso_input_keys();
  ASSERT_EQ(a.records.size(), keys.size());
  const json values = hs::analysis::iso_inputs_to_json(a.in);
  for (std::size_t k = 0; k < keys.size(); ++k) {
    EXPECT_EQ(a.records[k].key, keys[k]);
    EXPECT_EQ(a.records[k].value, values[keys[k]].get<double>()) << keys[k];
    EXPECT_TRUE(std::isfinite(a.records[k].value)) << keys[k];
    EXPECT_EQ(kSources.count(hs::sim::to_string(a.records[k].source)), 1u) << keys[k];
  }
}

}  // namespace

TEST(IsoInputs, LevelIceSceneTakesTheMeasuredThicknessAndPileHeight) {
  IsoMeasured m;
  m.thickness = 0.65;
  m.rubble_height = 0.4;
  const IsoAssembly a = assemble(pier_scene(), m);
  expect_complete(a);
  EXPECT_EQ(a.in.thickness, 0.65);
  EXPECT_EQ(a.record("thickness").source, IsoSource::Measured);
  EXPECT_EQ(a.in.rubble_height, 0.4);
  EXPECT_EQ(a.record("rubble_height").source, IsoSource::Measured);
  EXPECT_EQ(a.in.flexural_strength, 6e4);
  EXPECT_EQ(a.record("flexural_strength").source, IsoSource::Scene);
  EXPECT_EQ(a.in.youngs_modulus, 2e7);
  EXPECT_EQ(a.record("youngs_modulus").source, IsoSource::Scene);
  EXPECT_EQ(a.record("poisson_ratio").source, IsoSource::Default);
  EXPECT_EQ(a.in.rubble_porosity, 0.3);
  EXPECT_EQ(a.record("rubble_porosity").source, IsoSource::Default);
  EXPECT_EQ(a.in.keel_depth, 0.0);
  EXPECT_EQ(a.record("keel_depth").source, IsoSource::Default);
  EXPECT_EQ(a.in.keel_width, 14.0);  // no keel: the waterline diameter
  EXPECT_EQ(hs::analysis::compute_iso(a.in).F_K, 0.0);
  // Nothing measured (`hybridsim iso` on a scene): the nominal thickness, from the scene.
  const IsoAssembly n = assemble(pier_scene(), {});
  EXPECT_EQ(n.in.thickness, 0.6);
  EXPECT_EQ(n.record("thickness").source, IsoSource::Scene);
  EXPECT_EQ(n.record("rubble_height").source, IsoSource::Default);
}

TEST(IsoInputs, RidgeSceneTakesTheKeelBelowTheConsolidatedLayerAndThePorosityFromTheRidgeFile) {
  IsoMeasured m;
  m.thickness = 0.98;
  m.rubble_height = 0.3;
  m.ridge = keel_8m();
  const IsoAssembly a = assemble(pier_scene(), m);
  expect_complete(a);
  // 7.85 m below the waterline minus the layer's underside at 0.80 m: 7.05 m, not 7.85 m.
  EXPECT_NEAR(a.in.keel_depth, 7.05, 1e-15);  // 7.85 - 0.80 in doubles: measured 0
  EXPECT_EQ(a.record("keel_depth").source, IsoSource::RidgeFile);
  EXPECT_EQ(a.in.rubble_porosity, 0.42);
  EXPECT_EQ(a.record("rubble_porosity").source, IsoSource::RidgeFile);
  // The keel acts from the layer's underside (z = -0.80 m) down to z = -7.85 m: over the cone
  // (15.2 to 20.25 m across) and the 10 m shaft below z = -4 m.
  const double mu_phi = std::tan(M_PI / 4 + 15.0 * M_PI / 180.0);
  const double gamma_e = (1 - 0.42) * (1025.0 - 920.0) * 9.81;
  const hs::mesh::PierParams pier;
  const double wk = hs::sim::keel_width_on_pier(pier, -0.80, a.in.keel_depth, mu_phi, gamma_e, 3e3);
  EXPECT_NEAR(a.in.keel_width, wk, 1e-14 * wk);  // measured 0 (the same sums; phi/2 vs 15 deg could round)
  EXPECT_GT(a.in.keel_width, 10.0);
  EXPECT_LT(a.in.keel_width, 20.25);
  // The keel load with the ridge's own depth below the waterline would be larger: the
  // consolidated layer is subtracted.
  hs::analysis::IsoInputs full = a.in;
  full.keel_depth = 7.85;
  EXPECT_GT(hs::analysis::compute_iso(full).F_K, 1.1 * hs::analysis::compute_iso(a.in).F_K);  // measured 1.17
}

// ISO's pile is the pile at the load peak (sim::PileAtLoadPeak): its mean height, slope and
// porosity over the peak's window, each marked "measured at t = ..."; the run's maximum pile only
// when the window has no sample; the keel keeps the ridge file's porosity.
TEST(IsoInputs, ThePileAtTheLoadPeakGivesHeightSlopeAndPorosity) {
  IsoMeasured m;
  m.thickness = 0.98;
  m.rubble_height = 6.44;  // the run's maximum
  m.ridge = keel_8m();
  m.at_peak = hs::sim::PileAtLoadPeak{{2.5e6, 28.1, 29.1, false}, 5.9, 33.0, 0.22};
  const IsoAssembly a = assemble(pier_scene(), m);
  expect_complete(a);
  EXPECT_EQ(a.in.rubble_height, 5.9);
  EXPECT_EQ(a.record("rubble_height").source, IsoSource::Measured);
  EXPECT_EQ(a.record("rubble_height").origin, "measured at t = 28.1 to 29.1 s (load peak)");
  EXPECT_NE(a.record("rubble_height").note.find("the run's maximum 6.44 m"), std::string::npos);
  EXPECT_EQ(a.in.rubble_slope_deg, 33.0);
  EXPECT_EQ(a.record("rubble_slope_deg").origin, "measured at t = 28.1 to 29.1 s (load peak)");
  EXPECT_EQ(a.in.rubble_porosity, 0.22);
  EXPECT_EQ(a.record("rubble_porosity").source, IsoSource::Measured);
  EXPECT_EQ(a.in.keel_porosity, 0.42);
  EXPECT_EQ(a.record("keel_porosity").source, IsoSource::RidgeFile);
  // F_K follows the keel's porosity, not the pile's.
  hs::analysis::IsoInputs keel = a.in;
  keel.rubble_porosity = 0.42;
  EXPECT_EQ(hs::analysis::compute_iso(keel).F_K, hs::analysis::compute_iso(a.in).F_K);
  keel.keel_porosity = 0.22;
  EXPECT_GT(hs::analysis::compute_iso(keel).F_K, 1.05 * hs::analysis::compute_iso(a.in).F_K);
  // A slope outside (0, cone angle) is not ISO's: 0.8 alpha, assumed; no sample in the window:
  // the run's maximum pile, the ridge file's porosity.
  m.at_peak = hs::sim::PileAtLoadPeak{{2.5e6, 28.1, 29.1, false}, NAN, 60.0, NAN};
  const IsoAssembly b = assemble(pier_scene(), m);
  EXPECT_NEAR(b.in.rubble_slope_deg, 0.8 * 52.0, 1e-13);
  EXPECT_EQ(b.record("rubble_slope_deg").source, IsoSource::Default);
  EXPECT_EQ(b.record("rubble_slope_deg").origin, "assumed 0.8 x cone angle");
  EXPECT_NE(b.record("rubble_slope_deg").note.find("60 deg, is outside"), std::string::npos);
  EXPECT_EQ(b.in.rubble_height, 6.44);
  EXPECT_EQ(b.record("rubble_height").origin, "measured: the run's maximum");
  EXPECT_EQ(b.in.rubble_porosity, 0.42);
  EXPECT_EQ(b.record("rubble_porosity").source, IsoSource::RidgeFile);
}

// The paper's Fig. 7 "frozen at 4 m": the keel counts down to the cone base only.
TEST(IsoInputs, AKeelFrozenAtTheConeBaseStopsThere) {
  IsoMeasured m;
  m.thickness = 0.98;
  m.rubble_height = 0.3;
  m.ridge = keel_8m();
  const hs::scene::Scene s = hs::scene::parse_scene(pier_scene());
  EXPECT_EQ(hs::sim::cone_base_depth(s), 4.0);  // the default pier: cone base at z = -4 m
  m.keel_depth_limit = hs::sim::cone_base_depth(s);
  const IsoAssembly a = assemble(pier_scene(), m);
  EXPECT_NEAR(a.in.keel_depth, 4.0 - 0.80, 1e-15);  // the cone base minus the layer's underside
  m.keel_depth_limit.reset();
  const IsoAssembly full = assemble(pier_scene(), m);
  EXPECT_LT(hs::analysis::compute_iso(a.in).F_K, 0.6 * hs::analysis::compute_iso(full.in).F_K);
  m.keel_depth_limit = 20.0;  // deeper than the keel: the whole keel
  EXPECT_EQ(assemble(pier_scene(), m).in.keel_depth, full.in.keel_depth);
}

TEST(IsoInputs, SceneValuesOverrideTheRunAndTheRidgeFile) {
  json j = pier_scene();
  j["analysis"]["keel_depth"] = 3.0;
  j["analysis"]["rubble_porosity"] = 0.25;
  j["analysis"]["rubble_height"] = 2.0;
  IsoMeasured m;
  m.rubble_height = 0.3;
  m.ridge = keel_8m();
  const IsoAssembly a = assemble(j, m);
  expect_complete(a);
  EXPECT_EQ(a.in.keel_depth, 3.0);
  EXPECT_EQ(a.record("keel_depth").source, IsoSource::Scene);
  EXPECT_EQ(a.in.rubble_porosity, 0.25);
  EXPECT_EQ(a.record("rubble_porosity").source, IsoSource::Scene);
  EXPECT_EQ(a.in.rubble_height, 2.0);
  EXPECT_EQ(a.record("rubble_height").source, IsoSource::Scene);
}

TEST(IsoInputs, CalibratedIceReplacesTheScenesEAndStrength) {
  IsoMeasured m;
  hs::sim::CalibratedIce ci;
  ci.youngs_modulus = 5e9;
  ci.poisson_ratio = 0.28;
  ci.flexural_strength = 0.6e6;
  m.calibrated = ci;
  json j = pier_scene();
  j.erase("analysis");
  const IsoAssembly a = assemble(j, m);
  expect_complete(a);
  EXPECT_EQ(a.in.youngs_modulus, 5e9);
  EXPECT_EQ(a.in.poisson_ratio, 0.28);
  EXPECT_EQ(a.in.flexural_strength, 0.6e6);
  for (const char* k : {"youngs_modulus", "poisson_ratio", "flexural_strength"})
    EXPECT_EQ(a.record(k).source, IsoSource::Calibrated) << k;
  // An explicit analysis.flexural_strength overrides the lattice's, as every analysis.* value.
  const IsoAssembly o = assemble(pier_scene(), m);
  EXPECT_EQ(o.in.flexural_strength, 6e4);
  EXPECT_EQ(o.record("flexural_strength").source, IsoSource::Scene);
}

TEST(IsoInputs, KeelWidthOnThePierIsThePressureWeightedDiameter) {
  // A 45 deg cone (r = 7 - z) from z = 2 down to its base at z = -4 (r = 11), a 10 m shaft
  // down to z = -20. Widths by hand; Simpson's rule per piece is exact, so to rounding.
  hs::mesh::PierParams p;
  p.cone_angle_deg = 45.0;
  const double mu = 1.7;
  const auto width = [&](double z_top, double h_k, double gamma_e, double c) {
    return hs::sim::keel_width_on_pier(p, z_top, h_k, mu, gamma_e, c);
  };
  // Wholly on the shaft: its diameter, whatever the pressure.
  EXPECT_NEAR(width(-5.0, 3.0, 500.0, 3e3), 10.0, 1e-13);
  EXPECT_NEAR(width(-5.0, 3.0, 0.0, 3e3), 10.0, 1e-13);
  // On the cone, uniform pressure (cohesion only): the mean diameter, r from 8 to 10 -> 18 m.
  EXPECT_NEAR(width(-1.0, 2.0, 0.0, 3e3), 18.0, 1e-13);
  // On the cone, pressure ~ depth d (no cohesion): w = 2 (8 + d), int w d / int d over [0, 2]
  // = 2 (8 + (8/3)/2) = 56/3 m: the deeper, wider part weighs more.
  EXPECT_NEAR(width(-1.0, 2.0, 500.0, 0.0), 56.0 / 3.0, 1e-13);
  // Across the cone base (uniform pressure): 1 m of cone (r 10 -> 11, mean 21 m across) and
  // 2 m of shaft (10 m): (21 + 20) / 3 m; the step at the base is not smeared.
  EXPECT_NEAR(width(-3.0, 3.0, 0.0, 3e3), 41.0 / 3.0, 1e-13);
  // Below the shaft's bottom the keel meets nothing: 1 m of shaft, 1 m of nothing.
  EXPECT_NEAR(width(-19.0, 2.0, 0.0, 3e3), 5.0, 1e-13);
  // Measured error of all of these: 0 (limit 1e-13 m, a few ulps of the sums).
}

TEST(IsoInputs, LatticeThicknessIsTheBuiltLayers) {
  // 0.6 m at D = 0.2 m: round(0.6 / c) = 4 HCP layers of c = D sqrt(2/3) = 0.1633 m -> 0.653 m,
  // 9 % above the nominal thickness; a 0.9 m consolidated layer: 6 layers -> 0.980 m.
  const double c = hs::hcp_layer_spacing(0.2);
  json j = pier_scene();
  j["structure"]["position"] = {-30, 2, 0};
  const hs::sim::Built b = hs::sim::build_engine(hs::scene::parse_scene(j));
  EXPECT_NEAR(b.lattice_thickness, 4 * c, 3e-13 * c);  // measured 2.7e-14 relative (buoyant volume / area)
  j["ice"]["consolidated_layer"] = {{"thickness", 0.9}, {"width", 2.0}, {"center_x", 2.0}};
  const hs::sim::Built bc = hs::sim::build_engine(hs::scene::parse_scene(j));
  EXPECT_NEAR(bc.lattice_thickness, 6 * c, 3e-13 * c);  // measured 2.5e-14 relative
}

TEST(IsoInputs, TheRidgeFilesKeelReachesTheBlockSetup) {
  // A ridge file with one keel block: stats say 5.0 m keel depth and porosity 0.37; its
  // consolidated-layer box (part 1) has its underside at z = -0.8 m, the level ice at -0.53 m.
  hs::rigid::RidgeResult r;
  r.def.name = "iso";
  r.def.level_ice_thickness = 0.6;
  hs::rigid::RidgeBlock blk;
  blk.half_extents = hs::Vec3(0.5, 0.5, 0.15);
  blk.position = hs::Vec3(2, 0, -3.0);
  r.blocks.push_back(blk);
  r.ice.push_back({hs::Vec3(10, 10, 0.3), hs::Vec3(-20, 10, -0.23), 0});
  r.ice.push_back({hs::Vec3(5, 10, 0.45), hs::Vec3(0, 10, -0.35), 1});
  r.stats.keel_depth_achieved = 5.0;
  r.stats.keel_porosity = 0.37;
  r.profile.x = {0.0};
  r.profile.keel_target = r.profile.keel_depth = r.profile.sail_target = r.profile.sail_height = {0.0};
  const fs::path dir = hs::testing::cli_work_dir("iso_inputs");
  hs::sim::apply_run_scene(r.def, hs::scene::parse_scene(pier_scene()));  // made with the run's ice
  hs::io::save_ridge((dir / "keel.h5").string(), r);
  json j = pier_scene();
  j["blocks"] = {{"ridge_file", "keel.h5"}, {"loose_blocks", "keep"}};  // the block has no joint
  const hs::scene::Scene s = hs::scene::parse_scene(j, dir.string());
  const hs::sim::BlockSetup setup = hs::sim::block_setup(s, nullptr, 0.0);
  ASSERT_TRUE(setup.ridge.has_value());
  EXPECT_EQ(setup.ridge->keel_depth, 5.0);
  EXPECT_EQ(setup.ridge->porosity, 0.37);
  EXPECT_NEAR(setup.ridge->layer_bottom_depth, 0.8, 1e-15);
  IsoMeasured m;
  m.ridge = setup.ridge;
  EXPECT_NEAR(hs::sim::assemble_iso_inputs(s, m).in.keel_depth, 4.2, 1e-15);
  // Without a ridge file: no keel from it.
  EXPECT_FALSE(hs::sim::block_setup(hs::scene::parse_scene(pier_scene()), nullptr, 0.0).ridge.has_value());
}

TEST(IsoInputs, RidgeBlocksWithoutAJointAreLeftOut) {
  // Four keel blocks in a row: 0-1 jointed, 2 frozen to the ice only, 3 frozen to nothing (loose
  // rubble: docs/bridge.md, "Relaxation"). blocks.loose_blocks "drop" (the default) leaves 3 out
  // and renumbers nothing else; "keep" keeps all four.
  hs::rigid::RidgeResult r;
  r.def.name = "loose";
  for (int k = 0; k < 4; ++k) {
    hs::rigid::RidgeBlock blk;
    blk.half_extents = hs::Vec3(0.5, 0.5, 0.15);
    blk.position = hs::Vec3(2.0 * k, 0, -3.0);
    r.blocks.push_back(blk);
  }
  r.ice.push_back({hs::Vec3(10, 10, 0.3), hs::Vec3(0, 0, -0.23), 0});
  hs::rigid::RidgeJoint j01, j2i;
  j01.a = 0;
  j01.b = 1;
  j01.area = 0.3;
  j2i.a = 2;
  j2i.b = -1;
  j2i.area = 0.5;
  r.joints = {j01, j2i};
  r.profile.x = {0.0};
  r.profile.keel_target = r.profile.keel_depth = r.profile.sail_target = r.profile.sail_height = {0.0};
  const fs::path dir = hs::testing::cli_work_dir("iso_inputs");
  hs::sim::apply_run_scene(r.def, hs::scene::parse_scene(pier_scene()));
  hs::io::save_ridge((dir / "loose.h5").string(), r);
  const auto setup = [&](const char* loose) {
    json j = pier_scene();
    j["blocks"] = {{"ridge_file", "loose.h5"}};
    if (loose) j["blocks"]["loose_blocks"] = loose;
    return hs::sim::block_setup(hs::scene::parse_scene(j, dir.string()), nullptr, 0.0);
  };
  const hs::sim::BlockSetup d = setup(nullptr);
  ASSERT_EQ(d.blocks.size(), 3u);
  EXPECT_EQ(d.loose_blocks_dropped, 1u);
  EXPECT_EQ(d.ridge_blocks_in_file, 4u);
  for (int k = 0; k < 3; ++k) EXPECT_EQ(d.blocks[k].def.position.x(), 2.0 * k);
  ASSERT_EQ(d.joints.size(), 1u);
  EXPECT_EQ(d.joints[0].a, 0u);
  EXPECT_EQ(d.joints[0].b, 1u);
  ASSERT_EQ(d.ice_joints.size(), 1u);
  EXPECT_EQ(d.ice_joints[0].block, 2u);
  const hs::sim::BlockSetup k = setup("keep");
  EXPECT_EQ(k.blocks.size(), 4u);
  EXPECT_EQ(k.loose_blocks_dropped, 0u);
  EXPECT_THROW(setup("lose"), std::exception);  // not a choice
}

namespace {

/// A fixed-length or variable-length string attribute, "" when absent.
std::string string_attribute(const fs::path& h5, const std::string& object, const char* name) {
  std::string v;
  const hid_t f = H5Fopen(h5.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (f < 0) return v;
  if (H5Lexists(f, object.c_str(), H5P_DEFAULT) > 0 && H5Aexists_by_name(f, object.c_str(), name, H5P_DEFAULT) > 0) {
    const hid_t a = H5Aopen_by_name(f, object.c_str(), name, H5P_DEFAULT, H5P_DEFAULT);
    const hid_t t = H5Aget_type(a);
    if (!H5Tis_variable_str(t)) {
      std::string buf(H5Tget_size(t), '\0');
      H5Aread(a, t, buf.data());
      v = buf.substr(0, buf.find('\0'));
    }
    H5Tclose(t);
    H5Aclose(a);
  }
  H5Fclose(f);
  return v;
}

double double_attribute(const fs::path& h5, const std::string& object, const char* name) {
  double v = NAN;
  const hid_t f = H5Fopen(h5.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (f < 0) return v;
  if (H5Lexists(f, object.c_str(), H5P_DEFAULT) > 0 && H5Aexists_by_name(f, object.c_str(), name, H5P_DEFAULT) > 0) {
    const hid_t a = H5Aopen_by_name(f, object.c_str(), name, H5P_DEFAULT, H5P_DEFAULT);
    H5Aread(a, H5T_NATIVE_DOUBLE, &v);
    H5Aclose(a);
  }
  H5Fclose(f);
  return v;
}

}  // namespace

TEST(IsoInputs, ARidgeRunRecordsItsInputsAndTheReferenceScriptAgrees) {
  // hybridsim run on a small pier scene with a one-block ridge file (keel 5.0 m below the
  // waterline, layer underside 0.8 m, porosity 0.37): /analysis/iso/inputs says where each
  // input came from, and tools/iso_reference.py recomputes the estimate from those inputs.
  hs::rigid::RidgeResult r;
  r.def.name = "iso_run";
  r.def.level_ice_thickness = 1.5;
  hs::rigid::RidgeBlock blk;
  blk.half_extents = hs::Vec3(0.5, 0.5, 0.15);
  blk.position = hs::Vec3(3, 0, -3.0);
  r.blocks.push_back(blk);
  r.ice.push_back({hs::Vec3(5, 10, 0.45), hs::Vec3(0, 10, -0.35), 1});
  r.stats.keel_depth_achieved = 5.0;
  r.stats.keel_porosity = 0.37;
  r.profile.x = {0.0};
  r.profile.keel_target = r.profile.keel_depth = r.profile.sail_target = r.profile.sail_height = {0.0};
  const fs::path dir = hs::testing::cli_work_dir("iso_inputs");
  const json j = json::parse(R"({
    "name": "iso_run",
    "time": {"duration": 0.02, "output_interval": 0.01},
    "material": {"particle_diameter": 0.5},
    "bonds": {"tensile_strength": 2e5, "shear_strength": 2e5},
    "water": {"linear_drag_per_area": 1000},
    "ice": {"thickness": 1.5, "length": 4, "width": 2, "origin": [0, -1]},
    "structure": {"type": "pier", "position": [-8.5, 0, 0], "velocity": [0.5, 0, 0]},
    "blocks": {"ridge_file": "run_keel.h5", "conversion": "never", "relax": false, "loose_blocks": "keep"}
  })");
  json without_blocks = j;
  without_blocks.erase("blocks");
  hs::sim::apply_run_scene(r.def, hs::scene::parse_scene(without_blocks));  // made with the run's ice
  hs::io::save_ridge((dir / "run_keel.h5").string(), r);
  std::ofstream(dir / "iso_run.json") << j.dump(2);
  const fs::path h5 = dir / "iso_run.h5";
  fs::remove(h5);
  const hs::testing::CliResult run = hs::testing::run_hybridsim(dir, "run iso_run.json -o iso_run.h5");
  ASSERT_EQ(run.rc, 0) << run.out << run.err;
  const std::string in = "/analysis/iso/inputs/";
  EXPECT_EQ(string_attribute(h5, in + "keel_depth", "source"), "ridge_file");
  EXPECT_NEAR(double_attribute(h5, in + "keel_depth", "value"), 4.2, 1e-15);
  EXPECT_EQ(double_attribute(h5, "/analysis/iso", "keel_depth"), double_attribute(h5, in + "keel_depth", "value"));
  EXPECT_EQ(string_attribute(h5, in + "rubble_porosity", "source"), "ridge_file");
  EXPECT_EQ(double_attribute(h5, in + "rubble_porosity", "value"), 0.37);
  EXPECT_EQ(string_attribute(h5, in + "thickness", "source"), "measured");
  // D = 0.5 m: round(1.5 / 0.408) = 4 layers -> 1.633 m.
  const double h4 = 4 * hs::hcp_layer_spacing(0.5);
  EXPECT_NEAR(double_attribute(h5, in + "thickness", "value"), h4, 3e-13 * h4);  // as LatticeThicknessIsTheBuiltLayers
  EXPECT_EQ(string_attribute(h5, in + "thickness", "unit"), "m");
  EXPECT_EQ(string_attribute(h5, in + "rubble_height", "source"), "measured");
  // The scene's material is the default, "calibrated" model: ISO gets the lattice's E and strength.
  EXPECT_EQ(string_attribute(h5, in + "flexural_strength", "source"), "calibrated");
  EXPECT_EQ(string_attribute(h5, in + "youngs_modulus", "source"), "calibrated");
  EXPECT_GT(double_attribute(h5, "/analysis/iso", "F_K"), 0.0);
  // The independent script: inputs read back from the file, results recomputed (3e-15).
  const int rc = std::system(("/usr/bin/python3 " HYBRIDSIM_SOURCE_DIR "/tools/iso_reference.py --run '" +
                              h5.string() + "' > '" + (dir / "iso_ref.txt").string() + "' 2>&1")
                                 .c_str());
  EXPECT_EQ(rc, 0) << hs::testing::slurp(dir / "iso_ref.txt");
}
