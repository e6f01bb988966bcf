// Issue 15, ridge generation with the run's ice: the sheet function (sim::sheet_geometry) is where
// build_engine puts its particles; a ridge file records what it was generated with and a run with
// other ice refuses it (each field, through the CLI too), and so does a run whose own ridge section
// has changed since the file was made; `hybridsim ridge <run scene>` takes the scene's ice and
// refuses a ridge section that contradicts it.
#include "cli_fixtures.h"

#include "bonded/hcp_lattice.h"
#include "common/error.h"
#include "common/ice_formulas.h"
#include "io/ridge_file.h"
#include "ridge/ridge.h"
#include "ridge/ridge_json.h"
#include "scene/scene.h"
#include "sim/build.h"
#include "sim/ridge_sheet.h"

#include <gtest/gtest.h>
#include <hdf5.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

namespace fs = std::filesystem;
using nlohmann::json;
using hs::testing::CliResult;

namespace {

fs::path work_dir() {
  static const fs::path d = hs::testing::cli_work_dir("ridge_generation");
  return d;
}
CliResult hybridsim(const std::string& args) { return hs::testing::run_hybridsim(work_dir(), args); }
void write(const std::string& name, const std::string& text) { std::ofstream(work_dir() / name) << text; }
bool has(const std::string& s, const std::string& what) { return s.find(what) != std::string::npos; }

/// A small run scene with a consolidated layer (D = 0.2 m: level ice 3 layers, the layer 5).
json run_scene() {
  return json::parse(R"({
    "name": "gen",
    "time": {"duration": 0.02, "output_interval": 0.01},
    "material": {"particle_diameter": 0.2, "density": 920, "friction": 0.3},
    "water": {"linear_drag_per_area": 1000},
    "ice": {"thickness": 0.5, "length": 6, "width": 3, "origin": [-3, 0],
            "consolidated_layer": {"thickness": 0.9, "width": 2.0, "center_x": 0.0}}
  })");
}

/// A ridge file made for `scene` without running the generator: one keel block under the layer.
void save_matching_ridge(const json& scene, const std::string& file) {
  hs::rigid::RidgeResult r;
  r.def.name = "one block";
  hs::sim::apply_run_scene(r.def, hs::scene::parse_scene(scene, work_dir().string()));
  hs::rigid::RidgeBlock b;
  b.half_extents = hs::Vec3(0.5, 0.5, 0.15);
  b.position = hs::Vec3(0, 1.5, -2.0);
  r.blocks.push_back(b);
  r.profile.x = {0.0};
  r.profile.keel_target = r.profile.keel_depth = r.profile.sail_target = r.profile.sail_height = {0.0};
  hs::io::save_ridge((work_dir() / file).string(), r);
}

json with_ridge(json s, const std::string& file) {
  s["blocks"] = {{"ridge_file", file}, {"conversion", "never"}};
  return s;
}

std::string refusal(const json& scene) {
  try {
    const hs::scene::Scene s = hs::scene::parse_scene(scene, work_dir().string());
    hs::sim::check_ridge_generation(hs::io::load_ridge(s.blocks.ridge_file_path), s, s.blocks.ridge_file_path);
  } catch (const hs::InputError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(RidgeGeneration, TheSheetFunctionIsWhereTheRunPutsItsParticles) {
  const hs::scene::Scene s = hs::scene::parse_scene(run_scene());
  const hs::sim::SheetGeometry g = hs::sim::sheet_geometry(s);
  const double D = 0.2, c = hs::bonded::hcp_layer_spacing(D);
  // Analytic: the level ice's lattice box (3 layers, h = 3 c) floats at draft h rho_i / rho_w.
  EXPECT_EQ(g.layers, 3u);
  EXPECT_NEAR(g.level_box_bottom, -3 * c * 920.0 / 1025.0, 1e-15);
  EXPECT_NEAR(g.level_underside, g.level_box_bottom + 0.5 * c - 0.5 * D, 1e-15);
  EXPECT_NEAR(g.level_top, g.level_box_bottom + 2.5 * c + 0.5 * D, 1e-15);
  // The particles build_engine makes: the lowest and highest centres +- D/2, per part.
  const hs::sim::Built b = hs::sim::build_engine(s, false);
  double lv_lo = 1e9, lv_hi = -1e9, cl_lo = 1e9, cl_hi = -1e9;
  const auto& P = b.engine->particles();
  for (std::size_t i = 0; i < P.size(); ++i) {
    const hs::Vec3 x = P.x[i];
    const bool in_layer = std::abs(x.x()) <= 1.0;
    (in_layer ? cl_lo : lv_lo) = std::min(in_layer ? cl_lo : lv_lo, x.z() - 0.5 * D);
    (in_layer ? cl_hi : lv_hi) = std::max(in_layer ? cl_hi : lv_hi, x.z() + 0.5 * D);
  }
  EXPECT_NEAR(lv_lo, g.level_underside, 1e-12);
  EXPECT_NEAR(lv_hi, g.level_top, 1e-12);
  EXPECT_NEAR(cl_lo, g.layer_underside, 1e-12);
  EXPECT_NEAR(cl_hi, g.layer_top, 1e-12);
  EXPECT_LT(g.layer_underside, g.level_underside - c);  // the layer hangs lower
  // The layer's spheres reach D/2 beyond its band: the generator's layer plate is that wide.
  double reach = 0.0;
  for (std::size_t i = 0; i < P.size(); ++i)
    if (P.x[i].z() < g.level_underside) reach = std::max(reach, std::abs(P.x[i].x()) + 0.5 * D);
  hs::rigid::RidgeDef d;
  hs::sim::apply_run_scene(d, s);
  EXPECT_GT(reach, 1.0 + 0.25 * D);  // beyond the band's 1 m half width
  EXPECT_LE(reach, 0.5 * d.sheet.layer_width + 1e-12);
  // A free plate of those contact surfaces floats there (plate_density) with the draft of the
  // sheet: its buoyancy per area at rest, rho_w (-underside), is the lattice's rho_i h plus the
  // water of the half-layer between the box bottom and the contact surface.
  const double rho = hs::rigid::plate_density(g.level_top, g.level_underside, 1025.0);
  EXPECT_NEAR(rho * (g.level_top - g.level_underside), 920.0 * 3 * c + 1025.0 * (0.5 * D - 0.5 * c), 1e-9);
}

TEST(RidgeGeneration, ARunRefusesARidgeMadeWithOtherIceNamingEachField) {
  save_matching_ridge(run_scene(), "match.h5");
  EXPECT_EQ(refusal(with_ridge(run_scene(), "match.h5")), "");
  struct Case {
    const char* pointer;
    json value;
    const char* named;
  };
  const std::vector<Case> cases = {
      {"/material/density", 910, "/material/density is 910 kg/m^3 in the scene, 920 kg/m^3 in the ridge file"},
      {"/material/friction", 0.5, "/material/friction is 0.5 in the scene, 0.3 in the ridge file"},
      {"/water/density", 1000, "/water/density is 1000 kg/m^3 in the scene, 1025 kg/m^3"},
      {"/ice/thickness", 0.6, "/ice/thickness is 0.6 m in the scene, 0.5 m"},
      {"/ice/consolidated_layer/thickness", 1.2, "/ice/consolidated_layer/thickness is 1.2 m in the scene, 0.9 m"},
      {"/ice/consolidated_layer/width", 3.0, "/ice/consolidated_layer/width is 3 m in the scene, 2 m"},
      {"/ice/consolidated_layer/center_x", 1.0, "/ice/consolidated_layer/center_x (- /blocks/offset/0) is 1 m"},
      {"/material/particle_diameter", 0.25, "/material/particle_diameter 0.25 m in the scene, 0.2 m in the ridge file"},
      {"/blocks/density", 900, "/blocks/density is 900 kg/m^3 in the scene, 920"},
  };
  for (const Case& k : cases) {
    json s = with_ridge(run_scene(), "match.h5");
    s[json::json_pointer(k.pointer)] = k.value;
    const std::string e = refusal(s);
    EXPECT_TRUE(has(e, k.named)) << k.pointer << ": " << e;
    EXPECT_TRUE(has(e, "/blocks/ridge_file")) << e;
    EXPECT_TRUE(has(e, "hybridsim ridge <this scene>.json")) << e;
  }
  // Two fields at once: both named.
  json s = with_ridge(run_scene(), "match.h5");
  s["material"]["density"] = 910;
  s["water"]["density"] = 1000;
  const std::string e = refusal(s);
  EXPECT_TRUE(has(e, "/material/density") && has(e, "/water/density")) << e;
  // A ridge generated under fixed boxes (a standalone ridge scene) is refused as such.
  hs::rigid::RidgeResult r = hs::io::load_ridge((work_dir() / "match.h5").string());
  r.def.sheet.floating = false;
  hs::io::save_ridge((work_dir() / "fixed.h5").string(), r);
  EXPECT_TRUE(has(refusal(with_ridge(run_scene(), "fixed.h5")), "fixed ice boxes"));
}

TEST(RidgeGeneration, AnOldFormatFileIsRefusedWithTheFix) {
  save_matching_ridge(run_scene(), "old.h5");
  // Rewrite its file_format to the first version's.
  const hid_t f = H5Fopen((work_dir() / "old.h5").c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  const hid_t g = H5Gopen2(f, "ridge", H5P_DEFAULT);
  H5Adelete(g, "file_format");
  const hid_t t = H5Tcopy(H5T_C_S1);
  H5Tset_size(t, H5T_VARIABLE);
  H5Tset_cset(t, H5T_CSET_UTF8);
  const hid_t sp = H5Screate(H5S_SCALAR);
  const hid_t a = H5Acreate2(g, "file_format", t, sp, H5P_DEFAULT, H5P_DEFAULT);
  const char* v = "hybridsim-ridge/1";
  H5Awrite(a, t, &v);
  H5Aclose(a), H5Sclose(sp), H5Tclose(t), H5Gclose(g), H5Fclose(f);
  const std::string e = refusal(with_ridge(run_scene(), "old.h5"));
  EXPECT_TRUE(has(e, "hybridsim-ridge/1")) << e;
  EXPECT_TRUE(has(e, "regenerate it with `hybridsim ridge <scene>.json`")) << e;
}

TEST(RidgeGeneration, CliRunRefusesAMismatchWithExit2AndGenerationTakesTheScenesIce) {
  save_matching_ridge(run_scene(), "cli.h5");
  json s = with_ridge(run_scene(), "cli.h5");
  s["material"]["friction"] = 0.5;
  write("mismatch.json", s.dump());
  for (const char* cmd : {"check mismatch.json", "run mismatch.json -o mismatch.h5"}) {
    const CliResult r = hybridsim(cmd);
    EXPECT_EQ(r.rc, 2) << cmd << ": " << r.err;
    EXPECT_TRUE(has(r.err, "/material/friction is 0.5 in the scene, 0.3 in the ridge file")) << r.err;
  }
  // `hybridsim ridge <run scene>`: a ridge section that sets a value the scene sets otherwise is
  // refused before anything is generated, both JSON paths named.
  json g = with_ridge(run_scene(), "gen_ridge.h5");
  g["ridge"] = json::parse(R"({"keel_depth": 1.5, "shoulder_slope_deg": 30, "sail_height": 0, "length": 2.0,
                               "block_thickness": 0.2, "seed": 3, "ice_density": 910,
                               "settle": {"max_time": 40}})");
  write("gen_bad.json", g.dump());
  const CliResult bad = hybridsim("ridge gen_bad.json");
  EXPECT_EQ(bad.rc, 2) << bad.err;
  EXPECT_TRUE(has(bad.err, "/ridge/ice_density") && has(bad.err, "/material/density")) << bad.err;
  EXPECT_FALSE(fs::exists(work_dir() / "gen_ridge.h5"));
  // Without the contradiction it generates into blocks.ridge_file, with the scene's ice, and the
  // run accepts the file.
  g["ridge"].erase("ice_density");
  g["ridge"]["settle"]["friction"] = 0.3;  // equal to the scene's: allowed
  write("gen.json", g.dump());
  const CliResult ok = hybridsim("ridge gen.json");
  ASSERT_EQ(ok.rc, 0) << ok.err;
  const json rep = json::parse(ok.out);
  EXPECT_EQ(rep.at("generation").at("ice_density"), 920.0);
  EXPECT_EQ(rep.at("generation").at("friction"), 0.3);
  EXPECT_EQ(rep.at("generation").at("sheet").at("kind"), "floating");
  ASSERT_TRUE(fs::exists(work_dir() / "gen_ridge.h5"));
  const CliResult chk = hybridsim("check gen.json");
  EXPECT_EQ(chk.rc, 0) << chk.err;
  // Once the scene's ridge section changes the file is out of date: a run refuses it (exit 2),
  // naming every changed field of the definition with both values, until it is made again.
  json stale = g;
  stale["ridge"]["joints"] = {{"min_area", 0.05}};
  stale["ridge"]["seed"] = 4;
  write("gen_stale.json", stale.dump());
  const CliResult st = hybridsim("check gen_stale.json");
  EXPECT_EQ(st.rc, 2) << st.err;
  EXPECT_TRUE(has(st.err, "/joints/min_area is 0.05 there, 0.01 in the file")) << st.err;
  EXPECT_TRUE(has(st.err, "/seed is 4 there, 3 in the file")) << st.err;
  EXPECT_TRUE(has(st.err, "/blocks/ridge_file") && has(st.err, "hybridsim ridge <this scene>.json")) << st.err;
  // The same definition in a file the scene names: the message names that file.
  write("gen_stale_def.json", stale["ridge"].dump());
  stale["ridge"] = "gen_stale_def.json";
  write("gen_stale_file.json", stale.dump());
  const CliResult sf = hybridsim("check gen_stale_file.json");
  EXPECT_EQ(sf.rc, 2) << sf.err;
  EXPECT_TRUE(has(sf.err, "gen_stale_def.json") && has(sf.err, "/joints/min_area is 0.05 there")) << sf.err;
  // A definition file that is gone: the error says why the run reads it and how to do without.
  stale["ridge"] = "no_such_def.json";
  write("gen_no_def.json", stale.dump());
  const CliResult nd = hybridsim("check gen_no_def.json");
  EXPECT_EQ(nd.rc, 2) << nd.err;
  EXPECT_TRUE(has(nd.err, "no_such_def.json") && has(nd.err, "remove /ridge from the scene")) << nd.err;
  // `bench hybrid` on it times steps at once: its scene must not relax the ridge first (with the
  // relaxation on, as a ridge file turns it on by default, 8 steps took over 5 min of relaxing).
  // (The ridge settled again in the bench's world goes to the cache directory, here the test's.)
  setenv("HYBRIDSIM_CACHE_DIR", work_dir().string().c_str(), 1);
  for (const auto& e : fs::directory_iterator(work_dir()))  // a former run's
    if (e.path().filename().string().find(".bench_rest_") != std::string::npos) fs::remove(e.path());
  // (30 steps after the warm-up, so that the timed part holds a rigid step of this small ridge; the
  // pier 34 m from its axis: at its default place, 3 m outside the toe, it would reach every block)
  const CliResult bench = hybridsim("bench hybrid --ridge gen_ridge.h5 --steps 30 --pier-x -34");
  ASSERT_EQ(bench.rc, 0) << bench.err;
  const json b = json::parse(bench.out);
  EXPECT_EQ(b.at("steps"), 30);
  EXPECT_GT(b.at("rigid_steps").get<double>(), 0.0) << bench.out;
  // Made once (with the plates' lift under the sheet), found in the cache the next time.
  const std::string rest = b.at("ridge_at_rest_file").get<std::string>();
  EXPECT_TRUE(std::filesystem::exists(rest)) << rest;
  EXPECT_EQ(std::filesystem::path(rest).parent_path(), work_dir()) << rest;
  EXPECT_TRUE(b.contains("ridge_at_rest_plate_lift_m"));
  const CliResult again = hybridsim("bench hybrid --ridge gen_ridge.h5 --steps 4 --pier-x -34");
  ASSERT_EQ(again.rc, 0) << again.err;
  const json a2 = json::parse(again.out);
  EXPECT_EQ(a2.at("ridge_at_rest_file"), rest);
  EXPECT_FALSE(a2.contains("ridge_at_rest_made_s")) << "made again instead of taken from the cache";
  EXPECT_GT(b.at("rigid_share").get<double>(), 0.0);
  EXPECT_LT(b.at("setup_s").get<double>(), 60.0) << "the bench's set-up relaxes or settles something";
  EXPECT_TRUE(b.contains("moving_blocks_mean"));
  // Whether the file's ridge was at rest when its generation stopped, as the file says, and a
  // warning when it was not (the awake counts then measure its creep).
  const hs::rigid::RidgeResult gen = hs::io::load_ridge((work_dir() / "gen_ridge.h5").string());
  EXPECT_TRUE(gen.stats.settled) << "this ridge settles (the no-warning case; the other ridge below does not)";
  EXPECT_EQ(b.at("ridge_settled").get<bool>(), gen.stats.settled);
  EXPECT_EQ(b.at("ridge_final_asleep_blocks").get<std::size_t>(), gen.stats.final_asleep_blocks);
  EXPECT_EQ(has(bench.err, "was not settled when its generation stopped"), !gen.stats.settled) << bench.err;
  // A ridge made with other ice (910 kg/m^3, friction 0.5, water 1020): the bench's world takes
  // the file's values, so that the ridge is at rest as generated (with 920 / 0.3 hard-wired, the
  // paper-size ridge's blocks slid wherever the sheet woke them).
  json other = with_ridge(g, "other_ice.h5");
  other["ridge"] = g["ridge"];
  other["ridge"]["settle"].erase("friction");
  other["ridge"]["settle"]["max_time"] = 2.5;  // stopped before it settles: the bench warns
  other["ridge"]["settle"]["compaction_time"] = 1.0;
  other["material"]["density"] = 910;
  other["material"]["friction"] = 0.5;
  other["water"]["density"] = 1020;
  write("gen_other.json", other.dump());
  const CliResult og = hybridsim("ridge gen_other.json");
  ASSERT_EQ(og.rc, 0) << og.err;
  const CliResult ob = hybridsim("bench hybrid --ridge other_ice.h5 --steps 4 --pier-x -34");
  ASSERT_EQ(ob.rc, 0) << ob.err;
  const json o = json::parse(ob.out);
  EXPECT_EQ(o.at("ice_density"), 910.0);
  EXPECT_EQ(o.at("friction"), 0.5);
  EXPECT_EQ(o.at("water_density"), 1020.0);
  EXPECT_FALSE(o.at("ridge_settled").get<bool>());
  EXPECT_TRUE(has(ob.err, "was not settled when its generation stopped")) << ob.err;
}
