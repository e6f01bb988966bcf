// Scene loading: defaults, the built engine, overrides, and malformed scenes that must each
// give an hs::InputError naming the right JSON path.
#include "bonded/hcp_lattice.h"
#include "common/error.h"
#include "scene/scene.h"
#include "sim/blocks.h"
#include "sim/build.h"
#include "sim/calibrated_ice.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <functional>

using namespace hs;
using nlohmann::json;

namespace {

json minimal() {
  return json::parse(R"({
    "name": "t",
    "time": {"duration": 0.01},
    "ice": {"thickness": 1.5, "length": 3, "width": 3}
  })");
}

/// Runs f, expects an InputError with this path whose message contains `needle`.
void expect_error(const std::function<void()>& f, const std::string& path, const std::string& needle) {
  try {
    f();
    ADD_FAILURE() << "no error; expected one at " << path;
  } catch (const InputError& e) {
    EXPECT_EQ(e.path(), path) << e.what();
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << "message: " << e.what();
  }
}

/// Parses minimal() with the JSON-pointer `where` set to `value` (or erased if null-ptr tag).
void expect_bad(const std::string& where, const json& value, const std::string& path, const std::string& needle) {
  json j = minimal();
  j[json::json_pointer(where)] = value;
  expect_error([&] { scene::parse_scene(j); }, path, needle);
}

void expect_bad_erase(const std::string& parent, const std::string& key, const std::string& path,
                      const std::string& needle) {
  json j = minimal();
  j[json::json_pointer(parent)].erase(key);
  expect_error([&] { scene::parse_scene(j); }, path, needle);
}

}  // namespace

TEST(Scene, DefaultsFromAMinimalScene) {
  const scene::Scene s = scene::parse_scene(minimal());
  EXPECT_EQ(s.name, "t");
  EXPECT_EQ(s.output, "t.h5");
  EXPECT_EQ(s.time.dt, 0.0);
  EXPECT_EQ(s.time.dt_alpha, 0.1);
  EXPECT_EQ(s.time.snapshot_interval, 0.0);
  EXPECT_EQ(s.material.density, 920.0);
  EXPECT_EQ(s.material.youngs_modulus, 1e9);
  EXPECT_EQ(s.material.particle_diameter, 0.5);
  EXPECT_EQ(s.material.restitution, 0.3);
  EXPECT_EQ(s.material.friction, 0.3);
  EXPECT_EQ(s.material.contact_model, bonded::ContactModel::LinearSpringDashpot);
  EXPECT_DOUBLE_EQ(s.material.effective_stiffness(), kPi * 1e9 * 0.5 / 12.0);  // paper Eq. 1
  EXPECT_EQ(s.bonds.damping_ratio, 0.1);
  EXPECT_EQ(s.bonds.radius_ratio, 1.0);
  EXPECT_EQ(s.bonds.strength_spread, 0.0);
  EXPECT_TRUE(s.water.enabled);
  EXPECT_EQ(s.water.density, 1025.0);
  EXPECT_EQ(s.gravity, Vec3(0, 0, -9.81));
  EXPECT_EQ(s.ice.type, "level_ice");
  EXPECT_FALSE(s.ice.has_consolidated_layer);
  EXPECT_TRUE(s.walls.empty());
  EXPECT_EQ(s.stability.max_speed, 100.0);
  EXPECT_EQ(s.stability.max_overlap_ratio, 0.5);
  EXPECT_TRUE(s.warnings.empty());

  // Default stiffness model "calibrated" (sim/calibrated_ice.h): the springs and the bond strength
  // come from E, nu and material.flexural_strength (0.5 MPa), not from Eq. 1 and bonds.* (those
  // are the "paper_eq1" values, checked below).
  EXPECT_EQ(s.material.stiffness_model, scene::StiffnessModel::Calibrated);
  EXPECT_EQ(s.material.flexural_strength, 0.5e6);
  const auto d = sim::engine_def(s);
  const sim::CalibratedIce ci = sim::calibrate_ice(s);
  EXPECT_EQ(d.contact.kn, ci.kn);
  EXPECT_EQ(d.bond[0].kn, ci.kn);
  EXPECT_EQ(d.bond[0].ks, ci.ks);
  EXPECT_DOUBLE_EQ(d.bond[0].radius, 0.25);
  EXPECT_EQ(d.bond[0].sigma_c, ci.bond_tensile_strength);
  EXPECT_NEAR(ci.flexural_strength, 0.5e6, 1e-6);
  EXPECT_TRUE(d.water.enabled);

  json j = minimal();
  j["material"]["stiffness_model"] = "paper_eq1";
  const auto dp = sim::engine_def(scene::parse_scene(j));
  EXPECT_DOUBLE_EQ(dp.contact.kn, kPi * 1e9 * 0.5 / 12.0);
  EXPECT_EQ(dp.bond[0].sigma_c, 0.6e6);
}

TEST(Scene, BuiltSheetFloatsAtEquilibrium) {
  json j = minimal();
  j["water"]["linear_drag_per_area"] = 1000.0;
  const scene::Scene s = scene::parse_scene(j);
  sim::Built b = sim::build_engine(s);
  const double D = 0.5, c = bonded::hcp_layer_spacing(D);
  EXPECT_EQ(b.layout.layers, 4u);  // round(1.5 / 0.408)
  EXPECT_GT(b.particles, 40u);
  EXPECT_GT(b.bonds, 3 * b.particles);
  const auto& p = b.engine->particles();
  double zmin = 1e9, zmax = -1e9;
  for (std::size_t i = 0; i < p.size(); ++i) {
    EXPECT_DOUBLE_EQ(p.mass[i], 920.0 * bonded::hcp_cell_volume(D));
    EXPECT_GE(p.x[i].x() - 0.25, -1e-9);  // spheres inside the footprint
    EXPECT_LE(p.x[i].x() + 0.25, 3.0 + 1e-9);
    zmin = std::min(zmin, p.x[i].z());
    zmax = std::max(zmax, p.x[i].z());
  }
  // freeboard h (1 - rho_i/rho_w) with h = layers * c
  EXPECT_NEAR(zmax + 0.5 * c, 4 * c * (1.0 - 920.0 / 1025.0), 1e-15);  // measured 8.3e-17 m (was 1e-9)
  auto mean_z = [&] {
    double z = 0;
    for (std::size_t i = 0; i < p.size(); ++i) z += p.x[i].z();
    return z / p.size();
  };
  const double z0 = mean_z();
  b.engine->run(2000);
  double vmax = 0;
  for (std::size_t i = 0; i < p.size(); ++i) vmax = std::max(vmax, p.v[i].norm());
  // Only the small elastic settling of the lattice (top layer partly submerged) remains.
  EXPECT_LT(vmax, 0.05);  // (edge rows differ between A and B layers: a small tilt settles)
  // Measured 3.0e-7 m after 2000 steps (limit 3e-6, was 2e-3).
  EXPECT_NEAR(mean_z(), z0, 3e-6) << "the sheet must start floating at equilibrium";
}

TEST(Scene, ConsolidatedLayerAddsBondedLayers) {
  json j = minimal();
  j["ice"]["length"] = 6;
  const auto n0 = sim::build_engine(scene::parse_scene(j)).particles;
  j["ice"]["consolidated_layer"] = {{"thickness", 2.4}, {"width", 2.0}, {"center_x", 3.0}};
  sim::Built b = sim::build_engine(scene::parse_scene(j));
  EXPECT_GT(b.layout.consolidated_layers, b.layout.layers);
  EXPECT_GT(b.particles, n0);
  // One connected lattice: every particle keeps at least 3 bonds.
  const auto& p = b.engine->particles();
  for (std::size_t i = 0; i < p.size(); ++i) EXPECT_GE(p.bond_count[i], 3) << i;
}

TEST(Scene, WarnsAboutThinIce) {
  json j = minimal();
  j["ice"]["thickness"] = 1.0;
  const scene::Scene s = scene::parse_scene(j);
  ASSERT_EQ(s.warnings.size(), 1u);
  EXPECT_NE(s.warnings[0].find("/ice/thickness"), std::string::npos);
}

TEST(Scene, OverridesSetFieldsParsedAsJsonElseString) {
  json j = minimal();
  j["walls"] = json::array({{{"name", "a"}, {"point", {0, 0, 0}}, {"normal", {1, 0, 0}}}});
  scene::apply_override(j, "ice.thickness=0.9");
  scene::apply_override(j, "name=run2");
  scene::apply_override(j, "water.current=[0.1,0,0]");
  scene::apply_override(j, "ice.consolidated_layer.thickness=2");
  scene::apply_override(j, "walls.0.velocity=[-0.4,0,0]");
  scene::apply_override(j, "water.enabled=false");
  EXPECT_EQ(j["ice"]["thickness"], 0.9);
  EXPECT_EQ(j["name"], "run2");
  EXPECT_EQ(j["water"]["current"][0], 0.1);
  EXPECT_EQ(j["ice"]["consolidated_layer"]["thickness"], 2);
  EXPECT_EQ(j["walls"][0]["velocity"][0], -0.4);
  EXPECT_EQ(j["water"]["enabled"], false);
}

TEST(Scene, SeedIsAWholeNumberDefaultZeroAndSettable) {
  EXPECT_EQ(scene::parse_scene(minimal()).seed, 0u);
  json j = minimal();
  scene::apply_override(j, "seed=7");
  EXPECT_EQ(scene::parse_scene(j).seed, 7u);
  scene::apply_override(j, "seed=18446744073709551615");  // 2^64 - 1, read exactly
  EXPECT_EQ(scene::parse_scene(j).seed, 18446744073709551615ull);
  expect_bad("/seed", -1, "/seed", "e.g. 7");
  expect_bad("/seed", 1.5, "/seed", "e.g. 7");
  expect_bad("/seed", "seven", "/seed", "number");
  expect_bad("/bonds/strength_spread", -0.1, "/bonds/strength_spread", "e.g. 0.2");
}

// ---------------------------------------------------------------- malformed scenes

TEST(SceneErrors, UnknownKeysSuggestTheNearestOne) {
  json j = minimal();
  j["tme"] = 1;
  expect_error([&] { scene::parse_scene(j); }, "/tme", "did you mean \"time\"");
  j = minimal();
  j["ice"]["thicknes"] = 1;
  expect_error([&] { scene::parse_scene(j); }, "/ice/thicknes", "did you mean \"thickness\"");
  j = minimal();
  j["walls"] = json::array({{{"name", "a"}, {"point", {0, 0, 0}}, {"normal", {1, 0, 0}}, {"velocty", {0, 0, 0}}}});
  expect_error([&] { scene::parse_scene(j); }, "/walls/0/velocty", "did you mean \"velocity\"");
}

TEST(SceneErrors, RemovedDragKeysNameTheirReplacement) {
  // One water for blocks and particles (docs/engine.md, "Water drag"): the per-particle
  // water.linear_drag (N s/m) and the blocks' own drag are refused, naming the water's fields.
  expect_bad("/water/linear_drag", 0.5, "/water/linear_drag", "\"linear_drag_per_area\" (Pa s/m");
  json j = minimal();
  j["blocks"] = {{"list", json::array({{{"half_extents", {0.5, 0.5, 0.2}}, {"position", {8, 8, 0}}}})},
                 {"linear_drag", 1000}};
  expect_error([&] { scene::parse_scene(j); }, "/blocks/linear_drag", "water.linear_drag_per_area");
  j["blocks"].erase("linear_drag");
  j["blocks"]["drag_coefficient"] = 1.0;
  expect_error([&] { scene::parse_scene(j); }, "/blocks/drag_coefficient", "water.drag_coefficient");
  j["blocks"].erase("drag_coefficient");
  const scene::Scene s = scene::parse_scene(j);  // and without them the scene is fine
  EXPECT_EQ(s.water.linear_drag_per_area, 1000.0);
  EXPECT_EQ(s.water.drag_coefficient, 1.0);
}

TEST(SceneErrors, WrongTypes) {
  expect_bad("/ice/thickness", "thick", "/ice/thickness", "expected a number");
  expect_bad("/water/enabled", "yes", "/water/enabled", "expected true or false");
  expect_bad("/water/current", json::array({1, 2}), "/water/current", "array of 3 numbers");
  expect_bad("/gravity", json::array({0, 0, "x"}), "/gravity/2", "expected a finite number");
  expect_bad("/walls", 5, "/walls", "expected an array");
  expect_bad("/time", 3, "/time", "expected an object");
  expect_bad("/name", 42, "/name", "expected a string");
}

TEST(SceneErrors, OutOfRangeValues) {
  expect_bad("/ice/thickness", -0.5, "/ice/thickness", "-0.5");
  expect_bad("/ice/thickness", 0.1, "/ice/thickness", "no particle layer");
  expect_bad("/time/dt", -1e-5, "/time/dt", "out of range");
  expect_bad("/time/dt_alpha", 0, "/time/dt_alpha", "> 0");
  expect_bad("/time/duration", 0, "/time/duration", "> 0");
  expect_bad("/material/poisson_ratio", 0.7, "/material/poisson_ratio", "< 0.5");
  expect_bad("/material/restitution", 0, "/material/restitution", "out of range");
  expect_bad("/bonds/damping_ratio", 2, "/bonds/damping_ratio", "<= 1");
  expect_bad("/stability/max_speed", 0, "/stability/max_speed", "> 0");
  expect_bad("/ice/consolidated_layer", json{{"thickness", 1.0}, {"width", 2}}, "/ice/consolidated_layer/thickness",
             "greater than the level ice thickness");
}

TEST(SceneErrors, BadWordsAndNames) {
  expect_bad("/material/contact_model", "hertzz", "/material/contact_model", "did you mean \"hertz\"");
  expect_bad("/ice/type", "ridge", "/ice/type", "level_ice");
  expect_bad("/name", "a/b", "/name", "letters, digits");
}

TEST(SceneErrors, MissingRequiredFields) {
  expect_bad_erase("/ice", "length", "/ice/length", "missing required field");
  expect_bad_erase("/time", "duration", "/time/duration", "missing required field");
  expect_bad_erase("", "name", "/name", "missing required field");
  expect_bad_erase("", "ice", "/ice", "missing required section");
  expect_bad_erase("", "time", "/time", "missing required field");
}

TEST(SceneErrors, Walls) {
  json j = minimal();
  j["walls"] = json::array({{{"name", "a"}, {"point", {0, 0, 0}}, {"normal", {0, 0, 0}}}});
  expect_error([&] { scene::parse_scene(j); }, "/walls/0/normal", "zero length");
  j["walls"] = json::array({{{"name", "a"}, {"point", {0, 0, 0}}, {"normal", {1, 0, 0}}}, {{"name", "b"}}});
  expect_error([&] { scene::parse_scene(j); }, "/walls/1/point", "missing required field");
  j["walls"] = json::array({{{"name", "a"}, {"point", {0, 0, 0}}, {"normal", {1, 0, 0}}},
                            {{"name", "a"}, {"point", {0, 0, 0}}, {"normal", {1, 0, 0}}}});
  expect_error([&] { scene::parse_scene(j); }, "/walls/1/name", "used twice");
}

TEST(SceneErrors, UnstableTimeStepNamesTimeDt) {
  json j = minimal();
  j["time"]["dt"] = 1e-2;
  const scene::Scene s = scene::parse_scene(j);
  expect_error([&] { sim::build_engine(s); }, "/time/dt", "stable limit");
}

TEST(SceneErrors, FilesAndJsonSyntax) {
  expect_error([] { scene::load_scene_file("/nonexistent/dir/scene.json"); }, "/nonexistent/dir/scene.json",
               "cannot open");
  expect_error([] { scene::parse_json_text("{\n  \"name\": \"x\",\n  \"time\": {\"duration\": 1,}\n}", "s.json"); },
               "s.json", "line 3");
  expect_error([] { scene::parse_scene(json::array({1, 2})); }, "/", "expected an object");
  const auto dir = std::filesystem::temp_directory_path() / "hs_test_scene";
  std::filesystem::create_directories(dir);
  const auto f = (dir / "bad.json").string();
  std::ofstream(f) << "{\"name\": \"x\"\n \"time\": {}}";
  expect_error([&] { scene::load_scene_file(f); }, f, "line 2");
}

TEST(SceneErrors, BadOverrides) {
  json j = minimal();
  expect_error([&] { scene::apply_override(j, "ice.thicknes=1"); }, "/ice/thicknes", "did you mean \"thickness\"");
  expect_error([&] { scene::apply_override(j, "ice.thickness"); }, "--set", "path.to.field=value");
  expect_error([&] { scene::apply_override(j, "walls.5.velocity=[0,0,0]"); }, "/walls", "absent");
  expect_error([&] { scene::apply_override(j, "time.duration.x=1"); }, "/time/duration", "not an object");
  expect_error([&] { scene::apply_override(j, "bogus=1"); }, "/bogus", "does not exist in the scene schema");
  // The override is validated like the file: a bad value names its path.
  expect_error(
      [&] {
        json k = minimal();
        scene::apply_override(k, "ice.thickness=-1");
        scene::parse_scene(k);
      },
      "/ice/thickness", "out of range");
}

TEST(SceneSchema, DocsSchemaListsTheSameKeys) {
  std::ifstream in(std::string(HYBRIDSIM_SOURCE_DIR) + "/docs/scene.schema.json");
  ASSERT_TRUE(in) << "docs/scene.schema.json missing";
  const json schema = json::parse(in);
  // Walk the schema's objects and compare their properties with allowed_keys().
  std::function<void(const json&, const std::string&)> walk = [&](const json& node, const std::string& ptr) {
    if (node.contains("$ref")) {
      const std::string ref = node["$ref"].get<std::string>();  // "#/$defs/wall"
      return walk(schema[json::json_pointer(ref.substr(1))], ptr);
    }
    if (node.contains("properties")) {
      std::vector<std::string> keys;
      for (const auto& [k, v] : node["properties"].items()) keys.push_back(k);
      auto allowed = scene::allowed_keys(ptr);
      std::sort(keys.begin(), keys.end());
      std::sort(allowed.begin(), allowed.end());
      EXPECT_EQ(keys, allowed) << "at " << ptr;
      EXPECT_EQ(node.value("additionalProperties", true), false) << "at " << ptr;
      for (const auto& [k, v] : node["properties"].items()) walk(v, ptr + "/" + k);
    }
    if (node.contains("items") && node["items"].is_object()) walk(node["items"], ptr + "/0");
    // A key that takes several forms (e.g. blocks.relax: true/false or an object): each form.
    for (const char* alt : {"oneOf", "anyOf"})
      if (node.contains(alt))
        for (const auto& form : node[alt]) walk(form, ptr);
  };
  walk(schema, "");
}

// ---- structure and analysis sections ----

namespace {
json with_pier() {
  json j = minimal();
  j["structure"] = json::object();
  return j;
}
}  // namespace

TEST(SceneStructure, DefaultsAndBuild) {
  const scene::Scene s0 = scene::parse_scene(minimal());
  EXPECT_FALSE(s0.has_structure);
  const scene::Scene s = scene::parse_scene(with_pier());
  ASSERT_TRUE(s.has_structure);
  EXPECT_EQ(s.structure.name, "pier");
  EXPECT_EQ(s.structure.type, "pier");
  EXPECT_EQ(s.structure.pier.waterline_diameter, 14.0);
  EXPECT_EQ(s.structure.pier.cone_angle_deg, 52.0);
  EXPECT_EQ(s.structure.pier.segments, 64);
  // The column above the cone rises to the deck, z = +20 m, unless the scene says otherwise.
  EXPECT_EQ(s.structure.pier.cone_top_z + s.structure.pier.neck_height, 20.0);
  json deck = with_pier();
  deck["structure"]["pier"] = {{"cone_top_z", 1.5}, {"deck_z", 12.0}};
  EXPECT_EQ(scene::parse_scene(deck).structure.pier.neck_height, 10.5);
  deck["structure"]["pier"] = {{"cone_top_z", 1.5}, {"neck_height", 4.0}};
  EXPECT_EQ(scene::parse_scene(deck).structure.pier.neck_height, 4.0);
  EXPECT_EQ(s.structure.velocity, Vec3(0.4, 0, 0));
  EXPECT_EQ(s.structure.position, Vec3(0, 0, 0));
  EXPECT_EQ(s.structure.friction, 0.1);
  EXPECT_EQ(s.analysis.flexural_strength, 0.5e6);
  EXPECT_EQ(s.analysis.friction_ice_ice, s.material.friction);

  json j = with_pier();
  j["structure"]["pier"] = {{"waterline_diameter", 2.0}, {"cone_top_z", 0.5}, {"cone_bottom_z", -1.0},
                            {"neck_height", 0.5}, {"shaft_diameter", 1.5}, {"shaft_bottom_z", -3.0}};
  j["structure"]["position"] = {-5.0, 1.5, 0.0};
  const scene::Scene s2 = scene::parse_scene(j);
  sim::Built b = sim::build_engine(s2);
  ASSERT_EQ(b.structure, 0);
  EXPECT_EQ(b.structure_parts, (std::vector<std::string>{"neck", "cone", "shaft"}));
  EXPECT_NEAR(b.structure_radius, 1.0 + 1.0 / std::tan(52.0 * kPi / 180.0), 1e-12);
  EXPECT_EQ(b.engine->mesh_wall_position(0), Vec3(-5.0, 1.5, 0.0));

  const auto in = sim::iso_inputs(s2, 1.25);
  EXPECT_EQ(in.waterline_diameter, 2.0);
  EXPECT_EQ(in.thickness, 1.5);
  EXPECT_EQ(in.rubble_height, 1.25);
  EXPECT_DOUBLE_EQ(in.rubble_slope_deg, 0.8 * 52.0);
  EXPECT_EQ(in.youngs_modulus, 1e9);
  EXPECT_EQ(in.friction_ice_ice, 0.3);
  j["ice"]["length"] = 6;
  j["ice"]["consolidated_layer"] = {{"thickness", 2.4}, {"width", 2.0}};
  EXPECT_EQ(sim::iso_inputs(scene::parse_scene(j), 0).thickness, 2.4);
  expect_error([] { sim::iso_inputs(scene::parse_scene(minimal()), 0); }, "/structure", "needs a cone");
}

TEST(SceneStructure, Errors) {
  expect_bad("/structure/pier/cone_angle_deg", 95, "/structure/pier/cone_angle_deg", "(0, 90)");
  expect_bad("/structure/pier/cone_angle", 45, "/structure/pier/cone_angle", "unknown key");
  expect_bad("/structure/pier/shaft_diameter", 30, "/structure/pier/shaft_diameter", "smaller than the cone base");
  expect_bad("/structure/pier/segments", 6.5, "/structure/pier/segments", "whole number");
  expect_bad("/structure/velocty", json::array({1, 0, 0}), "/structure/velocty", "did you mean \"velocity\"");
  expect_bad("/structure/type", "cone", "/structure/type", "use one of");
  expect_bad("/structure/friction", -1, "/structure/friction", "out of range");
  expect_bad("/analysis/rubble_porosity", 1.0, "/analysis/rubble_porosity", "out of range");
  expect_bad("/analysis/flexural", 1e6, "/analysis/flexural", "unknown key");
  expect_bad("/structure/pier/deck_z", 1.0, "/structure/pier/deck_z", "must be above cone_top_z = 2 m");
  json both = minimal();
  both["structure"]["pier"] = {{"deck_z", 15.0}, {"neck_height", 4.0}};
  expect_error([&] { scene::parse_scene(both); }, "/structure/pier/deck_z", "not both");
  json j = minimal();
  j["structure"] = {{"type", "mesh"}};
  expect_error([&] { scene::parse_scene(j); }, "/structure/mesh", "missing required field");
  j["structure"] = {{"type", "mesh"}, {"mesh", "no_such_pier.stl"}};
  expect_error([&] { scene::parse_scene(j, "/some/dir"); }, "/structure/mesh", "/some/dir/no_such_pier.stl");
  j["structure"] = {{"type", "mesh"}, {"pier", json::object()}, {"mesh", "x.stl"}};
  expect_error([&] { scene::parse_scene(j); }, "/structure/pier", "only used with");
}

TEST(SceneBlocks, DefaultsAndErrors) {
  json j = minimal();
  j["blocks"] = json::parse(R"({"list": [{"half_extents": [1, 0.5, 0.3], "position": [0, 0, -1]}]})");
  const scene::Scene s = scene::parse_scene(j);
  ASSERT_TRUE(s.has_blocks);
  EXPECT_EQ(s.blocks.list.size(), 1u);
  EXPECT_EQ(s.blocks.conversion, "hybrid");
  EXPECT_EQ(s.blocks.density, s.material.density);
  EXPECT_EQ(s.blocks.flexural_strength, s.analysis.flexural_strength);
  EXPECT_FALSE(scene::parse_scene(minimal()).has_blocks);

  expect_bad("/blocks", json::object(), "/blocks", "no blocks");
  expect_bad("/blocks/ridge_file", "no_such_ridge.h5", "/blocks/ridge_file", "hybridsim ridge");
  expect_bad("/blocks/list", json::parse(R"([{"half_extents": [1, 0, 0.3]}])"), "/blocks/list/0/half_extents/1",
             "must be > 0");
  expect_bad("/blocks/list", json::parse(R"([{"orientation": [0, 0, 0, 0]}])"), "/blocks/list/0/orientation",
             "non-zero quaternion");
  expect_bad("/blocks/list", json::parse(R"([{"postion": [0, 0, 0]}])"), "/blocks/list/0/postion",
             "did you mean \"position\"");
  json k = minimal();
  k["blocks"] = json::parse(R"({"list": [{}], "rigid_dt": -1})");
  expect_error([&] { scene::parse_scene(k); }, "/blocks/rigid_dt", "out of range");
  k["blocks"] = json::parse(R"({"list": [{}], "conversion": "sometimes"})");
  expect_error([&] { scene::parse_scene(k); }, "/blocks/conversion", "use one of");
  k["blocks"] = json::parse(R"({"list": [{}], "safety_factor": 0})");
  expect_error([&] { scene::parse_scene(k); }, "/blocks/safety_factor", "out of range");
  k["blocks"] = json::parse(R"({"list": [{}], "region": {"shape": "box"}})");
  expect_error([&] { scene::parse_scene(k); }, "/blocks/region/half_extents", "three half extents");
  k["blocks"] = json::parse(R"({"list": [{}], "keep_x": [5, 1]})");
  expect_error([&] { scene::parse_scene(k); }, "/blocks/keep_x", "min must be < max");
  // Counts are whole numbers (20.5 used to be cut to 20); 20.0 is 20.
  k["blocks"] = json::parse(R"({"list": [{}], "solver_iterations": 20.5})");
  expect_error([&] { scene::parse_scene(k); }, "/blocks/solver_iterations", "expected a whole number, got 20.5");
  k["blocks"] = json::parse(R"({"list": [{}], "solver_iterations": 30.0})");
  EXPECT_EQ(scene::parse_scene(k).blocks.solver_iterations, 30);
  // The solver's early exit (docs/rigid.md, "Solver iterations and their early exit"): 1e-4 m/s by
  // default, 0 turns it off, a negative value is refused; the scene's value reaches the world.
  EXPECT_EQ(scene::parse_scene(k).blocks.solver_tolerance, 1e-4);
  k["blocks"] = json::parse(R"({"list": [{}], "solver_tolerance": 0})");
  EXPECT_EQ(sim::block_setup(scene::parse_scene(k), nullptr, 0.0).def.world.solver_tolerance, 0.0);
  k["blocks"] = json::parse(R"({"list": [{}], "solver_tolerance": 3e-4})");
  EXPECT_EQ(sim::block_setup(scene::parse_scene(k), nullptr, 0.0).def.world.solver_tolerance, 3e-4);
  k["blocks"] = json::parse(R"({"list": [{}], "solver_tolerance": -1e-4})");
  expect_error([&] { scene::parse_scene(k); }, "/blocks/solver_tolerance", "out of range");
  k["blocks"] = json::parse(R"({"list": [{}], "solver_iterations": 30.0})");
  // Fixed friction directions: on by default (the generator settles the keel so; with Bullet's one
  // sliding direction the keel creeps in the run), off on request.
  EXPECT_TRUE(scene::parse_scene(k).blocks.fixed_friction_directions);
  k["blocks"] = json::parse(R"({"list": [{}], "fixed_friction_directions": false})");
  EXPECT_FALSE(scene::parse_scene(k).blocks.fixed_friction_directions);
  k["blocks"] = json::parse(R"({"list": [{}], "fixed_friction_directions": 1})");
  expect_error([&] { scene::parse_scene(k); }, "/blocks/fixed_friction_directions", "");
  // Friction rows that see external torques (docs/rigid.md): off by default, on on request.
  k["blocks"] = json::parse(R"({"list": [{}]})");
  EXPECT_FALSE(scene::parse_scene(k).blocks.friction_sees_torque);
  k["blocks"] = json::parse(R"({"list": [{}], "friction_sees_torque": true})");
  EXPECT_TRUE(scene::parse_scene(k).blocks.friction_sees_torque);
  EXPECT_TRUE(sim::block_setup(scene::parse_scene(k), nullptr, 0.0).def.world.friction_sees_torque);  // reaches the world
  k["blocks"] = json::parse(R"({"list": [{}], "friction_sees_torque": "yes"})");
  expect_error([&] { scene::parse_scene(k); }, "/blocks/friction_sees_torque", "");
  expect_bad("/parallel/balance_interval", 500.5, "/parallel/balance_interval", "whole number");
  expect_bad("/parallel/balance_interval", -1, "/parallel/balance_interval", "must be >= 0");
}

TEST(SceneBlocks, Relax) {
  // The relaxation before the freeze: on by default with a ridge file, off for a list alone
  // (its initial velocities are the scene's), true / an object turns it on, false off.
  json k = minimal();
  k["blocks"] = json::parse(R"({"list": [{}]})");
  const scene::Scene d = scene::parse_scene(k);
  EXPECT_FALSE(d.blocks.relax.enabled);
  k["blocks"]["relax"] = true;
  EXPECT_TRUE(scene::parse_scene(k).blocks.relax.enabled);
  EXPECT_EQ(d.blocks.relax.max_time, 30.0);
  EXPECT_EQ(d.blocks.relax.speed, 0.002);
  EXPECT_EQ(d.blocks.relax.hold, 1.0);
  EXPECT_EQ(d.blocks.relax.damping, 0.0);
  k["blocks"]["relax"] = false;
  EXPECT_FALSE(scene::parse_scene(k).blocks.relax.enabled);
  k["blocks"]["relax"] = json::parse(R"({"max_time": 12, "speed": 0.005, "hold": 0.5, "damping": 0.3})");
  const scene::Scene r = scene::parse_scene(k);
  EXPECT_TRUE(r.blocks.relax.enabled);
  EXPECT_EQ(r.blocks.relax.max_time, 12.0);
  EXPECT_EQ(r.blocks.relax.speed, 0.005);
  EXPECT_EQ(r.blocks.relax.hold, 0.5);
  EXPECT_EQ(r.blocks.relax.damping, 0.3);
  k["blocks"]["relax"] = json::parse(R"({"max_tim": 12})");
  expect_error([&] { scene::parse_scene(k); }, "/blocks/relax/max_tim", "did you mean \"max_time\"");
  k["blocks"]["relax"] = json::parse(R"({"speed": 0})");
  expect_error([&] { scene::parse_scene(k); }, "/blocks/relax/speed", "out of range");
  k["blocks"]["relax"] = json::parse(R"({"damping": -1})");
  expect_error([&] { scene::parse_scene(k); }, "/blocks/relax/damping", "out of range");
  k["blocks"]["relax"] = "yes";
  expect_error([&] { scene::parse_scene(k); }, "/blocks/relax", "");
}

TEST(SceneStructure, MeshFileRelativeToTheSceneFile) {
  namespace fs = std::filesystem;
  const fs::path d = fs::temp_directory_path() / ("hs_test_scene_mesh_" + std::to_string(::getpid()));
  fs::create_directories(d / "meshes");
  mesh::PierParams pp;
  pp.waterline_diameter = 2.0;
  pp.cone_top_z = 0.5;
  pp.cone_bottom_z = -1.0;
  pp.neck_height = 0.5;
  pp.shaft_diameter = 1.5;
  pp.shaft_bottom_z = -3.0;
  pp.segments = 16;
  mesh::write_stl_ascii(mesh::make_pier(pp), (d / "meshes" / "p.stl").string());
  json j = minimal();
  j["structure"] = {{"type", "mesh"}, {"mesh", "meshes/p.stl"}, {"position", {-5, 0, 0}}};
  std::ofstream(d / "s.json") << j.dump();
  const scene::Scene s = scene::load_scene_file((d / "s.json").string());
  EXPECT_EQ(s.structure.mesh_path, (d / "meshes" / "p.stl").string());
  sim::Built b = sim::build_engine(s);
  EXPECT_EQ(b.structure_parts, (std::vector<std::string>{"neck", "cone", "shaft"}));
  EXPECT_NEAR(b.structure_radius, mesh::pier_cone_radius(pp, -1.0), 1e-9);
  expect_error([&] { sim::iso_inputs(s, 0); }, "/structure/type", "parametric pier");
  fs::remove_all(d);
}
