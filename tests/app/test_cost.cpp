// The run's cost breakdown (/analysis/cost, docs/output.md): the phases add up to the run's wall
// time, none is negative, a scene without blocks spends nothing in the rigid world or the bridge,
// and a restarted run's figures cover the run before its checkpoint too. No assertion on speed.
#include <gtest/gtest.h>
#include "cli_fixtures.h"
#include "h5_read.h"
#include "sim/cost.h"

#include <array>
#include <cmath>
#include <cstring>
#include <string>

namespace fs = std::filesystem;

namespace {

using hs::testing::read_doubles;

fs::path work_dir() { return hs::testing::cli_work_dir("cost"); }
hs::testing::CliResult hybridsim(const std::string& args, const std::string& prefix = "") {
  return hs::testing::run_hybridsim(work_dir(), args, prefix);
}

const std::string kPinnedScene = HYBRIDSIM_SOURCE_DIR "/tests/app/pinned_run.json";  // ice, pier, 2 blocks
const std::string kNoBlocksScene = HYBRIDSIM_SOURCE_DIR "/scenes/demo_bonded_ice.json";

constexpr std::array<const char*, 17> kPhases = {
    "read",          "calibration",     "build",         "relax_rigid",   "relax_jointed", "relax_lattice",
    "freeze",        "particle_forces", "particle_other", "rigid_world",  "bridge_coupling", "bridge_stress",
    "bridge_policy", "bridge_conversion", "output",      "mpi_wait",      "analysis"};

double scalar(const fs::path& file, const std::string& name) {
  const auto v = read_doubles(file, "/analysis/cost/" + name);
  EXPECT_EQ(v.size(), 1u) << file << ": /analysis/cost/" << name;
  return v.empty() ? NAN : v[0];
}

/// Every phase >= 0 and their sum within the tolerance of /analysis/cost/wall; returns the sum.
double expect_phases_add_up(const fs::path& file) {
  double sum = 0.0;
  for (const char* p : kPhases) {
    const double s = scalar(file, p);
    EXPECT_GE(s, 0.0) << file << ": " << p;
    sum += s;
  }
  const double wall = scalar(file, "wall");
  EXPECT_GT(wall, 0.0);
  // The gaps between the timed phases (warnings printed, the loop's bookkeeping): measured
  // 0.1-0.4 % of the wall on these runs (0.5-2 ms); 3 % allows for a run descheduled between two
  // phases on a shared machine.
  EXPECT_NEAR(sum, wall, 0.03 * wall) << file << ": the phases add up to " << sum << " s of " << wall << " s";
  EXPECT_LE(sum, wall * (1.0 + 1e-9)) << "the phases are parts of the wall time";
  return sum;
}

}  // namespace

TEST(Cost, PhasesAddUpToTheWallTime) {
  const auto r = hybridsim("run '" + kPinnedScene + "' -o p.h5");
  ASSERT_EQ(r.rc, 0) << r.err;
  const fs::path f = work_dir() / "p.h5";
  expect_phases_add_up(f);
  // The step's parts ran: particles, the rigid world (2 blocks), the bridge.
  EXPECT_GT(scalar(f, "particle_forces"), 0.0);
  EXPECT_GT(scalar(f, "rigid_world"), 0.0);
  EXPECT_GT(scalar(f, "bridge_coupling"), 0.0);
  EXPECT_GT(scalar(f, "output"), 0.0);
  EXPECT_EQ(scalar(f, "mpi_wait"), 0.0) << "a serial run waits for no rank";
  EXPECT_EQ(scalar(f, "ranks"), 1.0);
  EXPECT_EQ(scalar(f, "processes"), 1.0);
  const auto steps = read_doubles(f, "/series/step");
  ASSERT_FALSE(steps.empty());
  EXPECT_EQ(scalar(f, "steps"), steps.back());
  // 804 particles throughout (no conversion in this run): particle-steps = 804 x steps.
  EXPECT_EQ(scalar(f, "particle_steps"), 804.0 * steps.back());
  EXPECT_NE(r.out.find("  cost (wall time, s, and share of the run's"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("    per step: particles "), std::string::npos) << r.out;
}

TEST(Cost, WithoutBlocksNoRigidOrBridgeTime) {
  const auto r = hybridsim("run '" + kNoBlocksScene + "' -o nb.h5 --set time.duration=0.02");
  ASSERT_EQ(r.rc, 0) << r.err;
  const fs::path f = work_dir() / "nb.h5";
  expect_phases_add_up(f);
  for (const char* p : {"rigid_world", "bridge_coupling", "bridge_stress", "bridge_policy", "bridge_conversion",
                        "relax_rigid", "relax_jointed", "relax_lattice", "freeze"})
    EXPECT_EQ(scalar(f, p), 0.0) << p;
  EXPECT_EQ(scalar(f, "rigid_steps"), 0.0);
  EXPECT_GT(scalar(f, "particle_forces"), 0.0);
}

// check's estimate, by its formula: all_at_start steps the sheet and the blocks' particles and no
// block in the run; its relaxation is the rigid stages (sheet + blocks) and then the lattice stage
// (sheet + blocks' particles).
TEST(Cost, EstimateOfAllAtStartStepsTheConvertedParticlesAndNoBlock) {
  hs::sim::CostInputs in;
  in.particles = 1000;
  in.steps = 100;
  in.dt = 1e-3;
  in.movable_blocks = 10;
  in.rigid_dt = 4e-3;
  in.solver_iterations = 20;
  in.relax_time = 0.5;
  hs::sim::CostRates r;
  r.particle_step = 1e-6;
  r.block_iteration = 1e-7;
  r.output_share = 0.0;
  const hs::sim::CostEstimate hybrid = hs::sim::estimate_cost(in, r);
  EXPECT_NEAR(hybrid.particles, 1000 * 100 * 1e-6, 1e-15);
  EXPECT_NEAR(hybrid.rigid, 25 * 10 * 20 * 1e-7, 1e-15);  // floor(100 x 1e-3 / 4e-3) = 25 rigid steps
  EXPECT_NEAR(hybrid.relax_particles, 1000 * 500 * 1e-6, 1e-15);
  EXPECT_NEAR(hybrid.relax_rigid, 125 * 10 * 20 * 1e-7, 1e-15);
  in.converted_particles = 500;
  in.relax_lattice_time = 0.2;
  const hs::sim::CostEstimate all = hs::sim::estimate_cost(in, r);
  EXPECT_NEAR(all.particles, 1500 * 100 * 1e-6, 1e-15);
  EXPECT_EQ(all.rigid, 0.0);
  EXPECT_NEAR(all.relax_particles, (1000 * 500 + 1500 * 200) * 1e-6, 1e-15);
  EXPECT_NEAR(all.relax_rigid, hybrid.relax_rigid, 1e-15);
  EXPECT_EQ(all.relax_steps, 700.0);
}

// `check` counts the blocks as the particles all_at_start makes of them, and no rigid world in the run.
TEST(Cost, CheckCountsAllAtStartsParticlesAndNoRigidWorldInTheRun) {
  const auto h = hybridsim("check '" + kPinnedScene + "'");
  ASSERT_EQ(h.rc, 0) << h.err;
  EXPECT_NE(h.out.find("; rigid world "), std::string::npos) << h.out;
  EXPECT_EQ(h.out.find("particles included"), std::string::npos) << h.out;
  const auto a = hybridsim("check '" + kPinnedScene + "' --set blocks.conversion=all_at_start");
  ASSERT_EQ(a.rc, 0) << a.err;
  // The two blocks: 0.8 x 0.6 x 0.3 + 1.0 x 0.5 x 0.4 = 0.344 m^3 over D^3 / sqrt 2 (D = 0.25 m) = 31.1.
  EXPECT_NE(a.out.find("the blocks' ~31.1 particles included"), std::string::npos) << a.out;
  EXPECT_EQ(a.out.find("; rigid world "), std::string::npos) << a.out;
}

// A run checkpointed half way and restarted from there: the restarted file counts both processes
// (its particle-steps equal those of the run that went straight through, exactly) and its wall
// time is at least what the first process had spent when it wrote the checkpoint.
TEST(Cost, RestartAccumulatesThroughTheCheckpoint) {
  const std::string ck = " --set time.checkpoint_interval=0.05";
  const auto a = hybridsim("run '" + kPinnedScene + "' -o a.h5" + ck);
  ASSERT_EQ(a.rc, 0) << a.err;
  // The checkpoint entry is the bytes of three doubles: particle-steps, wall time, processes.
  const auto bytes = read_doubles(work_dir() / "a.ckpt.h5", "/checkpoint/rank_0/cost/figures");
  ASSERT_EQ(bytes.size(), 3 * sizeof(double)) << "the cost figures in the checkpoint";
  std::array<unsigned char, 3 * sizeof(double)> raw{};
  for (std::size_t i = 0; i < raw.size(); ++i) raw[i] = static_cast<unsigned char>(bytes[i]);
  double saved[3];
  std::memcpy(saved, raw.data(), sizeof saved);
  const auto b = hybridsim("run '" + kPinnedScene + "' --restart a.h5 -o b.h5" + ck);
  ASSERT_EQ(b.rc, 0) << b.err;
  const fs::path fa = work_dir() / "a.h5", fb = work_dir() / "b.h5";
  expect_phases_add_up(fb);
  EXPECT_EQ(scalar(fb, "processes"), 2.0);
  EXPECT_EQ(scalar(fb, "particle_steps"), scalar(fa, "particle_steps"));
  EXPECT_EQ(scalar(fb, "steps"), scalar(fa, "steps"));
  EXPECT_GE(scalar(fb, "wall"), saved[1]);
  EXPECT_GT(saved[0], 0.0);
  EXPECT_LT(saved[0], scalar(fa, "particle_steps"));
  // Both processes read the scene and built the simulation.
  EXPECT_GT(scalar(fb, "build"), 0.0);
  EXPECT_NE(b.out.find("2 processes (restarts) together"), std::string::npos) << b.out;
}
