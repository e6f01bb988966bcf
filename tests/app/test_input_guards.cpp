// Issue 14, items 4-5 and defects 5, 6, 7, 9, 10: inputs that would crash, exhaust the machine
// or give a silently wrong result are refused with exit 2 and the JSON path (or dataset) that
// causes them; nothing non-finite is written to the output. End to end through `hybridsim`.
#include <gtest/gtest.h>
#include "cli_fixtures.h"
#include <hdf5.h>
#include <nlohmann/json.hpp>

#include "common/error.h"
#include "io/ridge_file.h"
#include "ridge/ridge.h"
#include "ridge/ridge_json.h"
#include "scene/scene.h"
#include "sim/build.h"

#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

using Result = hs::testing::CliResult;

fs::path work_dir() { return hs::testing::cli_work_dir("guards"); }

using hs::testing::slurp;

// An 8 GiB address-space cap: a regressed guard fails the test instead of exhausting the machine.
// Not under AddressSanitizer (scripts/test-sanitizers.sh): it reserves ~15 TiB of address space for
// its shadow memory at start, which no cap allows (the guards are then checked without one).
#if defined(__SANITIZE_ADDRESS__)
constexpr const char* kAddressSpaceCap = "";
#else
constexpr const char* kAddressSpaceCap = "ulimit -v 8000000 && ";
#endif
Result hybridsim(const std::string& args) { return hs::testing::run_hybridsim(work_dir(), args, kAddressSpaceCap); }

/// The same at 2 ranks (no address-space cap: Open MPI reserves more than 8 GiB of it).
Result hybridsim_mpi2(const std::string& args) {
  return hs::testing::run_hybridsim(work_dir(), args, hs::testing::mpirun_prefix(2));
}

void write(const std::string& name, const std::string& text) { std::ofstream(work_dir() / name) << text; }

bool has(const std::string& text, const std::string& needle) { return text.find(needle) != std::string::npos; }

/// A 4 m x 2 m sheet of 0.5 m particles with the default pier 1 m clear of its -x edge.
json pier_scene() {
  return json::parse(R"({
    "name": "guard",
    "time": {"duration": 0.02, "output_interval": 0.01},
    "material": {"particle_diameter": 0.5},
    "bonds": {"tensile_strength": 2e5, "shear_strength": 2e5},
    "water": {"linear_drag_per_area": 1000},
    "ice": {"thickness": 1.5, "length": 4, "width": 2, "origin": [0, -1]},
    "structure": {"type": "pier", "position": [-8.5, 0, 0], "velocity": [0.5, 0, 0]}
  })");
}

/// Every scalar double attribute under `group` (name -> value); non-double attributes are skipped.
std::vector<std::pair<std::string, double>> double_attributes(const fs::path& h5, const std::string& group) {
  std::vector<std::pair<std::string, double>> out;
  const hid_t f = H5Fopen(h5.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (f < 0) return out;
  const hid_t g = H5Oopen(f, group.c_str(), H5P_DEFAULT);
  if (g >= 0) {
    hsize_t idx = 0;
    H5Aiterate2(
        g, H5_INDEX_NAME, H5_ITER_INC, &idx,
        [](hid_t loc, const char* name, const H5A_info_t*, void* data) -> herr_t {
          auto& list = *static_cast<std::vector<std::pair<std::string, double>>*>(data);
          const hid_t a = H5Aopen(loc, name, H5P_DEFAULT);
          const hid_t t = H5Aget_type(a);
          if (H5Tget_class(t) == H5T_FLOAT) {
            double v = 0;
            H5Aread(a, H5T_NATIVE_DOUBLE, &v);
            list.emplace_back(name, v);
          }
          H5Tclose(t);
          H5Aclose(a);
          return 0;
        },
        &out);
    H5Oclose(g);
  }
  H5Fclose(f);
  return out;
}

}  // namespace

// ---------------------------------------------------------------- defect 9: JSON and step counts

TEST(InputGuards, DeepJsonDuplicateKeysAndHugeNumbersAreExit2WithTheirPath) {
  // 100,000-deep nesting: was a crash (SIGSEGV, rc 139) while the error was formatted.
  write("deep.json", "{\"name\": \"x\", \"time\": " + std::string(100000, '[') + std::string(100000, ']') + "}");
  Result r = hybridsim("check deep.json");
  EXPECT_EQ(r.rc, 2) << r.err.substr(0, 300);
  EXPECT_TRUE(has(r.err, "nesting deeper than")) << r.err.substr(0, 300);
  // 1e400: was exit 1 with the raw parser message.
  json s = pier_scene();
  std::string text = s.dump();
  text.replace(text.find("0.02"), 4, "1e400");
  write("big.json", text);
  r = hybridsim("check big.json");
  EXPECT_EQ(r.rc, 2) << r.err;
  EXPECT_TRUE(has(r.err, "error: /time/duration: ")) << r.err;
  r = hybridsim("check big.json --set time.duration=1e400");  // --set values too (after the file: same error)
  EXPECT_EQ(r.rc, 2) << r.err;
  write("ok.json", pier_scene().dump());
  r = hybridsim("check ok.json --set time.dt=1e400");
  EXPECT_EQ(r.rc, 2) << r.err;
  EXPECT_TRUE(has(r.err, "error: --set")) << r.err;
  // A duplicate key: silently took the last value.
  text = pier_scene().dump();
  text.replace(text.find("\"duration\""), 0, "\"output_interval\": 0.005, ");
  write("dup.json", text);
  r = hybridsim("check dup.json");
  EXPECT_EQ(r.rc, 2) << r.err;
  EXPECT_TRUE(has(r.err, "error: /time/output_interval: duplicate key")) << r.err;
}

TEST(InputGuards, AbsurdStepCountsAreRefusedNamingBothFields) {
  json s = pier_scene();
  s["time"]["dt"] = 1e-300;  // passed `check` before: 2e298 steps
  write("tiny_dt.json", s.dump());
  Result r = hybridsim("check tiny_dt.json");
  EXPECT_EQ(r.rc, 2) << r.out << r.err;
  EXPECT_TRUE(has(r.err, "error: /time/dt: ")) << r.err;
  EXPECT_TRUE(has(r.err, "/time/duration")) << r.err;
  // The limit itself: 1e10 steps pass the scene reader, one more order does not.
  hs::scene::TimeDef t;
  t.duration = 1.0;
  EXPECT_NO_THROW(hs::scene::check_step_count(t, 1e-10));
  EXPECT_THROW(hs::scene::check_step_count(t, 1e-11), hs::InputError);
  // Eq. 2's dt (time.dt = 0) is checked too, when the simulation is scheduled.
  s = pier_scene();
  s["time"]["duration"] = 1e9;
  write("long.json", s.dump());
  r = hybridsim("check long.json");
  EXPECT_EQ(r.rc, 2) << r.out << r.err;
  EXPECT_TRUE(has(r.err, "Eq. 2")) << r.err;
}

// ---------------------------------------------------------------- defect 7: memory

TEST(InputGuards, MemoryEstimateMatchesTheBuiltSheet) {
  // The estimate (extent / D, before anything is built) against the count of the built sheet.
  std::vector<double> ratios;
  for (const double D : {0.5, 0.25}) {
    json j = pier_scene();
    j["material"]["particle_diameter"] = D;
    j["ice"]["length"] = 6;
    j["ice"]["width"] = 4;
    const hs::scene::Scene s = hs::scene::parse_scene(j, "");
    const hs::sim::MemoryEstimate est = hs::sim::memory_estimate(s);
    const hs::sim::Built b = hs::sim::build_engine(s, false);
    // The estimate counts the whole footprint and 6 bonds per particle (the bulk value); the
    // built sheet drops the spheres crossing its edges and its surface particles have fewer
    // bonds, so the estimate is above the count and closer for smaller D. Measured: particles
    // 1.131 (D = 0.5), 1.074 (D = 0.25); bonds 1.460, 1.226.
    const double rp = est.particles / static_cast<double>(b.particles), rb = est.bonds / static_cast<double>(b.bonds);
    EXPECT_GE(rp, 1.0) << D;
    EXPECT_LE(rp, 1.2) << D;
    EXPECT_GE(rb, 1.0) << D;
    EXPECT_LE(rb, 1.6) << D;
    ratios.push_back(rp);
    EXPECT_GT(est.bytes, 100.0 * est.particles);
  }
  EXPECT_LT(ratios[1], ratios[0]);  // edges matter less as D shrinks
}

TEST(InputGuards, MemoryGuardRefusesWhatDoesNotFitAndNamesTheFields) {
  json j = pier_scene();
  const hs::scene::Scene s = hs::scene::parse_scene(j, "");
  const hs::sim::MemoryEstimate est = hs::sim::memory_estimate(s);
  EXPECT_NO_THROW(hs::sim::check_memory(s, est, 2 * est.bytes));
  EXPECT_NO_THROW(hs::sim::check_memory(s, est, -1));  // unknown: no guard
  try {
    hs::sim::check_memory(s, est, 0.5 * est.bytes);
    ADD_FAILURE() << "no error";
  } catch (const hs::InputError& e) {
    const std::string m = e.what();
    EXPECT_EQ(e.path(), "/ice");
    for (const char* field : {"/ice/length", "/ice/width", "/ice/thickness", "/material/particle_diameter",
                              "MemAvailable", "--ignore-memory-limit"})
      EXPECT_TRUE(has(m, field)) << field << " in " << m;
  }
  EXPECT_THROW(hs::sim::check_memory(s, est, 1.5 * est.bytes, 2), hs::InputError);  // every rank builds it all
}

TEST(InputGuards, BlocksCountInTheMemoryEstimateAndCanBeWhatDoesNotFit) {
  // Two 2 m x 1 m x 0.5 m blocks (1 m^3 each) and a joint: the rigid world and, with conversion
  // on, the particles the blocks would become (2 m^3 / the HCP cell volume D^3/sqrt(2)).
  json j = pier_scene();
  const hs::scene::Scene s = hs::scene::parse_scene(j, "");
  const double D = s.material.particle_diameter;
  hs::sim::BlockSetup b;
  for (int k = 0; k < 2; ++k) {
    hs::bridge::BlockInit bi;
    bi.def.half_extents = hs::Vec3(1.0, 0.5, 0.25);
    b.blocks.push_back(bi);
  }
  b.joints.push_back({});
  b.def.mode = hs::bridge::ConversionMode::Never;
  hs::sim::MemoryEstimate est = hs::sim::memory_estimate(s);
  const double ice_bytes = est.bytes;
  hs::sim::add_blocks(est, b, D, s.walls.size());
  EXPECT_EQ(est.blocks, 2.0);
  EXPECT_EQ(est.joints, 1.0);
  EXPECT_EQ(est.block_particles, 0.0);  // never converted: the rigid world only
  EXPECT_DOUBLE_EQ(est.bytes - ice_bytes, 2 * hs::sim::kBytesPerBlock + hs::sim::kBytesPerJoint);
  b.def.mode = hs::bridge::ConversionMode::Hybrid;
  hs::sim::add_blocks(est, b, D, s.walls.size());  // replaces the first call's figures
  EXPECT_NEAR(est.block_particles, 2.0 * std::sqrt(2.0) / (D * D * D), 1e-9 * est.block_particles);
  EXPECT_GT(est.block_bytes, 100.0 * est.block_particles);
  EXPECT_DOUBLE_EQ(est.bytes, ice_bytes + est.block_bytes);
  // A fixed box (a wall, e.g. the keel scenes' end walls of 2,000 m^3 each) never converts: it
  // counts as a block of the rigid world, not as particles.
  hs::bridge::BlockInit wall;
  wall.def.half_extents = hs::Vec3(25.0, 1.0, 10.0);
  wall.def.fixed = true;
  b.blocks.push_back(wall);
  hs::sim::add_blocks(est, b, D, s.walls.size());
  EXPECT_EQ(est.blocks, 3.0);
  EXPECT_NEAR(est.block_particles, 2.0 * std::sqrt(2.0) / (D * D * D), 1e-9 * est.block_particles);
  EXPECT_DOUBLE_EQ(est.bytes, ice_bytes + est.block_bytes);
  // Blocks that need more than the ice: the error is at /blocks and names what sets their size.
  est.block_bytes = 10 * ice_bytes;
  est.bytes = 11 * ice_bytes;
  try {
    hs::sim::check_memory(s, est, 5 * ice_bytes);
    ADD_FAILURE() << "no error";
  } catch (const hs::InputError& e) {
    const std::string m = e.what();
    EXPECT_EQ(e.path(), "/blocks");
    for (const char* field : {"rigid blocks", "/blocks/conversion", "/blocks/keep_x", "/ice/length", "MemAvailable",
                              "--ignore-memory-limit"})
      EXPECT_TRUE(has(m, field)) << field << " in " << m;
  }
}

TEST(InputGuards, AKilometreSheetIsRefusedByCheckBeforeAllocating) {
  // 1000 m x 1000 m, D = 0.2 m: ~1.2e8 particles, under the old fixed count (2e8) that let
  // `check` allocate it all and die of bad_alloc or the OOM killer.
  json j = pier_scene();
  j["material"]["particle_diameter"] = 0.2;
  j["ice"]["thickness"] = 0.6;
  j["ice"]["length"] = 1000;
  j["ice"]["width"] = 1000;
  j["structure"]["position"] = json::array({-8, 0, 0});
  const hs::scene::Scene s = hs::scene::parse_scene(j, "");
  const double need = hs::sim::memory_estimate(s).bytes, avail = hs::sim::available_memory_bytes();
  if (avail < 0 || avail > 0.8 * need) GTEST_SKIP() << "this machine has " << avail / 1e9 << " GB available";
  write("km.json", j.dump());
  const Result r2 = hybridsim("check km.json");
  EXPECT_EQ(r2.rc, 2) << r2.err;
  EXPECT_TRUE(has(r2.err, "error: /ice: the scene needs about")) << r2.err;
  EXPECT_TRUE(has(r2.err, "MemAvailable")) << r2.err;
}

// ---------------------------------------------------------------- defect 5: ridge file values

TEST(InputGuards, ANaNInTheRidgeFileIsExit2ForCheckAndRun) {
  hs::rigid::RidgeResult rr;
  rr.def.name = "nan";
  hs::rigid::RidgeBlock b;
  b.half_extents = hs::Vec3(0.5, 0.5, 0.15);
  b.position = hs::Vec3(2, 0, -1.5);
  rr.blocks.push_back(b);
  b.position = hs::Vec3(2, std::numeric_limits<double>::quiet_NaN(), -1.5);
  rr.blocks.push_back(b);
  rr.profile.x = {0.0};
  rr.profile.keel_target = rr.profile.keel_depth = rr.profile.sail_target = rr.profile.sail_height = {0.0};
  hs::io::save_ridge((work_dir() / "nan_ridge.h5").string(), rr);
  json j = pier_scene();
  j["blocks"] = {{"ridge_file", "nan_ridge.h5"}};
  write("nan_blocks.json", j.dump());
  for (const char* cmd : {"check", "run"}) {
    const Result r = hybridsim(std::string(cmd) + " nan_blocks.json" + (cmd[0] == 'r' ? " -o nan.h5" : ""));
    EXPECT_EQ(r.rc, 2) << cmd << ": " << r.err;
    EXPECT_TRUE(has(r.err, "/ridge/blocks/position row 1 column 1")) << cmd << ": " << r.err;
  }
  // Under MPI every rank reads the file and refuses alike: exit 2, no crash, no output file.
  const Result r = hybridsim_mpi2("run nan_blocks.json -o nan2.h5");
  EXPECT_EQ(r.rc, 2) << r.err;
  EXPECT_TRUE(has(r.err, "/ridge/blocks/position row 1 column 1")) << r.err;
  EXPECT_FALSE(fs::exists(work_dir() / "nan2.h5"));
}

// ---------------------------------------------------------------- defect 6: initial overlap

TEST(InputGuards, AStructureOverlappingTheIceIsReportedByCheckAndRefusedByRun) {
  write("clear.json", pier_scene().dump());
  Result r = hybridsim("check clear.json");
  ASSERT_EQ(r.rc, 0) << r.err;
  const std::string clear_err = r.err;
  // Enclosing: the 14 m cone around the 4 m x 2 m sheet, every centre inside (no surface contact).
  json j = pier_scene();
  j["structure"]["position"] = json::array({2, 0, 0});
  write("enclosed.json", j.dump());
  for (const char* cmd : {"check", "run"}) {
    r = hybridsim(std::string(cmd) + " enclosed.json" + (cmd[0] == 'r' ? " -o enclosed.h5" : ""));
    EXPECT_EQ(r.rc, 2) << cmd << ": " << r.out << r.err;
    EXPECT_TRUE(has(r.err, "error: /structure/position: ")) << r.err;
    EXPECT_TRUE(has(r.err, "with the centre inside")) << r.err;
    EXPECT_TRUE(has(r.err, "Place the structure clear of the sheet")) << r.err;
  }
  EXPECT_FALSE(fs::exists(work_dir() / "enclosed.h5"));
  r = hybridsim_mpi2("run enclosed.json -o enclosed2.h5");
  EXPECT_EQ(r.rc, 2) << r.out << r.err;
  EXPECT_TRUE(has(r.err, "error: /structure/position: ")) << r.err;
  EXPECT_FALSE(fs::exists(work_dir() / "enclosed2.h5"));
  // Partly overlapping: the cone's edge 0.5 m into the sheet.
  j["structure"]["position"] = json::array({-6.5, 0, 0});
  write("overlap.json", j.dump());
  r = hybridsim("check overlap.json");
  EXPECT_EQ(r.rc, 2) << r.out << r.err;
  EXPECT_TRUE(has(r.err, "deepest surface overlap")) << r.err;
  // A shallow overlap (0.15 of the radius, under stability.max_overlap_ratio = 0.5): pushed out
  // at the first steps, so a warning, not an error.
  j["structure"]["position"] = json::array({-8.0, 0, 0});
  write("shallow.json", j.dump());
  r = hybridsim("check shallow.json");
  EXPECT_EQ(r.rc, 0) << r.out << r.err;
  EXPECT_TRUE(has(r.err, "warning: /structure/position: 2 ice particles start overlapping")) << r.err;
  EXPECT_FALSE(has(clear_err, "/structure/position")) << clear_err;
}

// ---------------------------------------------------------------- defect 10: zero gravity

TEST(InputGuards, ZeroGravityWritesNoNonFiniteNumber) {
  json j = pier_scene();
  j["gravity"] = json::array({0, 0, 0});
  write("zero_g.json", j.dump());
  const Result r = hybridsim("zero_g.json -o zero_g.h5");
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_TRUE(has(r.out, "L_c not defined: gravity is zero")) << r.out;
  EXPECT_FALSE(has(r.out, "inf")) << r.out;
  const auto pieces = double_attributes(work_dir() / "zero_g.h5", "/analysis/pieces");
  for (const auto& [name, v] : pieces) {
    EXPECT_TRUE(std::isfinite(v)) << name;
    EXPECT_NE(name, "characteristic_length");
  }
  for (const auto& [name, v] : double_attributes(work_dir() / "zero_g.h5", "/analysis/iso"))
    EXPECT_TRUE(std::isfinite(v)) << name;
}

// ---------------------------------------------------------------- defect 7: the ridge generator

TEST(InputGuards, RidgeBlockEstimateMatchesTheGeneratedRidge) {
  // The small ridge of CliRidge (~1 s): the estimate before generation against the blocks made.
  const json j = json::parse(R"({
      "level_ice_thickness": 0.2, "consolidated_layer_thickness": 0.3, "consolidated_layer_width": 2.0,
      "keel_depth": 2.0, "shoulder_slope_deg": 30, "sail_height": 0.4, "length": 3.0,
      "block_thickness": 0.2, "seed": 11, "settle": {"max_time": 40}})");
  const hs::rigid::RidgeDef def = hs::rigid::ridge_def_from_json(j, "/ridge", "");
  const hs::rigid::RidgeEstimate est = hs::rigid::ridge_estimate(def);
  const hs::rigid::RidgeResult r = hs::rigid::generate_ridge(def);
  // The fill stops at the target volume, so the estimate is off by the sampled block sizes'
  // deviation from their mean (145 blocks: a few per cent of sampling noise) and the last
  // block's overshoot. Measured: 126.8 estimated, 145 made (ratio 0.875).
  const double ratio = est.blocks / static_cast<double>(r.blocks.size());
  EXPECT_NEAR(ratio, 1.0, 0.25) << est.blocks << " estimated, " << r.blocks.size() << " made";
  // Measured: 1.00029 (4000 intervals here, the generator's 2 cm grid there).
  EXPECT_NEAR(est.keel_volume / r.stats.keel_target_volume, 1.0, 0.003);
}

TEST(InputGuards, AHugeRidgeIsRefusedBeforeGeneration) {
  write("huge_ridge.json", R"({"name": "huge", "ridge": {"keel_depth": 8, "length": 1e6}})");
  const Result r = hybridsim("ridge huge_ridge.json -o huge_ridge.h5");
  const double avail = hs::sim::available_memory_bytes();
  if (avail < 0 || avail > 1e12) GTEST_SKIP() << "this machine has " << avail / 1e9 << " GB available";
  EXPECT_EQ(r.rc, 2) << r.err;
  EXPECT_TRUE(has(r.err, "error: /ridge: about")) << r.err;
  EXPECT_TRUE(has(r.err, "/ridge/length")) << r.err;
  EXPECT_TRUE(has(r.err, "--ignore-memory-limit")) << r.err;
  EXPECT_FALSE(fs::exists(work_dir() / "huge_ridge.h5"));
}

// ---------------------------------------------------------------- item 4: run time and output size

TEST(InputGuards, CheckWarnsAboutRunTimeAndOutputSizePastSensibleLimits) {
  write("short.json", pier_scene().dump());
  Result r = hybridsim("check short.json");
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_FALSE(has(r.err, "warning: /time/")) << r.err;
  // 3e5 s at dt = 4.8e-5 s (Eq. 2): 6.3e9 steps of 120 particles, ~3 days on one core; a snapshot every
  // 1e-3 s: 3e8 snapshots, terabytes.
  json j = pier_scene();
  j["time"]["duration"] = 3e5;
  j["time"]["snapshot_interval"] = 1e-3;
  write("long_run.json", j.dump());
  r = hybridsim("check long_run.json");
  EXPECT_EQ(r.rc, 0) << r.err;  // a warning, not an error
  EXPECT_TRUE(has(r.err, "warning: /time/duration: the run is estimated at")) << r.err;
  EXPECT_TRUE(has(r.err, "warning: /time/snapshot_interval: the output file is estimated at")) << r.err;
}
