// Ridge generator: reproducibility, porosity/profile sanity, no overlap after settling,
// block-size sampling, CSV profile errors, JSON validation, HDF5 round trip.
#include "common/error.h"
#include "io/ridge_file.h"
#include "ridge/ridge.h"
#include "ridge/ridge_json.h"
#include "rigid/rigid_world.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <vector>

namespace hs::rigid {
namespace {

// A small ridge (steep 30 deg shoulders, 3 m long, 0.2 m blocks): ~150 blocks, ~1 s.
RidgeDef small_def(std::uint64_t seed = 11) {
  RidgeDef d;
  d.name = "small";
  d.level_ice_thickness = 0.3;
  d.consolidated_layer_thickness = 0.45;
  d.consolidated_layer_width = 2.0;
  d.level_ice_margin = 2.0;
  d.keel_depth = 2.0;
  d.shoulder_slope_deg = 30.0;
  d.sail_height = 0.7;
  d.sail_slope_deg = 30.0;
  d.length = 3.0;
  d.block_thickness = 0.2;
  d.max_tilt_deg = 20.0;  // as the scenes
  d.seed = seed;
  d.settle.max_time = 60.0;
  d.profile_bin = 0.5;
  d.porosity_grid = 0.1;
  return d;
}

const RidgeResult& small_ridge() {
  static const RidgeResult r = generate_ridge(small_def());
  return r;
}

std::vector<double> flatten(const RidgeResult& r) {
  std::vector<double> v;
  for (const RidgeBlock& b : r.blocks) {
    for (int k = 0; k < 3; ++k) v.push_back(b.half_extents[k]);
    for (int k = 0; k < 3; ++k) v.push_back(b.position[k]);
    v.insert(v.end(), {b.orientation.w(), b.orientation.x(), b.orientation.y(), b.orientation.z()});
    v.push_back(b.part);
  }
  for (const RidgeJoint& j : r.joints) {
    v.insert(v.end(), {double(j.a), double(j.b), j.area});
    for (int k = 0; k < 3; ++k) v.push_back(j.anchor[k]), v.push_back(j.normal[k]);
  }
  for (double x : r.profile.keel_depth) v.push_back(x);
  for (double x : r.profile.sail_height) v.push_back(x);
  v.push_back(r.stats.keel_porosity);
  v.push_back(r.stats.core_porosity);
  v.push_back(r.stats.settle_time);
  return v;
}

bool bit_equal(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0;
}

TEST(Ridge, SmallRidgeIsSane) {
  const RidgeResult& r = small_ridge();
  const RidgeStats& s = r.stats;
  std::printf("[ ridge ] %zu keel + %zu sail blocks, %zu joints (%zu to ice), porosity %.3f (core %.3f), "
              "keel depth %.2f of %.2f m, sail %.2f of %.2f m, rms %.2f m, settled %d at %.1f s, "
              "KE/block %.2e J, overlap %.4f m, %.1f s wall\n",
              s.keel_blocks, s.sail_blocks, s.joints, s.ice_joints, s.keel_porosity, s.core_porosity,
              s.keel_depth_achieved, s.keel_depth_target, s.sail_height_achieved, s.sail_height_target,
              s.keel_profile_rms_error, int(s.settled), s.settle_time,
              s.final_kinetic_energy_per_block, s.max_final_overlap, s.wall_time);
  EXPECT_TRUE(s.settled);
  EXPECT_GT(s.keel_blocks, 30u);
  EXPECT_GT(s.sail_blocks, 3u);
  EXPECT_GT(s.joints, s.keel_blocks / 2);
  // A keel only ~10 blocks deep, between end walls 3 m apart, packs loosely (docs/ridge.md).
  // Measured (seed 11): keel 0.516, core 0.471. There is no target to measure a distance from
  // (fill_porosity 0.4 only counts blocks), so the band is the seed-to-seed spread: seeds 1-8 gave
  // keel 0.476-0.530 and core 0.320-0.476 (a throwaway sweep of small_def(1..8)); the bands
  // take about that spread again on each side: a change that moves seed 11 out of them
  // moves the packing beyond what a different seed does.
  EXPECT_GT(s.keel_porosity, 0.43);
  EXPECT_LT(s.keel_porosity, 0.58);
  EXPECT_GT(s.core_porosity, 0.25);
  EXPECT_LT(s.core_porosity, 0.55);
  EXPECT_GT(s.keel_depth_achieved, 0.6 * s.keel_depth_target);
  EXPECT_LT(s.keel_depth_achieved, 1.6 * s.keel_depth_target);
  EXPECT_LT(s.keel_profile_rms_error, 0.5 * s.keel_depth_target);
  EXPECT_GT(s.sail_height_achieved, 0.3);
  // Keel blocks float up against the ice, sail blocks rest on it.
  for (const RidgeBlock& b : r.blocks) {
    if (b.part == 0) EXPECT_LT(b.position.z(), 0.0);
    else EXPECT_GT(b.position.z(), 0.0);
  }
  for (const RidgeJoint& j : r.joints) {
    EXPECT_GT(j.area, 0.0);
    EXPECT_NEAR(j.normal.norm(), 1.0, 1e-9);
  }
}

TEST(Ridge, BlocksDoNotOverlapAfterSettling) {
  const RidgeResult& r = small_ridge();
  double worst = 0.0;
  for (std::size_t i = 0; i < r.blocks.size(); ++i) {
    const RidgeBlock& a = r.blocks[i];
    for (std::size_t k = i + 1; k < r.blocks.size(); ++k) {
      const RidgeBlock& b = r.blocks[k];
      worst = std::max(worst, box_penetration(a.half_extents, a.position, a.orientation, b.half_extents,
                                              b.position, b.orientation));
    }
    for (const IceBox& ice : r.ice)
      worst = std::max(worst, box_penetration(a.half_extents, a.position, a.orientation,
                                              ice.half_extents, ice.position, Quat::Identity()));
  }
  EXPECT_LT(worst, 0.03);  // m: Bullet's resting penetration, << 0.2 m block thickness
}

// settle.max_displacement: the settle phase goes on until no block moved more than that in the
// last second (besides the energy test). Control: the same ridge on the energy test alone stops
// with a block still moving more.
TEST(Ridge, SettleWaitsForTheLargestDisplacementWhenAsked) {
  const RidgeStats& plain = small_ridge().stats;
  RidgeDef d = small_def();
  d.settle.max_displacement = 3e-3;
  d.settle.max_time = 150.0;
  const RidgeStats s = generate_ridge(d).stats;
  std::printf("[ ridge ] energy only: settled %d at %.2f s, largest last-second displacement %.2e m; "
              "with max_displacement %.0e m: settled %d at %.2f s, %.2e m\n",
              int(plain.settled), plain.settle_time, plain.final_max_displacement, d.settle.max_displacement,
              int(s.settled), s.settle_time, s.final_max_displacement);
  EXPECT_TRUE(s.settled);
  EXPECT_LT(s.final_max_displacement, d.settle.max_displacement);
  EXPECT_GT(plain.final_max_displacement, d.settle.max_displacement);  // the control
  EXPECT_GT(s.settle_time, plain.settle_time);
}

TEST(Ridge, SameSeedIdenticalDifferentSeedDifferent) {
  const RidgeResult again = generate_ridge(small_def(11));
  EXPECT_TRUE(bit_equal(flatten(small_ridge()), flatten(again)));
  const RidgeResult other = generate_ridge(small_def(12));
  EXPECT_FALSE(bit_equal(flatten(small_ridge()), flatten(other)));
}

/// The median of `v` (an odd count: the middle value).
double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

constexpr std::uint64_t kSeeds[] = {11, 12, 13, 14, 15};

// Placement only (one rigid step): the greedy deposition with several candidate poses
// fills holes before the pile grows, so the released column is denser than plain
// ballistic deposition (one pose per block) and needs a shorter rise. A statement about
// the generator, not one pile: over 5 seeds, the median porosity gap and keel depth gap,
// and every seed but one denser. Measured (seeds 11-15): porosity 0.828-0.858 with one
// candidate, 0.741-0.752 with 8; gaps 0.076-0.110 (median 0.090), keel 0.67-2.20 m shallower
// (median 1.29 m), 5 of 5 denser. With 8 candidates switched off (1 and 1) every gap is 0.
TEST(Ridge, GreedyPlacementPacksDenserThanBallistic) {
  auto placed = [](int candidates, std::uint64_t seed) {
    RidgeDef d = small_def(seed);
    d.placement_candidates = candidates;
    d.settle.min_time = 0.0;
    d.settle.compaction_time = 0.0;
    d.settle.max_time = d.settle.dt;
    return generate_ridge(d).stats;
  };
  std::vector<double> gap, deeper;
  int denser = 0;
  for (const std::uint64_t seed : kSeeds) {
    const RidgeStats one = placed(1, seed), eight = placed(8, seed);
    std::printf("[ ridge ] seed %llu placed porosity: 1 candidate %.3f (keel %.2f m), 8 candidates %.3f (keel %.2f m)\n",
                static_cast<unsigned long long>(seed), one.keel_porosity, one.keel_depth_achieved,
                eight.keel_porosity, eight.keel_depth_achieved);
    gap.push_back(one.keel_porosity - eight.keel_porosity);
    deeper.push_back(one.keel_depth_achieved - eight.keel_depth_achieved);
    denser += eight.keel_porosity < one.keel_porosity;
  }
  std::printf("[ ridge ] median porosity gap %.3f, median keel depth gap %.2f m, %d of 5 denser\n", median(gap),
              median(deeper), denser);
  EXPECT_GT(median(gap), 0.05);
  EXPECT_GT(median(deeper), 0.3);
  EXPECT_GE(denser, 4);
}

// The compaction phase (keel friction off while the blocks rise) packs the rubble into
// the porosity band of first-year keels, 0.2-0.45 (docs/ridge.md), and denser than a
// rise with full friction; the block count is the same, so the keel gets shallower.
// The small ridge's core is 2 m x 3 m between end walls (about 5 block lengths): walls
// loosen the packing there, so the band is checked on a ridge twice as long and deeper.
// Over 5 seeds: the median core porosity in the band, every seed but one denser with the
// compaction than without. Measured (seeds 11-15): core porosity 0.368-0.415 with the
// compaction (median 0.392), 0.560-0.604 without (median 0.583: the switched-off feature
// misses the band), 5 of 5 denser; keel 1.58-2.00 m against 3.47-3.64 m. ~27 s of CPU (10
// generations).
TEST(Ridge, CompactionPacksIntoKeelPorosityBand) {
  std::vector<double> with_p, no_p;
  int denser = 0;
  for (const std::uint64_t seed : kSeeds) {
    RidgeDef d = small_def(seed);
    d.length = 6.0;
    d.keel_depth = 2.5;
    d.consolidated_layer_width = 3.0;
    const RidgeResult with = generate_ridge(d);
    d.settle.compaction_time = 0.0;
    const RidgeResult no = generate_ridge(d);
    const RidgeStats& c = with.stats;
    std::printf("[ ridge ] seed %llu: %zu keel blocks, settled %d at %.1f s, %.1f + %.1f s wall; core porosity "
                "without compaction %.3f, with %.3f; keel %.2f / %.2f m\n",
                static_cast<unsigned long long>(seed), c.keel_blocks, int(c.settled), c.settle_time, c.wall_time,
                no.stats.wall_time, no.stats.core_porosity, c.core_porosity, no.stats.keel_depth_achieved,
                c.keel_depth_achieved);
    EXPECT_EQ(no.stats.keel_blocks, c.keel_blocks);
    EXPECT_GT(c.compaction_time, 0.0);
    EXPECT_LE(c.compaction_time, small_def().settle.compaction_time + 0.5);  // + one KE check
    with_p.push_back(c.core_porosity);
    no_p.push_back(no.stats.core_porosity);
    denser += c.core_porosity < no.stats.core_porosity;
  }
  std::printf("[ ridge ] median core porosity without compaction %.3f, with %.3f; %d of 5 denser\n", median(no_p),
              median(with_p), denser);
  EXPECT_LT(median(with_p), median(no_p));
  EXPECT_GE(denser, 4);
  EXPECT_GT(median(with_p), 0.2);
  EXPECT_LT(median(with_p), 0.45);
}

TEST(Ridge, SaveLoadRoundTripBitExact) {
  const RidgeResult& r = small_ridge();
  const std::string path =
      (std::filesystem::temp_directory_path() / ("hs_ridge_" + std::to_string(::getpid()) + ".h5")).string();
  io::save_ridge(path, r);
  const RidgeResult l = io::load_ridge(path);
  std::filesystem::remove(path);
  EXPECT_TRUE(bit_equal(flatten(r), flatten(l)));
  ASSERT_EQ(l.ice.size(), r.ice.size());
  for (std::size_t i = 0; i < r.ice.size(); ++i) {
    EXPECT_EQ(l.ice[i].half_extents, r.ice[i].half_extents);
    EXPECT_EQ(l.ice[i].position, r.ice[i].position);
    EXPECT_EQ(l.ice[i].part, r.ice[i].part);
  }
  EXPECT_EQ(ridge_def_to_json(l.def), ridge_def_to_json(r.def));
  EXPECT_EQ(ridge_report(l).dump(), ridge_report(r).dump());
  EXPECT_TRUE(bit_equal(l.profile.x, r.profile.x));
  EXPECT_TRUE(bit_equal(l.profile.keel_target, r.profile.keel_target));
  EXPECT_TRUE(bit_equal(l.profile.sail_target, r.profile.sail_target));
  EXPECT_THROW(io::load_ridge(path), InputError);
}

TEST(Ridge, LognormalAspectMatchesRequest) {
  const std::size_t n = 10000;
  AspectLognormal a;  // ln(L/h) ~ N(1.06, 0.5)
  const std::vector<double> s = sample_log_aspect(a, n, 5);
  double m = 0.0, v = 0.0;
  for (double x : s) m += x;
  m /= n;
  for (double x : s) v += (x - m) * (x - m);
  const double sd = std::sqrt(v / (n - 1));
  // Standard errors: 0.5/sqrt(n) = 0.005 for the mean, 0.5/sqrt(2n) = 0.0035 for the sd.
  EXPECT_NEAR(m, 1.06, 4 * 0.005);
  EXPECT_NEAR(sd, 0.5, 4 * 0.0035);
  std::vector<double> sorted = s;
  std::sort(sorted.begin(), sorted.end());
  EXPECT_NEAR(std::exp(sorted[n / 2]), std::exp(1.06), 0.1);  // median L/h ~ 2.89

  AspectLognormal r;  // L/h itself has mean 1.06, sd 0.5
  r.of_log = false;
  const std::vector<double> t = sample_log_aspect(r, n, 6);
  double rm = 0.0, rv = 0.0;
  for (double x : t) rm += std::exp(x);
  rm /= n;
  for (double x : t) rv += (std::exp(x) - rm) * (std::exp(x) - rm);
  EXPECT_NEAR(rm, 1.06, 4 * 0.5 / std::sqrt(double(n)));
  EXPECT_NEAR(std::sqrt(rv / (n - 1)), 0.5, 0.03);  // skewed: looser than the normal rule
}

std::string write_tmp(const std::string& name, const std::string& text) {
  const std::string p = (std::filesystem::temp_directory_path() / name).string();
  std::ofstream(p) << text;
  return p;
}

TEST(Ridge, CsvProfile) {
  const std::string good = write_tmp("hs_ridge_good.csv", "position_m,depth_m\n# measured\n-20, 0.5\n0,6\n20,0.5\n");
  const auto pts = load_profile_csv(good);
  ASSERT_EQ(pts.size(), 3u);
  RidgeDef d;
  d.keel_profile = pts;
  EXPECT_DOUBLE_EQ(keel_target_depth(d, 0.0), 6.0);
  EXPECT_DOUBLE_EQ(keel_target_depth(d, -10.0), 3.25);
  EXPECT_DOUBLE_EQ(keel_target_depth(d, 25.0), 0.0);

  const std::string bad = write_tmp("hs_ridge_bad.csv", "position_m,depth_m\n-20,0.5\n0,six\n20,0.5\n");
  try {
    load_profile_csv(bad);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.path(), bad);
    EXPECT_NE(std::string(e.what()).find("line 3"), std::string::npos) << e.what();
  }
  const std::string unsorted = write_tmp("hs_ridge_unsorted.csv", "0,1\n5,2\n4,2\n");
  try {
    load_profile_csv(unsorted);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("line 3"), std::string::npos) << e.what();
  }
  // Through JSON: a relative path resolves against base_dir; the points are kept.
  const auto tmp = std::filesystem::temp_directory_path().string();
  const RidgeDef j = ridge_def_from_json({{"keel_profile_csv", "hs_ridge_good.csv"}}, "/ridge", tmp);
  EXPECT_EQ(j.keel_profile.size(), 3u);
  EXPECT_THROW(ridge_def_from_json({{"keel_profile_csv", "hs_ridge_bad.csv"}}, "/ridge", tmp), InputError);
  std::filesystem::remove(good);
  std::filesystem::remove(bad);
  std::filesystem::remove(unsorted);
}

TEST(Ridge, JsonValidation) {
  const RidgeDef d = ridge_def_from_json(nlohmann::json::object(), "/ridge");
  EXPECT_DOUBLE_EQ(d.keel_depth, 7.9);
  EXPECT_DOUBLE_EQ(d.sail_height, 7.9 / 4.4);
  EXPECT_DOUBLE_EQ(d.block_thickness, 0.6);
  const RidgeDef e = ridge_def_from_json({{"keel_depth", 4.4}, {"level_ice_thickness", 0.5},
                                          {"aspect_lognormal", {{"mu", 1.06}, {"sigma", 0.5}, {"of", "ratio"}}}},
                                         "/ridge");
  EXPECT_DOUBLE_EQ(e.sail_height, 1.0);
  EXPECT_DOUBLE_EQ(e.block_thickness, 0.5);
  EXPECT_FALSE(e.aspect.of_log);
  auto path_of = [](const nlohmann::json& j) {
    try {
      ridge_def_from_json(j, "/ridge");
    } catch (const InputError& e) {
      return e.path() + " | " + e.what();
    }
    return std::string("no error");
  };
  EXPECT_NE(path_of({{"keel_dept", 5}}).find("/ridge/keel_dept | "), std::string::npos);
  EXPECT_NE(path_of({{"keel_dept", 5}}).find("did you mean \"keel_depth\""), std::string::npos);
  EXPECT_NE(path_of({{"settle", {{"max_tme", 5}}}}).find("/ridge/settle/max_tme"), std::string::npos);
  EXPECT_NE(path_of({{"keel_depth", "deep"}}).find("/ridge/keel_depth | "), std::string::npos);
  EXPECT_NE(path_of({{"keel_width", 30}}).find("/ridge/keel_width | "), std::string::npos);
  EXPECT_NE(path_of({{"aspect_lognormal", {{"of", "linear"}}}}).find("/ridge/aspect_lognormal/of"),
            std::string::npos);
  EXPECT_NE(path_of({{"seed", -1}}).find("/ridge/seed"), std::string::npos);
  EXPECT_NE(path_of({{"settle", {{"dt", 0.5}}}}).find("/ridge/settle/dt"), std::string::npos);
  // The shared reader's messages: the value and its unit; null means "not given".
  EXPECT_NE(path_of({{"keel_depth", "deep"}}).find("expected a number in m, got string \"deep\""), std::string::npos)
      << path_of({{"keel_depth", "deep"}});
  EXPECT_NE(path_of({{"seed", 1.5}}).find("/ridge/seed | /ridge/seed: expected a whole number"), std::string::npos);
  EXPECT_EQ(ridge_def_from_json({{"keel_width", nullptr}, {"sail_width", nullptr}}, "/ridge").keel_width, -1.0);
  EXPECT_EQ(ridge_def_from_json({{"seed", 18446744073709551615ULL}}, "/ridge").seed, 18446744073709551615ULL);
  EXPECT_EQ(ridge_def_from_json({{"placement_candidates", 4.0}}, "/ridge").placement_candidates, 4);
  // Full round trip through JSON.
  const RidgeDef s = small_def();
  EXPECT_EQ(ridge_def_to_json(ridge_def_from_json(ridge_def_to_json(s), "/ridge")), ridge_def_to_json(s));
}

}  // namespace
}  // namespace hs::rigid

// Manual driver (not run by ctest): builds the ridge of a scene file and saves it.
//   HS_RIDGE_SCENE=scenes/ridge_keel_8m.json HS_RIDGE_OUT=ridge.h5 (one line)
//     test_rigid --gtest_also_run_disabled_tests --gtest_filter=RidgeManual.*
namespace hs::rigid {
namespace {
TEST(RidgeManual, DISABLED_BuildScene) {
  const char* scene = std::getenv("HS_RIDGE_SCENE");
  const char* out = std::getenv("HS_RIDGE_OUT");
  ASSERT_NE(scene, nullptr) << "set HS_RIDGE_SCENE";
  std::ifstream in(scene);
  ASSERT_TRUE(in) << scene;
  const nlohmann::json j = nlohmann::json::parse(in);
  RidgeDef d = ridge_def_from_json(j.at("ridge"), "/ridge",
                                   std::filesystem::path(scene).parent_path().string());
  if (j.contains("name") && d.name.empty()) d.name = j["name"].get<std::string>();
  double last = -1e9;
  const RidgeResult r = generate_ridge(d, [&](const RidgeProgress& p) {
    if (std::string(p.phase) == "settle" && p.time - last < 2.0) return;
    last = p.time;
    std::fprintf(stderr, "[ridge] %-7s t=%6.2f s  KE/block=%.3e J  blocks=%zu\n", p.phase, p.time,
                 p.kinetic_energy_per_block, p.blocks);
  });
  std::printf("%s\n", ridge_report(r).dump(2).c_str());
  if (out) io::save_ridge(out, r);
}
}  // namespace
}  // namespace hs::rigid

// ---------------------------------------------------------------- floating plates (issue 15)
namespace hs::rigid {
namespace {

/// small_def under floating plates: a sheet of contact surfaces as a particle sheet of D = 0.1 m
/// would have (level ice 0.245 m between its contact surfaces, the layer 0.408 m); numbers, not
/// the run's sheet function (tests/app checks that one).
RidgeDef plated_def() {
  RidgeDef d = small_def();
  d.ice_density = 920.0;
  d.settle.friction = 0.3;
  d.sheet.floating = true;
  d.sheet.level_top = 0.03, d.sheet.level_underside = -0.215;
  d.sheet.layer_top = 0.03, d.sheet.layer_underside = -0.378;
  d.sheet.particle_diameter = 0.1;
  d.sheet.layer_width = d.consolidated_layer_width + 0.1;  // its spheres reach D/2 beyond the band
  // No sail: a sail on the 2 m wide, 3 cm freeboard layer plate would push it under (a plate
  // under water carries no more), and this test is about the balance of floating plates.
  d.sail_height = 0.0;
  return d;
}

const RidgeResult& plated_ridge() {
  static const RidgeResult r = generate_ridge(plated_def());
  return r;
}

}  // namespace

TEST(RidgePlates, AFreePlateFloatsWithItsContactSurfacesWhereTheyAre) {
  // One plate, no blocks: plate_density makes it weigh what the water under its underside
  // carries, so it stays at the sheet's rest geometry. Dropped 5 cm high it comes back there.
  const double top = 0.03, under = -0.215, rho_w = 1025.0;
  const double rho = plate_density(top, under, rho_w);
  EXPECT_NEAR(rho, rho_w * 0.215 / 0.245, 1e-12);  // analytic: draft / thickness = rho / rho_w
  RigidWorldDef wd;
  wd.dt = 1.0 / 60.0;
  RigidWorld w(wd);
  BlockDef b;
  b.half_extents = Vec3(2.0, 1.5, 0.5 * (top - under));
  b.position = Vec3(0, 0, 0.5 * (top + under) + 0.05);
  b.density = rho;
  b.linear_factor = Vec3::UnitZ();
  b.angular_factor = Vec3::Zero();
  const BlockId id = w.add_block(b);
  w.add_force(id, Vec3(300.0, 200.0, 0.0), Vec3(1.0, 0.0, 0.0));  // a push it must not follow sideways
  w.step(20.0);
  // Heave damping ratio ~0.3 (linear drag): after 20 s the 5 cm drop has died away.
  const Vec3 x = w.position(id);
  std::printf("[ plate ] rest error %.3e m\n", x.z() - 0.5 * (top + under));
  EXPECT_NEAR(x.z(), 0.5 * (top + under), 1e-12);  // measured 1e-16 m
  EXPECT_EQ(x.x(), 0.0);
  EXPECT_EQ(x.y(), 0.0);
  EXPECT_TRUE(w.orientation(id).isApprox(Quat::Identity(), 1e-12));
}

TEST(RidgePlates, ASmallRidgeUnderPlatesEndsInVerticalBalanceWithThePlatesLiftedByIt) {
  const RidgeResult& r = plated_ridge();
  const RidgeStats& s = r.stats;
  std::printf("[ plates ] %zu blocks, block net buoyancy %.1f N, plates %.1f N, keel depth %.2f of %.2f m, "
              "settled %d at %.1f s\n",
              r.blocks.size(), s.block_net_buoyancy, s.plate_net_buoyancy, s.keel_depth_achieved,
              s.keel_depth_target, int(s.settled), s.settle_time);
  ASSERT_TRUE(s.settled);
  ASSERT_EQ(r.ice.size(), 3u);  // level ice | consolidated layer | level ice
  // Sum of (buoyancy - weight) over blocks and plates: the keel's net buoyancy is carried by the
  // plates. Measured 1.8 % of the blocks' net buoyancy (171 of 9671 N: the pile still settling a
  // little; 1.0 % with free plates); fixed ice (floating = false) leaves the plates' share at 0: the sum is the whole 100 %.
  EXPECT_GT(s.block_net_buoyancy, 1000.0);
  EXPECT_LT(std::abs(s.block_net_buoyancy + s.plate_net_buoyancy), 0.1 * s.block_net_buoyancy);
  // Each plate rose by its net load / (rho_w g A): summed over the plates, rho_w g A_k lift_k is
  // what the blocks press up with (their net buoyancy), as long as no plate emerged or sank.
  double lifted = 0.0;
  for (const IceBox& p : r.ice) {
    EXPECT_LT(p.position.z() + p.half_extents.z(), p.position.z() + p.half_extents.z() - p.lift + 1.0);
    lifted += 1025.0 * 9.81 * 4.0 * p.half_extents.x() * p.half_extents.y() * p.lift;
  }
  std::printf("[ plates ] sum rho_w g A lift = %.1f N\n", lifted);
  EXPECT_NEAR(lifted, s.block_net_buoyancy, 0.1 * s.block_net_buoyancy);  // measured 1.8 %
  // Joined (the default), the plates heave as one: each by the net buoyancy over the whole area.
  double area = 0.0;
  for (const IceBox& p : r.ice) area += 4.0 * p.half_extents.x() * p.half_extents.y();
  const double predicted = s.block_net_buoyancy / (1025.0 * 9.81 * area);
  for (const IceBox& p : r.ice) {
    std::printf("[ plates ] lift %.5f m, predicted %.5f m\n", p.lift, predicted);
    EXPECT_NEAR(p.lift, predicted, 0.1 * predicted);  // measured 1.3-1.9 % (the balance's 1.8 %)
  }
  // The plates' x ranges tile the sheet and the middle one is the consolidated layer.
  EXPECT_EQ(r.ice[1].part, 1);
  EXPECT_NEAR(2.0 * r.ice[1].half_extents.x(), r.def.sheet.layer_width, 2e-3);
}

TEST(RidgePlates, FixedIceCarriesTheKeelWithoutMoving) {
  // The switch-off of the two tests above: the same ridge under fixed boxes. Its plates' share
  // is 0 and nothing is lifted, so the balance of the test above would fail by 100 %.
  RidgeDef d = plated_def();
  d.sheet.floating = false;
  const RidgeResult r = generate_ridge(d);
  EXPECT_EQ(r.stats.plate_net_buoyancy, 0.0);
  for (const IceBox& p : r.ice) EXPECT_EQ(p.lift, 0.0);
  EXPECT_GT(std::abs(r.stats.block_net_buoyancy), 1000.0);
}

TEST(RidgePlates, FreePlatesHeaveEachByItsOwnLoad) {
  // plates_joined = false: each plate carries what presses on it. The balance holds as a whole;
  // the layer plate, under the keel's deepest part, rises most.
  RidgeDef d = plated_def();
  d.sheet.plates_joined = false;
  const RidgeResult r = generate_ridge(d);
  const RidgeStats& s = r.stats;
  ASSERT_TRUE(s.settled);
  EXPECT_LT(std::abs(s.block_net_buoyancy + s.plate_net_buoyancy), 0.1 * s.block_net_buoyancy);  // measured 1.0 %
  std::printf("[ free plates ] lifts %.4f %.4f %.4f m, balance %.1f of %.1f N\n", r.ice[0].lift, r.ice[1].lift,
              r.ice[2].lift, s.block_net_buoyancy + s.plate_net_buoyancy, s.block_net_buoyancy);
  EXPECT_GT(r.ice[1].lift, 2.0 * std::max(r.ice[0].lift, r.ice[2].lift));
}

TEST(RidgePlates, GenerationRecordRoundTrips) {
  const RidgeResult& r = plated_ridge();
  const std::string path =
      (std::filesystem::temp_directory_path() / ("hs_plated_" + std::to_string(::getpid()) + ".h5")).string();
  io::save_ridge(path, r);
  const RidgeResult b = io::load_ridge(path);
  std::filesystem::remove(path);
  EXPECT_EQ(nlohmann::json::parse(b.generation), ridge_generation_json(r));
  EXPECT_EQ(ridge_generation_json(b), ridge_generation_json(r));
  EXPECT_TRUE(b.def.sheet.floating);
  EXPECT_EQ(b.def.sheet.level_top, r.def.sheet.level_top);
  EXPECT_EQ(b.def.sheet.layer_underside, r.def.sheet.layer_underside);
  EXPECT_EQ(b.def.ice_density, 920.0);
  EXPECT_EQ(b.def.settle.friction, 0.3);
  ASSERT_EQ(b.ice.size(), r.ice.size());
  for (std::size_t k = 0; k < r.ice.size(); ++k) {
    EXPECT_EQ(b.ice[k].lift, r.ice[k].lift);
    EXPECT_EQ(b.ice[k].position, r.ice[k].position);
  }
  EXPECT_EQ(b.stats.block_net_buoyancy, r.stats.block_net_buoyancy);
  const nlohmann::json g = nlohmann::json::parse(b.generation);
  EXPECT_EQ(g.at("sheet").at("kind"), "floating");
  EXPECT_EQ(g.at("sheet").at("plates_joined"), true);
  EXPECT_TRUE(b.def.sheet.plates_joined);
  EXPECT_EQ(g.at("plates").size(), 3u);
  EXPECT_EQ(g.at("plates")[1].at("lift").get<double>(), r.ice[1].lift);
}

// resettle_ridge (bench hybrid's ridge at rest): a 1 x 1 x 0.6 m block fully submerged under a
// 2 x 2 m floating plate (heave only) pushes it up until the plate's extra buoyancy carries the
// block's: lift = (rho_w - rho_i) V / (rho_w A) = 115 x 0.6 / (1025 x 4) = 16.8 mm. A block outside
// the region keeps its pose to the bit; a left-out block goes with its joints; a joint's anchor
// moves with its first block; a joint to the ice is taken to the plate.
TEST(Ridge, ResettleLiftsAFloatingPlateByTheBuoyancyUnderItAndHoldsTheRest) {
  RidgeResult in;
  in.def.ice_density = 910.0;
  in.def.water_density = 1025.0;
  RidgeBlock under;
  under.half_extents = Vec3(0.5, 0.5, 0.3);
  under.position = Vec3(0.0, 0.0, -0.5 - 0.3);  // touching the plate's underside (-0.5)
  RidgeBlock held = under;
  held.position = Vec3(20.0, 0.0, -3.0);
  RidgeBlock dropped = under;
  dropped.position = Vec3(-20.0, 0.0, -3.0);
  in.blocks = {under, dropped, held};
  in.joints = {{0, 1, Vec3(-10, 0, -1), Vec3::UnitX(), 0.1},
               {0, 2, Vec3(10, 0, -1), Vec3::UnitX(), 0.1},
               {0, -1, Vec3(0, 0, -0.5), Vec3::UnitZ(), 0.5}};
  RidgeResettleDef rd;
  IceBox plate;
  plate.half_extents = Vec3(1.0, 1.0, 0.3);
  plate.position = Vec3(0.0, 0.0, -0.2);  // contact surfaces -0.5 .. 0.1
  rd.plates = {plate};
  rd.keep = {1, 0, 1};
  rd.region_lo = Vec3(-5, -5, -10);
  rd.region_hi = Vec3(5, 5, 10);
  rd.phases = {{1.0 / 30.0, 20.0, 20, 5.0}, {1.0 / 240.0, 2.0, 20, 5.0}};
  RidgeResettleStats st;
  const RidgeResult out = resettle_ridge(in, rd, &st);
  const double expected = (1025.0 - 910.0) * 0.6 / (1025.0 * 4.0);
  ASSERT_EQ(out.ice.size(), 1u);
  EXPECT_NEAR(out.ice[0].lift / expected, 1.0, 2e-4);  // measured -1.1e-5 (a plate that does not float: -1)
  EXPECT_TRUE(out.def.sheet.floating);
  ASSERT_EQ(out.blocks.size(), 2u);
  const double rose = out.blocks[0].position.z() - under.position.z();
  EXPECT_NEAR(rose, out.ice[0].lift, 1e-10);  // rose with it; measured 1.2e-12 m
  EXPECT_EQ(out.blocks[1].position, held.position);  // held: to the bit
  EXPECT_EQ(st.dropped_blocks, 1u);
  EXPECT_EQ(st.dropped_joints, 1u);
  ASSERT_EQ(out.joints.size(), 2u);
  EXPECT_EQ(out.joints[0].b, 1);  // renumbered past the left-out block
  const Vec3 moved = out.blocks[0].position - under.position;
  EXPECT_LT((out.joints[0].anchor - (Vec3(10, 0, -1) + moved)).norm(), 2e-8);  // m; measured 2.2e-9 (a tilt of ~1e-10 rad)
  EXPECT_EQ(out.joints[1].b, -1);
  EXPECT_EQ(out.stats.ice_joints, 1u);
  std::printf("[ ridge ] resettle: plate lift %.6f m (%.6f m expected, relative %.1e), block rose %.6f m (lift - rise %.1e m), KE %.2e J\n",
              out.ice[0].lift, expected, out.ice[0].lift / expected - 1.0, moved.z(), out.ice[0].lift - rose, st.final_kinetic_energy_per_block);
}

}  // namespace hs::rigid
