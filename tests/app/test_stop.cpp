// What a run leaves behind when it does not end normally (issue 14): SIGTERM and SIGINT stop it
// gracefully (exit 143 / 130, every series row up to the stop), kill -9 after the wall-clock
// flush interval leaves a readable file with the rows up to that flush, and an unstable run
// (exit 3) ends with a snapshot of its last good step. Runs the built `hybridsim` as a child.
#include <gtest/gtest.h>
#include "cli_fixtures.h"
#include <hdf5.h>
#include <nlohmann/json.hpp>

#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

extern char** environ;

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

fs::path work_dir() { return hs::testing::cli_work_dir("stop"); }

using hs::testing::slurp;

void write(const std::string& name, const std::string& text) { std::ofstream(work_dir() / name) << text; }

/// A quiet floating sheet (120 particles, dt = 4.8e-5 s) that runs for hours: still running
/// whenever the test signals it.
json long_scene() {
  return json::parse(R"({
    "name": "long",
    "time": {"duration": 1000, "output_interval": 0.005},
    "material": {"particle_diameter": 0.5},
    "bonds": {"tensile_strength": 2e5, "shear_strength": 2e5},
    "water": {"linear_drag_per_area": 1000},
    "ice": {"thickness": 1.5, "length": 4, "width": 2},
    "walls": [{"name": "back", "point": [0, 0, 0], "normal": [1, 0, 0]}]
  })");
}

/// `hybridsim <args>` started in the work directory (stdout/stderr to <tag>.out/.err), after
/// `launcher` (e.g. mpirun and its options) if given. `signal_at` (HYBRIDSIM_TEST_SIGNAL,
/// docs/output.md: "TERM:loop:2000" raises SIGTERM after step 2000) stops it at a step of its
/// progress, whatever the machine's speed.
struct Child {
  pid_t pid = -1;
  std::string tag;
  std::string err() const { return slurp(work_dir() / (tag + ".err")); }
};

Child start(const std::string& tag, const std::string& args, const std::string& signal_at,
            const std::string& launcher = "") {
  const fs::path d = work_dir();
  const std::string cmd = "cd '" + d.string() + "' && HYBRIDSIM_TEST_SIGNAL=" + signal_at + " exec " + launcher +
                          "'" HYBRIDSIM_EXE "' " + args + " > " + tag + ".out 2> " + tag + ".err";
  Child c;
  c.tag = tag;
  const char* argv[] = {"/bin/sh", "-c", cmd.c_str(), nullptr};
  if (posix_spawn(&c.pid, "/bin/sh", nullptr, nullptr, const_cast<char**>(argv), environ) != 0) c.pid = -1;
  return c;
}

/// Exit status of the child: the exit code, or -signal if a signal ended it.
int wait_for(const Child& c) {
  int status = 0;
  if (waitpid(c.pid, &status, 0) != c.pid) return -1000;
  return WIFEXITED(status) ? WEXITSTATUS(status) : -WTERMSIG(status);
}

/// A dataset as doubles (integers converted); empty if the file or dataset cannot be opened.
std::vector<double> read(const fs::path& h5, const std::string& dataset) {
  std::vector<double> v;
  const hid_t f = H5Fopen(h5.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (f < 0) return v;
  const hid_t d = H5Dopen2(f, dataset.c_str(), H5P_DEFAULT);
  if (d >= 0) {
    const hid_t sp = H5Dget_space(d);
    const auto n = H5Sget_simple_extent_npoints(sp);
    v.resize(static_cast<std::size_t>(n));
    if (n > 0 && H5Dread(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()) < 0) v.clear();
    H5Sclose(sp);
    H5Dclose(d);
  }
  H5Fclose(f);
  return v;
}

bool exists(const fs::path& h5, const std::string& object) {
  const hid_t f = H5Fopen(h5.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (f < 0) return false;
  const bool e = H5Lexists(f, object.c_str(), H5P_DEFAULT) > 0;
  H5Fclose(f);
  return e;
}

/// The number after `key` in `text` (e.g. "after step 1234"), or -1.
long long number_after(const std::string& text, const std::string& key) {
  const std::regex re(key + " ([0-9]+)");
  std::smatch m;
  return std::regex_search(text, m, re) ? std::stoll(m[1].str()) : -1;
}

/// Rows are every output step from 0 without a gap: steps 0, m, 2m, ... (m from the first gap),
/// then possibly one last row at `last_step` (a partial interval). Times follow the steps.
void expect_contiguous_rows(const fs::path& h5, long long last_step) {
  const auto step = read(h5, "/series/step");
  const auto time = read(h5, "/series/time");
  ASSERT_GE(step.size(), 3u) << "a run of seconds writes many rows";
  ASSERT_EQ(time.size(), step.size());
  const double m = step[1];
  const double dt = time[1] / m;
  EXPECT_NEAR(time[1], 0.005, dt) << "rows at output_interval = 0.005 s";
  const std::size_t n = step.size();
  for (std::size_t i = 0; i + 1 < n; ++i) {
    ASSERT_EQ(step[i], m * static_cast<double>(i)) << "row " << i << ": a row is missing";
    // Relative to the time: t accumulates one dt per step (measured agreement ~1e-13 relative).
    EXPECT_NEAR(time[i], dt * step[i], 1e-9 * (1 + time[i])) << "row " << i;
  }
  if (last_step >= 0) {
    EXPECT_EQ(step[n - 1], static_cast<double>(last_step)) << "the last row is the step the run stopped at";
    EXPECT_GT(step[n - 1], step[n - 2]);
    EXPECT_LE(step[n - 1] - step[n - 2], m);
  }
  // Every series has the same rows.
  for (const char* s : {"/series/force", "/series/walls/back/force", "/series/energy/total", "/series/bonds"})
    EXPECT_EQ(read(h5, s).size() / (std::string(s).find("force") != std::string::npos ? 3 : 1), n) << s;
}

}  // namespace

// (1) SIGTERM (a batch system's wall-time limit): the step under way finishes, every row up to it
// is written, the file is closed, exit 143. On main the run died by the signal with only row 0.
TEST(Stop, SigtermFinishesTheStepWritesEveryRowAndExits143) {
  write("long.json", long_scene().dump());
  fs::remove(work_dir() / "term.h5");
  const Child c = start("term", "long.json -o term.h5", "TERM:loop:2000");
  ASSERT_GT(c.pid, 0);
  const int rc = wait_for(c);
  const std::string err = c.err();
  ASSERT_EQ(rc, 143) << err;
  EXPECT_NE(err.find("stopped by SIGTERM"), std::string::npos) << err;
  EXPECT_NE(err.find("to continue the run: hybridsim run long.json --restart term.h5"), std::string::npos)
      << "prints the command that resumes the run\n" << err;
  EXPECT_TRUE(fs::exists(work_dir() / "term.ckpt.h5")) << "and writes the checkpoint it needs";
  const long long k = number_after(err, "after step");
  ASSERT_EQ(k, 2000) << "a serial run looks after every step\n" << err;
  expect_contiguous_rows(work_dir() / "term.h5", k);
  EXPECT_FALSE(exists(work_dir() / "term.h5", "/analysis")) << "a stopped run is not analysed";
}

// (2) SIGINT (Ctrl-C), snapshots on: exit 130, the rows up to the stop and a final snapshot of
// the stop step.
TEST(Stop, SigintStopsWithRowsAndAFinalSnapshotAndExits130) {
  json j = long_scene();
  j["time"]["snapshot_interval"] = 0.5;
  write("long_snap.json", j.dump());
  fs::remove(work_dir() / "int.h5");
  const Child c = start("int", "long_snap.json -o int.h5", "INT:loop:2000");
  ASSERT_GT(c.pid, 0);
  const int rc = wait_for(c);
  const std::string err = c.err();
  ASSERT_EQ(rc, 130) << err;
  EXPECT_NE(err.find("stopped by SIGINT"), std::string::npos) << err;
  const long long k = number_after(err, "after step");
  ASSERT_EQ(k, 2000) << err;
  expect_contiguous_rows(work_dir() / "int.h5", k);
  const auto snap_steps = read(work_dir() / "int.h5", "/snapshots/steps");
  ASSERT_GE(snap_steps.size(), 1u);
  EXPECT_EQ(snap_steps.back(), static_cast<double>(k)) << "the final snapshot is the stop step";
}

// (3) kill -9 cannot be caught: what survives is the last wall-clock flush. With an interval
// shorter than a step (1e-6 s: a flush after every step) and the kill after step 320, the
// (partial) file holds every row up to the kill, contiguous from t = 0 (without the flushes
// only the t = 0 row would survive).
TEST(Stop, KillNineAfterTheWallClockFlushLeavesTheRowsFlushed) {
  write("long.json", long_scene().dump());
  fs::remove(work_dir() / "kill.h5");
  const Child c = start("kill", "long.json -o kill.h5 --flush-interval 1e-6 --fsync", "KILL:loop:320");
  ASSERT_GT(c.pid, 0);
  EXPECT_EQ(wait_for(c), -SIGKILL) << c.err();
  // A killed run never renames its file: the rows are in the partial file (docs/output.md).
  EXPECT_FALSE(fs::exists(work_dir() / "kill.h5"));
  const fs::path partial = work_dir() / ("kill.partial-" + std::to_string(c.pid) + ".h5");
  const auto step = read(partial, "/series/step");
  ASSERT_GT(step.size(), 1u) << "more than the t = 0 row survives\n" << c.err();
  expect_contiguous_rows(partial, -1);
  // Every row before the kill: the next row was due after step 320 (or at it: the kill comes
  // before step 320's flush).
  EXPECT_LE(step.back(), 320.0);
  EXPECT_GE(step.back() + step[1], 320.0) << "a row flushed before the kill is missing";
  fs::remove(partial);
}

// (1b) Under MPI: SIGTERM reaches one rank only (the hardest case for agreement): the ranks agree
// every 16 steps (one allreduce), all stop after the same step, write the rows up to it and
// exit 143, so mpirun exits 143 too. Rank 1 raises it after step 401: all stop after 416.
TEST(Stop, SigtermToOneMpiRankStopsAllRanksAtTheSameStep) {
  write("long.json", long_scene().dump());
  fs::remove(work_dir() / "mpi.h5");
  const std::string mpirun = hs::testing::mpirun_prefix(2);
  // --flush-interval 0.5: flushes decided collectively on the way
  const Child c = start("mpi", "long.json -o mpi.h5 --flush-interval 0.5", "TERM:loop:401:1", mpirun);
  ASSERT_GT(c.pid, 0);
  const int rc = wait_for(c);
  const std::string err = c.err();
  ASSERT_EQ(rc, 143) << err;
  const long long k = number_after(err, "after step");
  EXPECT_EQ(k, 416) << "the ranks decide every 16 steps\n" << err;
  expect_contiguous_rows(work_dir() / "mpi.h5", k);
}

// (4) An unstable run (exit 3) ends with a snapshot of its last good step, whether or not the scene
// asked for snapshots: the step before the one that failed, every value finite and every speed
// within the limit the failed step broke (stability.max_speed = 0.5 m/s with the pusher at 2 m/s).
TEST(Stop, UnstableRunEndsWithTheLastGoodStateAsASnapshot) {
  json j = json::parse(R"({
    "name": "unstable",
    "time": {"duration": 0.05, "output_interval": 0.002},
    "material": {"particle_diameter": 0.5},
    "bonds": {"tensile_strength": 2e5, "shear_strength": 2e5},
    "water": {"linear_drag_per_area": 1000},
    "ice": {"thickness": 1.5, "length": 4, "width": 2},
    "stability": {"max_speed": 0.5},
    "walls": [
      {"name": "pusher", "point": [3.9, 0, 0.2], "normal": [-0.788, 0, -0.616], "velocity": [-2, 0, 0]},
      {"name": "back", "point": [0, 0, 0], "normal": [1, 0, 0]}
    ]
  })");
  for (const double snapshot_interval : {0.0, 0.004}) {
    SCOPED_TRACE("snapshot_interval = " + std::to_string(snapshot_interval));
    j["time"]["snapshot_interval"] = snapshot_interval;
    write("unstable.json", j.dump());
    fs::remove(work_dir() / "unstable.h5");
    const Child c = start("unstable", "unstable.json -o unstable.h5", "");
    ASSERT_GT(c.pid, 0);
    const int rc = wait_for(c);
    const std::string err = c.err();
    ASSERT_EQ(rc, 3) << err;
    const long long failed = number_after(err, "unstable at step");
    ASSERT_GT(failed, 1) << err;
    const fs::path h5 = work_dir() / "unstable.h5";
    const auto steps = read(h5, "/snapshots/steps");
    ASSERT_GE(steps.size(), 1u) << "the last good state is written as a snapshot\n" << err;
    EXPECT_EQ(steps.back(), static_cast<double>(failed - 1)) << "the step before the one that failed";
    char last[32];
    std::snprintf(last, sizeof last, "/snapshots/%06zu/", steps.size() - 1);
    const auto x = read(h5, std::string(last) + "position");
    const auto v = read(h5, std::string(last) + "velocity");
    ASSERT_EQ(x.size(), 3u * 120u);
    ASSERT_EQ(v.size(), x.size());
    double vmax = 0;
    for (std::size_t i = 0; i < v.size(); i += 3) vmax = std::max(vmax, std::hypot(v[i], v[i + 1], v[i + 2]));
    for (const double a : x) ASSERT_TRUE(std::isfinite(a));
    // Measured 0.4847 m/s in the kept state (the failed step had 0.5365 m/s).
    EXPECT_LE(vmax, 0.5) << "the kept state is a good one";
    EXPECT_GT(vmax, 0.0);
    for (const char* s : {"/series/time", "/series/force", "/series/energy/total", "/series/walls/pusher/force"})
      for (const double a : read(h5, s)) ASSERT_TRUE(std::isfinite(a)) << s;
  }
}

// (5) One writer per output (docs/output.md, "Where the file is written"): while a run writes
// lock.h5 and lock.ckpt.h5, a second run on the same -o, and a --restart of that run, are refused
// with exit 2 before they write anything, naming the running process (its PID and command line).
// The first run's files are its own when it ends; after it, the same command is accepted.
TEST(Stop, ASecondRunOnAnOutputInUseIsRefusedNamingTheProcess) {
  write("long.json", long_scene().dump());
  for (const char* f : {"lock.h5", "lock.ckpt.h5", "lock.h5.lock", "lock.ckpt.h5.lock"}) fs::remove(work_dir() / f);
  const Child first =
      start("lock", "long.json -o lock.h5 --set time.checkpoint_interval=0.05", "TERM:loop:1000000000");
  ASSERT_GT(first.pid, 0);
  // Running once its first checkpoint is written (step ~1040).
  for (int k = 0; k < 600 && !fs::exists(work_dir() / "lock.ckpt.h5"); ++k) usleep(100000);
  ASSERT_TRUE(fs::exists(work_dir() / "lock.ckpt.h5")) << first.err();
  const std::string pid = std::to_string(first.pid);
  for (const std::string args : {"long.json -o lock.h5 --set time.duration=0.01", "long.json --restart lock.h5"}) {
    const auto second = hs::testing::run_hybridsim(work_dir(), args);
    EXPECT_EQ(second.rc, 2) << args << "\n" << second.err;
    EXPECT_NE(second.err.find("is in use by another running hybridsim: process " + pid + " ("), std::string::npos)
        << args << "\n" << second.err;
    EXPECT_NE(second.err.find("long.json -o lock.h5"), std::string::npos) << "the holder's command line\n"
                                                                          << second.err;
    EXPECT_NE(second.err.find("lock.h5.lock"), std::string::npos) << second.err;
  }
  // Nothing of the refused runs: the only partial file is the first run's.
  for (const auto& e : fs::directory_iterator(work_dir())) {
    const std::string name = e.path().filename().string();
    if (name.rfind("lock.partial-", 0) == 0) {
      EXPECT_EQ(name.rfind("lock.partial-" + pid + ".", 0), 0u) << name;
    }
  }
  ASSERT_EQ(kill(first.pid, SIGTERM), 0);
  ASSERT_EQ(wait_for(first), 143) << first.err();
  const long long k = number_after(first.err(), "after step");
  expect_contiguous_rows(work_dir() / "lock.h5", k);  // every row of the first run, up to its stop
  EXPECT_TRUE(fs::exists(work_dir() / "lock.ckpt.h5"));
  EXPECT_FALSE(fs::exists(work_dir() / "lock.h5.lock")) << "a run that returns removes its lock files";
  EXPECT_FALSE(fs::exists(work_dir() / "lock.ckpt.h5.lock"));
  const auto again = hs::testing::run_hybridsim(work_dir(), "long.json -o lock.h5 --set time.duration=0.01");
  EXPECT_EQ(again.rc, 0) << again.err;
}

// A run killed outright (SIGKILL) leaves its lock file but no lock: the kernel released it with
// the process, and the next run on that output takes it over.
TEST(Stop, AKilledRunsLockFileDoesNotHoldTheOutput) {
  write("long.json", long_scene().dump());
  fs::remove(work_dir() / "killed.h5");
  const Child c = start("killed", "long.json -o killed.h5", "KILL:loop:200");
  ASSERT_GT(c.pid, 0);
  EXPECT_EQ(wait_for(c), -SIGKILL) << c.err();
  EXPECT_TRUE(fs::exists(work_dir() / "killed.h5.lock"));
  const auto next = hs::testing::run_hybridsim(work_dir(), "long.json -o killed.h5 --set time.duration=0.01");
  EXPECT_EQ(next.rc, 0) << next.err;
  EXPECT_FALSE(fs::exists(work_dir() / "killed.h5.lock"));
  fs::remove(work_dir() / ("killed.partial-" + std::to_string(c.pid) + ".h5"));
}
