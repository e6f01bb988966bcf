// `hybridsim study` end to end through the binary (docs/study.md): a 2-variant x 2-seed study of a
// 0.1 s scene (804 particles, ~0.3 s a member) runs, resumes a member stopped by SIGTERM from its
// checkpoint to the series and per-step load of an uninterrupted run bit for bit, writes the documented tables, and
// a second invocation runs nothing. Bad study files are refused with exit 2.
#include <gtest/gtest.h>

#include "cli_fixtures.h"
#include "h5_read.h"

#include <sys/stat.h>

#include <string>
#include <vector>

namespace fs = std::filesystem;
using hs::testing::expect_same_series;
using hs::testing::slurp;

namespace {

fs::path work_dir() { return hs::testing::cli_work_dir("study"); }
hs::testing::CliResult hybridsim(const std::string& args, const std::string& prefix = "") {
  return hs::testing::run_hybridsim(work_dir(), args, prefix);
}
void write(const std::string& name, const std::string& text) { std::ofstream(work_dir() / name) << text; }

void write_scene() {
  write("tiny.json", R"({
    "name": "tiny",
    "time": {"duration": 0.1, "output_interval": 0.004},
    "material": {"particle_diameter": 0.25, "youngs_modulus": 1e7},
    "bonds": {"tensile_strength": 1e5, "shear_strength": 1e5},
    "water": {"linear_drag_per_area": 1000},
    "ice": {"thickness": 0.75, "length": 3, "width": 4, "origin": [0, -2]},
    "walls": [{"name": "far_end", "point": [3, 0, 0], "normal": [-1, 0, 0]}],
    "structure": {
      "pier": {"waterline_diameter": 2.0, "cone_top_z": 0.5, "cone_bottom_z": -1.0, "neck_height": 0.5,
               "shaft_diameter": 1.5, "shaft_bottom_z": -3.0, "segments": 32},
      "position": [-1.5, 0, 0], "velocity": [1.0, 0, 0]}
  })");
}

/// Modification time in nanoseconds.
long long mtime_ns(const fs::path& p) {
  struct stat st {};
  if (::stat(p.c_str(), &st) != 0) return -1;
  return static_cast<long long>(st.st_mtim.tv_sec) * 1000000000LL + st.st_mtim.tv_nsec;
}

int count(const std::string& s, const std::string& what) {
  int n = 0;
  for (std::size_t p = s.find(what); p != std::string::npos; p = s.find(what, p + 1)) ++n;
  return n;
}

}  // namespace

TEST(StudyRun, RunsResumesAStoppedMemberBitIdenticallyAndRunsNothingTheSecondTime) {
  write_scene();
  write("smoke.json", R"({"base": "tiny.json", "seeds": 2, "reference": "v1.0",
                          "variants": {"v1.0": [], "v1.2": ["structure.velocity=[1.2,0,0]"]}})");
  // The uninterrupted run of member v1.0/seed1, and the member itself stopped by SIGTERM after a
  // step 3/8 of the way through (HYBRIDSIM_TEST_SIGNAL), run by hand as the study would run it.
  const auto n = hybridsim("run tiny.json -o straight.h5 --set seed=1");
  ASSERT_EQ(n.rc, 0) << n.err;
  const auto steps = hs::testing::read_doubles(work_dir() / "straight.h5", "/series/step");
  ASSERT_GE(steps.size(), 10u);
  const auto at = static_cast<long long>(steps[3 * steps.size() / 8]) + 1;
  const auto t = hybridsim("run tiny.json -o smoke/v1.0/seed1.h5 --set seed=1",
                           "mkdir -p smoke/v1.0 && HYBRIDSIM_TEST_SIGNAL=TERM:loop:" + std::to_string(at) + " ");
  ASSERT_EQ(t.rc, 143) << t.err;
  ASSERT_TRUE(fs::exists(work_dir() / "smoke/v1.0/seed1.ckpt.h5"));

  const auto s = hybridsim("study smoke.json -j 2 --no-plot");
  ASSERT_EQ(s.rc, 0) << s.err;
  EXPECT_NE(s.err.find("4 members (2 variants x 2 seeds): 0 done, 4 to run (-j 2)"), std::string::npos) << s.err;
  EXPECT_NE(s.err.find("start    v1.0/seed1 (restart from seed1.ckpt.h5)"), std::string::npos) << s.err;
  EXPECT_EQ(count(s.err, "(fresh)"), 3) << s.err;
  EXPECT_NE(s.err.find("4/4 members done"), std::string::npos) << s.err;
  EXPECT_NE(slurp(work_dir() / "smoke/v1.0/seed1.log").find("restarted from"), std::string::npos);
  expect_same_series(work_dir() / "straight.h5", work_dir() / "smoke/v1.0/seed1.h5");

  // The member table: the documented record columns, then the metrics; one row per member.
  const std::string table = slurp(work_dir() / "smoke/table.csv");
  const std::string record_columns =
      "member,variant,seed,status,exit_code,output,program_version,commit,runs,wall_seconds,core_seconds,core_hours,"
      "max_rss_mib,peak_particles,";
  EXPECT_EQ(table.rfind(record_columns, 0), 0u) << table;
  EXPECT_NE(table.substr(0, table.find('\n')).find(",load_h_peak_moving_mean,"), std::string::npos)
      << "the run metrics (/analysis/metrics) as columns\n" << table;
  EXPECT_EQ(count(table, "\n"), 5) << table;
  EXPECT_EQ(count(table, ",done,0,"), 4) << table;
  EXPECT_NE(table.find("\nv1.2/seed2,v1.2,2,done,0,v1.2/seed2.h5,"), std::string::npos) << table;
  EXPECT_EQ(hs::testing::read_doubles(work_dir() / "smoke/table.h5", "/members/seed"),
            (std::vector<double>{1, 2, 1, 2}));
  EXPECT_EQ(hs::testing::read_doubles(work_dir() / "smoke/table.h5", "/members/peak_particles"),
            (std::vector<double>{804, 804, 804, 804}));
  const std::string summary = slurp(work_dir() / "smoke/summary.csv");
  EXPECT_NE(summary.find("\nv1.2,core_hours,h,2,"), std::string::npos) << summary;
  EXPECT_NE(slurp(work_dir() / "smoke/summary.md").find("## Against the reference `v1.0`"), std::string::npos);

  // Again: nothing runs, nothing of the members is touched.
  std::vector<long long> before;
  for (const char* f : {"study_state.json", "v1.0/seed1.h5", "v1.0/seed2.h5", "v1.2/seed1.h5", "v1.2/seed2.h5"})
    before.push_back(mtime_ns(work_dir() / "smoke" / f));
  const auto again = hybridsim("study smoke.json --no-plot");
  ASSERT_EQ(again.rc, 0) << again.err;
  EXPECT_NE(again.err.find("4 done, 0 to run"), std::string::npos) << again.err;
  EXPECT_EQ(again.err.find("start "), std::string::npos) << again.err;
  std::vector<long long> after;
  for (const char* f : {"study_state.json", "v1.0/seed1.h5", "v1.0/seed2.h5", "v1.2/seed1.h5", "v1.2/seed2.h5"})
    after.push_back(mtime_ns(work_dir() / "smoke" / f));
  EXPECT_EQ(before, after);
  EXPECT_EQ(slurp(work_dir() / "smoke/table.csv"), table) << "the same table from the same members";
}

// --dry-run lists the members with check's estimate and creates nothing; a variant whose override
// is no scene field, and a study file that names no seeds, are refused before anything runs.
TEST(StudyRun, DryRunAndBadStudiesRunNothing) {
  write_scene();
  write("dry.json", R"({"base": "tiny.json", "seeds": [4, 5], "variants": {"a": [], "b": ["ice.thickness=0.5"]}})");
  const auto d = hybridsim("study dry.json --dry-run");
  ASSERT_EQ(d.rc, 0) << d.err;
  EXPECT_NE(d.out.find("study dry: 4 members"), std::string::npos) << d.out;
  EXPECT_NE(d.out.find("  b/seed5  pending  ~"), std::string::npos) << d.out;
  EXPECT_NE(d.out.find("core-hours for the members not done"), std::string::npos) << d.out;
  EXPECT_FALSE(fs::exists(work_dir() / "dry"));
  write("bad.json", R"({"base": "tiny.json", "seeds": 1, "variants": {"a": ["ice.thicknes=0.5"]}})");
  const auto b = hybridsim("study bad.json");
  EXPECT_EQ(b.rc, 2) << b.err;
  EXPECT_NE(b.err.find("member a/seed1"), std::string::npos) << b.err;
  EXPECT_NE(b.err.find("thicknes"), std::string::npos) << b.err;
  EXPECT_FALSE(fs::exists(work_dir() / "bad"));
  write("noseeds.json", R"({"base": "tiny.json"})");
  const auto c = hybridsim("study noseeds.json");
  EXPECT_EQ(c.rc, 2) << c.err;
  EXPECT_NE(c.err.find("error: /seeds: missing required field \"seeds\""), std::string::npos) << c.err;
}
