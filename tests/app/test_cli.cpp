// End to end: runs the built `hybridsim` executable on tiny scenes in a temp directory and
// checks exit codes, the output file and the error messages.
#include <gtest/gtest.h>
#include <hdf5.h>
#include <nlohmann/json.hpp>

#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

struct Result {
  int rc = -1;
  std::string out, err;
};

fs::path work_dir() {
  const fs::path d = fs::temp_directory_path() / ("hs_test_cli_" + std::to_string(::getpid()));
  fs::create_directories(d);
  return d;
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

/// Runs `hybridsim <args>` in the work directory.
Result hybridsim(const std::string& args) {
  const fs::path d = work_dir();
  const std::string cmd = "cd '" + d.string() + "' && '" HYBRIDSIM_EXE "' " + args + " > out.txt 2> err.txt";
  const int status = std::system(cmd.c_str());
  Result r;
  r.rc = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = slurp(d / "out.txt");
  r.err = slurp(d / "err.txt");
  return r;
}

json tiny() {
  return json::parse(R"({
    "name": "tiny",
    "time": {"duration": 0.03, "output_interval": 0.005, "snapshot_interval": 0.01},
    "material": {"particle_diameter": 0.5},
    "bonds": {"tensile_strength": 2e5, "shear_strength": 2e5},
    "water": {"linear_drag": 5},
    "ice": {"thickness": 1.5, "length": 4, "width": 2},
    "walls": [
      {"name": "pusher", "point": [3.9, 0, 0.2], "normal": [-0.788, 0, -0.616], "velocity": [-2, 0, 0]},
      {"name": "back", "point": [0, 0, 0], "normal": [1, 0, 0]}
    ]
  })");
}

void write(const std::string& name, const std::string& text) { std::ofstream(work_dir() / name) << text; }

std::uint64_t rows(const fs::path& h5, const char* dataset) {
  const hid_t f = H5Fopen(h5.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (f < 0) return 0;
  const hid_t d = H5Dopen2(f, dataset, H5P_DEFAULT);
  hsize_t dims[2] = {0, 0};
  if (d >= 0) {
    const hid_t sp = H5Dget_space(d);
    H5Sget_simple_extent_dims(sp, dims, nullptr);
    H5Sclose(sp);
    H5Dclose(d);
  }
  H5Fclose(f);
  return dims[0];
}

}  // namespace

TEST(Cli, VersionAndHelp) {
  const Result r = hybridsim("--version");
  EXPECT_EQ(r.rc, 0);
  EXPECT_NE(r.out.find(HYBRIDSIM_VERSION), std::string::npos) << r.out;
  EXPECT_EQ(hybridsim("--help").rc, 0);
  EXPECT_EQ(hybridsim("").rc, 2);
}

TEST(Cli, RunsATinySceneAndWritesTheFile) {
  write("tiny.json", tiny().dump(2));
  fs::remove(work_dir() / "tiny.h5");
  const Result r = hybridsim("tiny.json");
  ASSERT_EQ(r.rc, 0) << r.out << r.err;
  EXPECT_TRUE(fs::exists(work_dir() / "tiny.h5"));
  EXPECT_TRUE(fs::exists(work_dir() / "tiny.xmf"));
  EXPECT_NE(r.out.find("finished"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("particle-steps/s"), std::string::npos) << r.out;
  // t = 0, ~0.005, ..., ~0.03, plus the final state when the last step is not an output step
  const auto n = rows(work_dir() / "tiny.h5", "/series/time");
  EXPECT_GE(n, 7u);
  EXPECT_LE(n, 8u);
  EXPECT_EQ(rows(work_dir() / "tiny.h5", "/series/parts/pusher/force"), n);
  EXPECT_EQ(rows(work_dir() / "tiny.h5", "/series/force"), n);
  EXPECT_EQ(rows(work_dir() / "tiny.h5", "/series/energy/bond_elastic"), n);
  EXPECT_EQ(rows(work_dir() / "tiny.h5", "/series/bonds_broken"), n);
  EXPECT_GT(rows(work_dir() / "tiny.h5", "/snapshots/000003/position"), 10u);

  // `run` subcommand, -o and --set
  const Result r2 = hybridsim("run tiny.json -o other.h5 --set time.duration=0.01 --set name=renamed");
  ASSERT_EQ(r2.rc, 0) << r2.err;
  EXPECT_GE(rows(work_dir() / "other.h5", "/series/time"), 3u);
  EXPECT_LE(rows(work_dir() / "other.h5", "/series/time"), 4u);
}

TEST(Cli, CheckPrintsDerivedFigures) {
  write("tiny.json", tiny().dump(2));
  const Result r = hybridsim("check tiny.json");
  ASSERT_EQ(r.rc, 0) << r.err;
  for (const char* word : {"particles:", "bonds:", "critical dt", "estimated memory", "estimated time"})
    EXPECT_NE(r.out.find(word), std::string::npos) << word << "\n" << r.out;
}

TEST(Cli, BadInputExitsWithTwoAndNamesThePath) {
  write("tiny.json", tiny().dump(2));
  struct Case {
    std::string args, needle;
  };
  json neg = tiny();
  neg["ice"]["thickness"] = -1;
  write("neg.json", neg.dump());
  json unk = tiny();
  unk["walls"][0]["nromal"] = {1, 0, 0};
  write("unk.json", unk.dump());
  write("syntax.json", "{\n\"name\": \"x\",\n\"time\": {\"duration\": 1}\n\"ice\": {}\n}");
  const Case cases[] = {
      {"neg.json", "error: /ice/thickness: "},
      {"unk.json", "error: /walls/0/nromal: unknown key \"nromal\" (did you mean \"normal\"?)"},
      {"syntax.json", "line 4"},
      {"missing.json", "error: missing.json: cannot open"},
      {"tiny.json --set time.dt=0.01", "error: /time/dt: "},
      {"check tiny.json --set time.dt=0.01", "error: /time/dt: "},
      {"tiny.json --set ice.thicknes=1", "error: /ice/thicknes: "},
      {"tiny.json --set material.contact_model=hertzian", "error: /material/contact_model: "},
  };
  for (const auto& c : cases) {
    const Result r = hybridsim(c.args);
    EXPECT_EQ(r.rc, 2) << c.args << "\n" << r.err;
    EXPECT_NE(r.err.find(c.needle), std::string::npos) << c.args << "\nstderr: " << r.err;
  }
}

TEST(Cli, UnstableRunExitsWithThreeAndKeepsTheOutput) {
  json j = tiny();
  j["name"] = "unstable";
  j["time"]["duration"] = 0.05;
  j["time"]["output_interval"] = 0.002;
  j["stability"] = {{"max_speed", 0.5}};  // the pusher moves at 2 m/s: the run must stop
  write("unstable.json", j.dump());
  fs::remove(work_dir() / "unstable.h5");
  const Result r = hybridsim("unstable.json");
  EXPECT_EQ(r.rc, 3) << r.err;
  EXPECT_NE(r.err.find("unstable"), std::string::npos) << r.err;
  EXPECT_GE(rows(work_dir() / "unstable.h5", "/series/time"), 1u) << "output so far must be kept";
}
