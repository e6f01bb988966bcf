// The run metrics (docs/metrics.md) through the binary: each is independent of the output
// interval (the same run at two intervals gives the same value, exactly: they come from the
// per-step load and the state at the last step, which the output interval does not touch); a
// run stopped by SIGTERM gets them computed from its file, and the --restart that finishes it
// stores the same ones as the run that was never stopped; bad input exits 2.
#include <gtest/gtest.h>
#include "cli_fixtures.h"
#include "h5_read.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <string>

namespace {

namespace fs = std::filesystem;
using hs::testing::read_doubles;
using nlohmann::json;

fs::path work_dir() { return hs::testing::cli_work_dir("metrics"); }

hs::testing::CliResult hybridsim(const std::string& args, const std::string& prefix = "") {
  return hs::testing::run_hybridsim(work_dir(), args, prefix);
}

// tests/app/pinned_run.json for 1.2 s (5005 steps): a pier through bonded ice with two blocks;
// the front reaches the ice at 0.5 s, so the level-ice window and the 1 s moving mean have data.
const std::string kScene = "'" HYBRIDSIM_SOURCE_DIR "/tests/app/pinned_run.json' --set time.duration=1.2";

json metrics_json(const std::string& file, const std::string& extra = "") {
  const auto r = hybridsim("metrics " + file + " --json" + extra);
  EXPECT_EQ(r.rc, 0) << r.err;
  return r.rc == 0 ? json::parse(r.out) : json::object();
}

/// Every metric of a and b equal (both null: no data), and the same names.
void expect_same_metrics(const json& a, const json& b, const std::string& what) {
  ASSERT_EQ(a.size(), b.size()) << what;
  for (const auto& [name, m] : a.items()) {
    ASSERT_TRUE(b.contains(name)) << name << " " << what;
    EXPECT_EQ(m["value"], b[name]["value"]) << name << " " << what;
  }
}

double max_horizontal_row(const fs::path& file) {
  const auto f = read_doubles(file, "/series/force");
  double m = 0.0;
  for (std::size_t k = 0; k + 2 < f.size(); k += 3) m = std::max(m, std::hypot(f[k], f[k + 1]));
  return m;
}

TEST(RunMetrics, IndependentOfOutputInterval) {
  ASSERT_EQ(hybridsim("run " + kScene + " -o i01.h5 --set time.output_interval=0.01").rc, 0);
  ASSERT_EQ(hybridsim("run " + kScene + " -o i05.h5 --set time.output_interval=0.05").rc, 0);
  const json a = metrics_json("i01.h5"), b = metrics_json("i05.h5");
  // The per-step load is the same series of 5005 rows; /series has 121 and 25 rows.
  const auto fa = read_doubles(work_dir() / "i01.h5", "/load_per_step/force");
  EXPECT_EQ(fa.size(), 3u * 5005u);
  EXPECT_TRUE(fa == read_doubles(work_dir() / "i05.h5", "/load_per_step/force"));
  // Tolerance: none. Measured difference: 0 for every metric (the same per-step values summed
  // in the same order; the last row of /series is the last step's at both intervals).
  expect_same_metrics(a, b, "between output intervals 0.01 and 0.05 s");
  for (const char* name : {"load_h_mean_run", "load_v_mean_run", "load_h_mean_level_ice", "load_h_impulse",
                           "load_h_p95", "load_h_peak_moving_mean", "pile_height_mean_max", "pile_height_top_max",
                           "pile_height_mean_end", "pile_height_top_end"}) {
    ASSERT_TRUE(a.contains(name)) << name;
    EXPECT_TRUE(a[name]["value"].is_number()) << name << " has no data";
    EXPECT_FALSE(a[name]["unit"].get<std::string>().empty()) << name;
  }
  EXPECT_TRUE(a["load_h_mean_keel"]["value"].is_null()) << "a window with no data is NaN (null), not 0";
  // The same peak taken from the rows moves with the interval (why the metrics use the steps).
  EXPECT_GT(max_horizontal_row(work_dir() / "i01.h5"), max_horizontal_row(work_dir() / "i05.h5") * 1.01);
  // The run stored them in /analysis/metrics; computed again from the file they are the same.
  expect_same_metrics(a, metrics_json("i01.h5", " --moving-window 1"), "stored vs computed");
  const auto r = hybridsim("metrics i01.h5");
  EXPECT_NE(r.out.find("stored in /analysis/metrics"), std::string::npos) << r.out;
}

TEST(RunMetrics, StoppedRunAndItsRestart) {
  ASSERT_EQ(hybridsim("run " + kScene + " -o straight.h5 --set time.output_interval=0.01").rc, 0);
  const auto stop = hybridsim("run " + kScene + " -o stopped.h5 --set time.output_interval=0.01",
                              "HYBRIDSIM_TEST_SIGNAL=TERM:loop:4500 ");
  ASSERT_EQ(stop.rc, 143) << stop.err;
  // No /analysis: the metrics are computed from the per-step load of the 4500 steps.
  const auto r = hybridsim("metrics stopped.h5");
  EXPECT_EQ(r.rc, 0) << r.err;
  EXPECT_NE(r.out.find("computed from the run file"), std::string::npos) << r.out;
  EXPECT_EQ(metrics_json("stopped.h5")["steps"]["value"], 4500);
  const auto cont = hybridsim("run " + kScene + " -o stopped.h5 --set time.output_interval=0.01 --restart stopped.h5");
  ASSERT_EQ(cont.rc, 0) << cont.err;
  EXPECT_TRUE(read_doubles(work_dir() / "straight.h5", "/load_per_step/force") ==
              read_doubles(work_dir() / "stopped.h5", "/load_per_step/force"));
  expect_same_metrics(metrics_json("straight.h5"), metrics_json("stopped.h5"), "straight vs stopped + restarted");
}

TEST(RunMetrics, WindowsAndBadInput) {
  if (!fs::exists(work_dir() / "i01.h5"))
    ASSERT_EQ(hybridsim("run " + kScene + " -o i01.h5 --set time.output_interval=0.01").rc, 0);
  // The level ice's front: the pier's radius at the sheet's underside (0.75 m of ice floating at
  // 920 / 1025), 1 + 0.6732 / tan(52 deg) = 1.526 m ahead of the axis (x = -1.5 m at t = 0, 1 m/s):
  // x_f(t) = 0.0259 + t m, so x in [x_f(0.7), x_f(1.2)] holds the steps of 0.7 s < t <= 1.2 s.
  const double front0 = -1.5 + 1.0 + 0.75 * 920.0 / 1025.0 / std::tan(52.0 * M_PI / 180.0);
  const json w = {{{"name", "keel"}, {"x0", front0 + 0.7}, {"x1", front0 + 1.2}},
                  {{"name", "late"}, {"t0", 0.7}, {"t1", 1.2}}};
  std::ofstream(work_dir() / "w.json") << w.dump();
  const json m = metrics_json("i01.h5", " --windows w.json");
  ASSERT_TRUE(m["load_h_mean_keel"]["value"].is_number());
  // Measured: equal, difference 0 (the ends from x differ from 0.7 and 1.2 s by round-off only).
  EXPECT_NEAR(m["load_h_mean_keel"]["value"].get<double>(), m["load_h_mean_late"]["value"].get<double>(),
              1e-12 * m["load_h_mean_late"]["value"].get<double>());
  auto r = hybridsim("metrics nothere.h5");
  EXPECT_EQ(r.rc, 2);
  EXPECT_NE(r.err.find("error: RUN.h5: no run file 'nothere.h5'"), std::string::npos) << r.err;
  std::ofstream(work_dir() / "bad.json") << R"([{"name": "keel", "x0": 3, "x1": 1}])";
  r = hybridsim("metrics i01.h5 --windows bad.json");
  EXPECT_EQ(r.rc, 2);
  EXPECT_NE(r.err.find("bad.json/0: window 'keel': x1 must exceed x0"), std::string::npos) << r.err;
}

}  // namespace
