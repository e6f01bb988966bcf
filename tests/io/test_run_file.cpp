// hs::io::RunFile: file layout, XDMF index, survival of SIGKILL after a flush, bad paths.
#include <gtest/gtest.h>
#include <hdf5.h>
#include <mpi.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "common/error.h"
#include "io/run_file.h"

namespace fs = std::filesystem;
using hs::io::FieldSlice;
using hs::io::RunFile;
using hs::io::RunFileMeta;

namespace {

/// A fresh directory per test, removed afterwards.
class RunFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() /
           ("hs_io_" + std::to_string(::getpid()) + "_" + info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string file(const std::string& name) const { return (dir_ / name).string(); }
  fs::path dir_;
};

RunFileMeta meta() {
  RunFileMeta m;
  m.scene_text = R"({"ice": {"thickness": 0.6}})";
  m.program_version = "9.8.7-test";
  return m;
}

// ---- read-back helpers (plain HDF5 C API, read-only) ----
struct H5File {
  explicit H5File(const std::string& path) : id(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT)) {}
  ~H5File() {
    if (id >= 0) H5Fclose(id);
  }
  hid_t id;
};

bool object_exists(hid_t file, const std::string& path) {
  // Walk the components so a missing intermediate group is "false", not an error.
  std::string sofar;
  std::stringstream ss(path.substr(1));
  std::string part;
  while (std::getline(ss, part, '/')) {
    sofar += "/" + part;
    if (H5Lexists(file, sofar.c_str(), H5P_DEFAULT) <= 0) return false;
  }
  return true;
}

std::vector<hsize_t> dims_of(hid_t file, const std::string& path) {
  hid_t d = H5Dopen2(file, path.c_str(), H5P_DEFAULT);
  if (d < 0) return {};
  hid_t s = H5Dget_space(d);
  std::vector<hsize_t> dims(static_cast<std::size_t>(H5Sget_simple_extent_ndims(s)));
  H5Sget_simple_extent_dims(s, dims.data(), nullptr);
  H5Sclose(s);
  H5Dclose(d);
  return dims;
}

template <typename T>
std::vector<T> read_all(hid_t file, const std::string& path, hid_t mem_type) {
  std::vector<hsize_t> dims = dims_of(file, path);
  std::size_t n = 1;
  for (hsize_t d : dims) n *= d;
  std::vector<T> v(n);
  hid_t d = H5Dopen2(file, path.c_str(), H5P_DEFAULT);
  if (d < 0) return {};
  if (n > 0) {
    EXPECT_GE(H5Dread(d, mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()), 0) << path;
  }
  H5Dclose(d);
  return v;
}

std::string string_attr(hid_t file, const std::string& obj, const std::string& name) {
  hid_t a = H5Aopen_by_name(file, obj.c_str(), name.c_str(), H5P_DEFAULT, H5P_DEFAULT);
  if (a < 0) return "<missing>";
  hid_t t = H5Tcopy(H5T_C_S1);
  H5Tset_size(t, H5T_VARIABLE);
  H5Tset_cset(t, H5T_CSET_UTF8);
  char* p = nullptr;
  std::string out = "<unreadable>";
  if (H5Aread(a, t, &p) >= 0 && p != nullptr) {
    out = p;
    H5free_memory(p);
  }
  H5Tclose(t);
  H5Aclose(a);
  return out;
}

template <typename T>
T scalar_attr(hid_t file, const std::string& obj, const std::string& name, hid_t mem_type) {
  T v{};
  hid_t a = H5Aopen_by_name(file, obj.c_str(), name.c_str(), H5P_DEFAULT, H5P_DEFAULT);
  EXPECT_GE(a, 0) << obj << "@" << name;
  if (a >= 0) {
    EXPECT_GE(H5Aread(a, mem_type, &v), 0);
    H5Aclose(a);
  }
  return v;
}

std::string slurp(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// Minimal XML well-formedness: tags nest and close, attributes are quoted. Enough to catch a
/// broken writer; ParaView's reader is the real judge.
::testing::AssertionResult well_formed_xml(const std::string& x) {
  std::vector<std::string> open;
  const std::regex attr_re(R"(^\s*([A-Za-z_:][-A-Za-z0-9_:.]*)\s*=\s*"[^"<]*")");
  std::size_t i = 0;
  int elements = 0;
  while ((i = x.find('<', i)) != std::string::npos) {
    const std::size_t end = x.find('>', i);
    if (end == std::string::npos) return ::testing::AssertionFailure() << "unclosed '<' at " << i;
    std::string tag = x.substr(i + 1, end - i - 1);
    i = end + 1;
    if (tag.empty()) return ::testing::AssertionFailure() << "empty tag";
    if (tag[0] == '?' || tag[0] == '!') continue;  // declaration, DOCTYPE, comment
    if (tag[0] == '/') {
      const std::string name = tag.substr(1);
      if (open.empty() || open.back() != name)
        return ::testing::AssertionFailure() << "</" << name << "> does not close "
                                             << (open.empty() ? "anything" : open.back());
      open.pop_back();
      continue;
    }
    const bool self_closing = tag.back() == '/';
    if (self_closing) tag.pop_back();
    const std::size_t name_end = tag.find_first_of(" \t\n");
    const std::string name = tag.substr(0, name_end);
    std::string rest = name_end == std::string::npos ? "" : tag.substr(name_end);
    std::smatch m;
    while (std::regex_search(rest, m, attr_re)) rest = m.suffix();
    if (rest.find_first_not_of(" \t\n") != std::string::npos)
      return ::testing::AssertionFailure() << "bad attributes in <" << tag << ">";
    ++elements;
    if (!self_closing) open.push_back(name);
  }
  if (!open.empty()) return ::testing::AssertionFailure() << "<" << open.back() << "> never closed";
  if (elements == 0) return ::testing::AssertionFailure() << "no elements";
  return ::testing::AssertionSuccess();
}

std::vector<double> rows(int first, int count, int width) {
  std::vector<double> v;
  for (int r = first; r < first + count; ++r)
    for (int c = 0; c < width; ++c) v.push_back(r * 10.0 + c);
  return v;
}

}  // namespace

TEST_F(RunFileTest, RootAttributes) {
  const std::string path = file("run.h5");
  { RunFile rf(path, meta()); }
  H5File f(path);
  ASSERT_GE(f.id, 0);
  EXPECT_EQ(string_attr(f.id, "/", "scene"), meta().scene_text);
  EXPECT_EQ(string_attr(f.id, "/", "program_version"), "9.8.7-test");
  EXPECT_EQ(string_attr(f.id, "/", "file_format"), "hybridsim-run/1");
  EXPECT_TRUE(std::regex_match(string_attr(f.id, "/", "created"),
                               std::regex(R"(\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ)")))
      << string_attr(f.id, "/", "created");
}

TEST_F(RunFileTest, LargeSceneAttribute) {
  // Scenes can exceed the 64 KiB compact-attribute limit of the oldest file format.
  const std::string path = file("run.h5");
  RunFileMeta m = meta();
  m.scene_text = "{\"pad\": \"" + std::string(300000, 'x') + "\"}";
  { RunFile rf(path, m); }
  H5File f(path);
  EXPECT_EQ(string_attr(f.id, "/", "scene"), m.scene_text);
}

TEST_F(RunFileTest, SeriesAcrossSeveralFlushes) {
  const std::string path = file("run.h5");
  {
    RunFile rf(path, meta());
    const int force = rf.add_series("/series/force", 3, "N", "total force on the structure");
    const int energy = rf.add_series("/series/energy", 1, "J", "kinetic energy");
    const int cone = rf.add_series("/series/parts/cone/force", 3, "N", "force on the cone");
    const int broken = rf.add_int_series("/series/bonds_broken", 1, "1", "bonds broken so far");
    int row = 0;
    for (int chunk : {5, 7, 3}) {
      for (int k = 0; k < chunk; ++k, ++row) {
        const auto v = rows(row, 1, 3);
        rf.append(force, v.data());
        rf.append(energy, v.data());
        const double c[3] = {-v[0], -v[1], -v[2]};
        rf.append(cone, c);
        const std::int64_t b = 2 * row;
        rf.append(broken, &b);
      }
      rf.flush();
    }
    EXPECT_EQ(rf.series_rows(force), 15u);
  }
  H5File f(path);
  ASSERT_GE(f.id, 0);
  EXPECT_EQ(dims_of(f.id, "/series/force"), (std::vector<hsize_t>{15, 3}));
  EXPECT_EQ(dims_of(f.id, "/series/energy"), (std::vector<hsize_t>{15}));
  EXPECT_EQ(dims_of(f.id, "/series/parts/cone/force"), (std::vector<hsize_t>{15, 3}));
  EXPECT_EQ(dims_of(f.id, "/series/bonds_broken"), (std::vector<hsize_t>{15}));
  EXPECT_EQ(read_all<double>(f.id, "/series/force", H5T_NATIVE_DOUBLE), rows(0, 15, 3));
  const auto energy = read_all<double>(f.id, "/series/energy", H5T_NATIVE_DOUBLE);
  for (int r = 0; r < 15; ++r) EXPECT_EQ(energy[r], r * 10.0);
  const auto cone = read_all<double>(f.id, "/series/parts/cone/force", H5T_NATIVE_DOUBLE);
  EXPECT_EQ(cone[3 * 14 + 2], -142.0);
  const auto broken = read_all<std::int64_t>(f.id, "/series/bonds_broken", H5T_NATIVE_INT64);
  EXPECT_EQ(broken[14], 28);
  EXPECT_EQ(string_attr(f.id, "/series/force", "units"), "N");
  EXPECT_EQ(string_attr(f.id, "/series/force", "description"), "total force on the structure");
  EXPECT_EQ(string_attr(f.id, "/series/energy", "units"), "J");
  EXPECT_EQ(string_attr(f.id, "/series/parts/cone/force", "units"), "N");
}

TEST_F(RunFileTest, SnapshotsFieldsAndTimes) {
  const std::string path = file("run.h5");
  {
    RunFile rf(path, meta());
    for (int s = 0; s < 2; ++s) {
      const int n = 4 + 2 * s;
      rf.begin_snapshot(0.5 * (s + 1), 1000u * (s + 1));
      const auto pos = rows(100 * s, n, 3);
      std::vector<double> vel(pos.size(), -1.0 * s);
      std::vector<std::int64_t> id(n);
      std::vector<std::int32_t> type(n, 2);
      for (int i = 0; i < n; ++i) id[i] = 1000 + i;
      rf.write_field("position", pos.data(), n, 3, "m");
      rf.write_field("velocity", vel.data(), n, 3, "m/s");
      rf.write_field("global_id", id.data(), n, 1, "1");
      rf.write_field("type", type.data(), n, 1, "1");
      rf.end_snapshot();
    }
    EXPECT_EQ(rf.snapshot_count(), 2u);
  }
  H5File f(path);
  ASSERT_GE(f.id, 0);
  EXPECT_EQ(dims_of(f.id, "/snapshots/000000/position"), (std::vector<hsize_t>{4, 3}));
  EXPECT_EQ(dims_of(f.id, "/snapshots/000001/position"), (std::vector<hsize_t>{6, 3}));
  EXPECT_EQ(dims_of(f.id, "/snapshots/000001/global_id"), (std::vector<hsize_t>{6}));
  EXPECT_EQ(read_all<double>(f.id, "/snapshots/000001/position", H5T_NATIVE_DOUBLE),
            rows(100, 6, 3));
  EXPECT_EQ(read_all<std::int64_t>(f.id, "/snapshots/000000/global_id", H5T_NATIVE_INT64),
            (std::vector<std::int64_t>{1000, 1001, 1002, 1003}));
  EXPECT_EQ(read_all<std::int32_t>(f.id, "/snapshots/000000/type", H5T_NATIVE_INT32),
            (std::vector<std::int32_t>(4, 2)));
  EXPECT_EQ(string_attr(f.id, "/snapshots/000000/velocity", "units"), "m/s");
  EXPECT_EQ(scalar_attr<double>(f.id, "/snapshots/000001", "time", H5T_NATIVE_DOUBLE), 1.0);
  EXPECT_EQ(scalar_attr<std::uint64_t>(f.id, "/snapshots/000001", "step", H5T_NATIVE_UINT64),
            2000u);
  EXPECT_EQ(read_all<double>(f.id, "/snapshots/times", H5T_NATIVE_DOUBLE),
            (std::vector<double>{0.5, 1.0}));
  EXPECT_EQ(read_all<std::int64_t>(f.id, "/snapshots/steps", H5T_NATIVE_INT64),
            (std::vector<std::int64_t>{1000, 2000}));
  EXPECT_EQ(string_attr(f.id, "/snapshots/times", "units"), "s");
}

TEST_F(RunFileTest, FieldWrittenInSlices) {
  // The MPI shape: each piece is rows [offset, offset + n) of the global field.
  const std::string path = file("run.h5");
  {
    RunFile rf(path, meta());
    rf.begin_snapshot(0.0, 0);
    const auto all = rows(0, 5, 3);
    rf.write_field("position", all.data() + 9, 2, 3, "m", FieldSlice{3, 5});
    rf.write_field("position", all.data(), 3, 3, "m", FieldSlice{0, 5});
    rf.end_snapshot();
  }
  H5File f(path);
  EXPECT_EQ(read_all<double>(f.id, "/snapshots/000000/position", H5T_NATIVE_DOUBLE), rows(0, 5, 3));
}

TEST_F(RunFileTest, EmptySnapshot) {
  const std::string path = file("run.h5");
  {
    RunFile rf(path, meta());
    rf.begin_snapshot(0.0, 0);
    rf.write_field("position", static_cast<const double*>(nullptr), 0, 3, "m");
    rf.end_snapshot();
  }
  H5File f(path);
  EXPECT_EQ(dims_of(f.id, "/snapshots/000000/position"), (std::vector<hsize_t>{0, 3}));
}

TEST_F(RunFileTest, XdmfIndexReferencesExistingDatasets) {
  const std::string path = file("run.h5");
  {
    RunFile rf(path, meta());
    EXPECT_EQ(rf.xdmf_path(), file("run.xmf"));
    for (int s = 0; s < 3; ++s) {
      rf.begin_snapshot(0.25 * s, 10u * s);
      const auto pos = rows(0, 4, 3);
      const std::vector<double> radius(4, 0.1);
      const std::vector<std::int64_t> bonds(4, 12);
      rf.write_field("position", pos.data(), 4, 3, "m");
      rf.write_field("velocity", pos.data(), 4, 3, "m/s");
      rf.write_field("radius", radius.data(), 4, 1, "m");
      rf.write_field("bond_count", bonds.data(), 4, 1, "1");
      rf.end_snapshot();
    }
    rf.write_xdmf(file("explicit.xmf"));
  }
  const std::string x = slurp(file("run.xmf"));
  EXPECT_TRUE(well_formed_xml(x)) << x;
  EXPECT_EQ(x, slurp(file("explicit.xmf")));
  EXPECT_NE(x.find("CollectionType=\"Temporal\""), std::string::npos);
  EXPECT_NE(x.find("TopologyType=\"Polyvertex\" NumberOfElements=\"4\""), std::string::npos);
  EXPECT_NE(x.find("GeometryType=\"XYZ\""), std::string::npos);
  EXPECT_NE(x.find("<Time Value=\"0.5\" />"), std::string::npos);
  EXPECT_NE(x.find("run.h5:/snapshots/000002/position"), std::string::npos);
  EXPECT_NE(x.find("Name=\"velocity\" AttributeType=\"Vector\""), std::string::npos);
  EXPECT_NE(x.find("Name=\"radius\" AttributeType=\"Scalar\""), std::string::npos);
  EXPECT_NE(x.find("NumberType=\"Int\" Precision=\"8\""), std::string::npos);

  // Every dataset the index names exists with the dimensions it claims.
  H5File f(path);
  ASSERT_GE(f.id, 0);
  const std::regex item(R"re(<DataItem Dimensions="([0-9 ]+)"[^>]*>run\.h5:([^<]+)</DataItem>)re");
  int items = 0;
  for (auto it = std::sregex_iterator(x.begin(), x.end(), item); it != std::sregex_iterator(); ++it) {
    const std::string ds = (*it)[2];
    ASSERT_TRUE(object_exists(f.id, ds)) << ds;
    std::string dims_text;
    for (hsize_t d : dims_of(f.id, ds)) {
      if (!dims_text.empty()) dims_text += ' ';
      dims_text += std::to_string(d);
    }
    EXPECT_EQ(dims_text, (*it)[1]) << ds;
    ++items;
  }
  EXPECT_EQ(items, 3 * 4);
}

namespace {
/// Child side of the kill test: never returns.
[[noreturn]] void child_writes_then_dies(const std::string& path, int flushes) {
  try {
    RunFile rf(path, meta());
    const int force = rf.add_series("/series/force", 3, "N", "force");
    const int time = rf.add_series("/series/time", 1, "s", "time");
    int row = 0;
    for (int k = 0; k < flushes; ++k) {
      for (int i = 0; i < 50; ++i, ++row) {
        const auto v = rows(row, 1, 3);
        rf.append(force, v.data());
        const double t = row * 1e-3;
        rf.append(time, &t);
      }
      rf.flush();
    }
    const auto pos = rows(0, 10, 3);
    rf.begin_snapshot(0.125, 7);
    rf.write_field("position", pos.data(), 10, 3, "m");
    rf.end_snapshot();  // flushes
    // Not flushed: must not appear, must not damage what was flushed.
    for (int i = 0; i < 500; ++i, ++row) {
      const auto v = rows(row, 1, 3);
      rf.append(force, v.data());
      const double t = row * 1e-3;
      rf.append(time, &t);
    }
    rf.add_series("/series/late", 1, "1", "declared after the last flush");
    rf.begin_snapshot(0.25, 8);
    rf.write_field("position", pos.data(), 10, 3, "m");
    ::raise(SIGKILL);
  } catch (...) {
  }
  ::_exit(3);
}
}  // namespace

TEST_F(RunFileTest, KilledChildLeavesExactlyTheFlushedData) {
  const std::string path = file("killed.h5");
  const int flushes = 40;
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) child_writes_then_dies(path, flushes);
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFSIGNALED(status)) << "child exited with " << WEXITSTATUS(status);
  ASSERT_EQ(WTERMSIG(status), SIGKILL);

  H5File f(path);
  ASSERT_GE(f.id, 0) << "file not readable after SIGKILL";
  const int n = 50 * flushes;
  EXPECT_EQ(dims_of(f.id, "/series/force"), (std::vector<hsize_t>{hsize_t(n), 3}));
  EXPECT_EQ(read_all<double>(f.id, "/series/force", H5T_NATIVE_DOUBLE), rows(0, n, 3));
  const auto t = read_all<double>(f.id, "/series/time", H5T_NATIVE_DOUBLE);
  ASSERT_EQ(t.size(), std::size_t(n));
  EXPECT_EQ(t.back(), (n - 1) * 1e-3);
  EXPECT_EQ(string_attr(f.id, "/series/force", "units"), "N");
  EXPECT_FALSE(object_exists(f.id, "/series/late"));
  EXPECT_EQ(read_all<double>(f.id, "/snapshots/times", H5T_NATIVE_DOUBLE), (std::vector<double>{0.125}));
  EXPECT_EQ(read_all<double>(f.id, "/snapshots/000000/position", H5T_NATIVE_DOUBLE), rows(0, 10, 3));
  EXPECT_FALSE(object_exists(f.id, "/snapshots/000001"));
  EXPECT_EQ(string_attr(f.id, "/", "scene"), meta().scene_text);
  // The index was rewritten at the last flush and names only flushed data.
  const std::string x = slurp(file("killed.xmf"));
  EXPECT_TRUE(well_formed_xml(x));
  EXPECT_NE(x.find("killed.h5:/snapshots/000000/position"), std::string::npos);
  EXPECT_EQ(x.find("000001"), std::string::npos);
}

TEST_F(RunFileTest, KilledRightAfterCreationIsReadable) {
  const std::string path = file("killed.h5");
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    try {
      RunFile rf(path, meta());
      const int s = rf.add_series("/series/force", 3, "N", "force");
      const double v[3] = {1, 2, 3};
      rf.append(s, v);
      ::raise(SIGKILL);
    } catch (...) {
    }
    ::_exit(3);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFSIGNALED(status));
  H5File f(path);
  ASSERT_GE(f.id, 0);
  EXPECT_EQ(string_attr(f.id, "/", "program_version"), "9.8.7-test");
  EXPECT_FALSE(object_exists(f.id, "/series/force"));
}

TEST_F(RunFileTest, MissingDirectoryThrowsInputErrorNamingThePath) {
  const std::string path = file("no/such/dir/run.h5");
  try {
    RunFile rf(path, meta());
    FAIL() << "expected hs::InputError";
  } catch (const hs::InputError& e) {
    EXPECT_EQ(e.path(), path);
    const std::string what = e.what();
    EXPECT_NE(what.find(path), std::string::npos) << what;
    EXPECT_NE(what.find("directory exists"), std::string::npos) << what;
  }
}

TEST_F(RunFileTest, SerialUseNeedsNoMpiInit) {
  // The Open MPI build of HDF5 with the default (sec2) driver runs without MPI_Init.
  RunFile rf(file("run.h5"), meta());
  rf.flush();
  int initialized = 1;
  MPI_Initialized(&initialized);
  EXPECT_EQ(initialized, 0);
}

TEST_F(RunFileTest, MisuseIsRejected) {
  RunFile rf(file("run.h5"), meta());
  const int s = rf.add_series("/series/force", 3, "N", "force");
  EXPECT_THROW(rf.add_series("/series/force", 3, "N", "again"), std::invalid_argument);
  EXPECT_THROW(rf.add_series("/series/force/x", 1, "N", "under a dataset"), std::invalid_argument);
  EXPECT_THROW(rf.add_series("series/relative", 1, "N", ""), std::invalid_argument);
  EXPECT_THROW(rf.add_series("/snapshots/x", 1, "N", ""), std::invalid_argument);
  EXPECT_THROW(rf.add_series("/series/zero", 0, "N", ""), std::invalid_argument);
  const std::int64_t i[3] = {1, 2, 3};
  EXPECT_THROW(rf.append(s, i), std::invalid_argument);
  EXPECT_THROW(rf.append(99, static_cast<const double*>(nullptr)), std::out_of_range);
  const double p[3] = {0, 0, 0};
  EXPECT_THROW(rf.write_field("position", p, 1, 3, "m"), std::logic_error);  // no begin_snapshot
  rf.begin_snapshot(0, 0);
  EXPECT_THROW(rf.write_field("position", p, 3, 1, "m"), std::invalid_argument);
  EXPECT_THROW(rf.write_field("a/b", p, 1, 3, "m"), std::invalid_argument);
  rf.write_field("position", p, 1, 3, "m", FieldSlice{0, 2});
  EXPECT_THROW(rf.end_snapshot(), std::invalid_argument);  // half the rows missing
  rf.close();
  EXPECT_FALSE(rf.is_open());
  EXPECT_THROW(rf.flush(), std::logic_error);
}

TEST_F(RunFileTest, MoveKeepsTheFileOpen) {
  const std::string path = file("run.h5");
  {
    RunFile a(path, meta());
    const int s = a.add_series("/series/x", 1, "m", "x");
    RunFile b(std::move(a));
    const double v = 4.0;
    b.append(s, &v);
  }
  H5File f(path);
  EXPECT_EQ(read_all<double>(f.id, "/series/x", H5T_NATIVE_DOUBLE), (std::vector<double>{4.0}));
}

// Output safety (issue 14): with write_to_partial an existing file is replaced only by a closed,
// complete file; a RunFile destroyed without close() (an abandoned run) leaves the old file and
// its index untouched and keeps its data under the partial name.
TEST_F(RunFileTest, PartialFileReplacesTheTargetOnlyAtClose) {
  const std::string target = file("run.h5");
  std::ofstream(target) << "old result";
  std::ofstream(file("run.xmf")) << "old index";
  RunFileMeta m = meta();
  m.write_to_partial = true;
  const auto pos = rows(0, 4, 3);
  std::string partial;
  {
    RunFile rf(target, m);
    partial = rf.writing_path();
    EXPECT_EQ(rf.path(), target);
    EXPECT_EQ(partial, hs::io::partial_path(target, std::to_string(::getpid())));
    EXPECT_EQ(fs::path(partial).filename().string(), "run.partial-" + std::to_string(::getpid()) + ".h5");
    const int s = rf.add_series("/series/x", 1, "m", "x");
    const double v = 2.5;
    rf.append(s, &v);
    rf.begin_snapshot(0.5, 3);
    rf.write_field("position", pos.data(), 4, 3, "m");
    rf.end_snapshot();
    EXPECT_EQ(slurp(target), "old result");
    EXPECT_EQ(slurp(file("run.xmf")), "old index");
  }  // destroyed without close(): abandoned
  EXPECT_EQ(slurp(target), "old result");
  EXPECT_EQ(slurp(file("run.xmf")), "old index");
  {
    H5File f(partial);
    ASSERT_GE(f.id, 0);
    EXPECT_EQ(read_all<double>(f.id, "/series/x", H5T_NATIVE_DOUBLE), (std::vector<double>{2.5}));
  }
  const std::string partial_index = (fs::path(partial).replace_extension(".xmf")).string();
  EXPECT_NE(slurp(partial_index).find(fs::path(partial).filename().string() + ":/snapshots/000000/position"),
            std::string::npos);
  fs::remove(partial);
  fs::remove(partial_index);

  RunFile rf(target, m);
  const int s = rf.add_series("/series/x", 1, "m", "x");
  const double v = 7.0;
  rf.append(s, &v);
  rf.begin_snapshot(0.5, 3);
  rf.write_field("position", pos.data(), 4, 3, "m");
  rf.end_snapshot();
  rf.close();
  EXPECT_EQ(rf.writing_path(), target);
  EXPECT_FALSE(fs::exists(partial));
  EXPECT_FALSE(fs::exists(partial_index));
  H5File f(target);
  ASSERT_GE(f.id, 0);
  EXPECT_EQ(read_all<double>(f.id, "/series/x", H5T_NATIVE_DOUBLE), (std::vector<double>{7.0}));
  const std::string x = slurp(file("run.xmf"));  // the index now names the committed file
  EXPECT_TRUE(well_formed_xml(x));
  EXPECT_NE(x.find(">run.h5:/snapshots/000000/position"), std::string::npos) << x;
}

// Without write_to_partial (the default) the file is written in place, as before.
TEST_F(RunFileTest, WithoutPartialTheTargetIsWrittenInPlace) {
  RunFile rf(file("direct.h5"), meta());
  EXPECT_EQ(rf.writing_path(), file("direct.h5"));
  EXPECT_TRUE(fs::exists(file("direct.h5")));
}
