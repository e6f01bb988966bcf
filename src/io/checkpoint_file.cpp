// Checkpoint files: see checkpoint_file.h for the layout and the atomic write.
#include "io/checkpoint_file.h"

#include "common/error.h"
#include "io/h5_handle.h"
#include "io/run_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <regex>
#include <stdexcept>

namespace hs::io {

namespace {

using h5::Handle;
namespace fs = std::filesystem;

const char* const kFormat = "hybridsim-checkpoint/1";

hid_t check_id(hid_t id, const char* call, const std::string& object, const std::string& file) {
  if (id < 0) h5::fail(call, object, file);
  return id;
}
void check(herr_t r, const char* call, const std::string& object, const std::string& file) {
  if (r < 0) h5::fail(call, object, file);
}

void put_attr(hid_t loc, const char* name, hid_t type, const void* v, const std::string& file) {
  Handle space(check_id(H5Screate(H5S_SCALAR), "H5Screate", name, file), H5Sclose);
  Handle a(check_id(H5Acreate2(loc, name, type, space.get(), H5P_DEFAULT, H5P_DEFAULT), "H5Acreate2", name, file),
           H5Aclose);
  check(H5Awrite(a.get(), type, v), "H5Awrite", name, file);
}
void put_str_attr(hid_t loc, const char* name, const std::string& s, const std::string& file) {
  Handle type(check_id(H5Tcopy(H5T_C_S1), "H5Tcopy", name, file), H5Tclose);
  check(H5Tset_size(type.get(), s.size() + 1), "H5Tset_size", name, file);
  put_attr(loc, name, type.get(), s.c_str(), file);
}
template <class T>
T get_attr(hid_t loc, const char* name, hid_t type, const std::string& file) {
  Handle a(check_id(H5Aopen(loc, name, H5P_DEFAULT), "H5Aopen", name, file), H5Aclose);
  T v{};
  check(H5Aread(a.get(), type, &v), "H5Aread", name, file);
  return v;
}
std::string get_str_attr(hid_t loc, const char* name, const std::string& file) {
  Handle a(check_id(H5Aopen(loc, name, H5P_DEFAULT), "H5Aopen", name, file), H5Aclose);
  Handle ft(check_id(H5Aget_type(a.get()), "H5Aget_type", name, file), H5Tclose);
  if (H5Tis_variable_str(ft.get()) > 0) {  // e.g. the run file's units
    Handle mt(check_id(H5Tcopy(H5T_C_S1), "H5Tcopy", name, file), H5Tclose);
    check(H5Tset_size(mt.get(), H5T_VARIABLE), "H5Tset_size", name, file);
    check(H5Tset_cset(mt.get(), H5Tget_cset(ft.get())), "H5Tset_cset", name, file);
    char* p = nullptr;
    check(H5Aread(a.get(), mt.get(), &p), "H5Aread", name, file);
    std::string s = p ? p : "";
    H5free_memory(p);
    return s;
  }
  const std::size_t n = H5Tget_size(ft.get());
  Handle mt(check_id(H5Tcopy(H5T_C_S1), "H5Tcopy", name, file), H5Tclose);
  check(H5Tset_size(mt.get(), n), "H5Tset_size", name, file);
  check(H5Tset_cset(mt.get(), H5Tget_cset(ft.get())), "H5Tset_cset", name, file);
  std::string s(n, '\0');
  check(H5Aread(a.get(), mt.get(), s.data()), "H5Aread", name, file);
  s.resize(std::strlen(s.c_str()));
  return s;
}

void write_bytes(hid_t loc, const std::string& name, const std::string& bytes, hid_t lcpl, const std::string& file) {
  const hsize_t n = bytes.size();
  Handle space(check_id(H5Screate_simple(1, &n, nullptr), "H5Screate_simple", name, file), H5Sclose);
  Handle d(check_id(H5Dcreate2(loc, name.c_str(), H5T_NATIVE_UINT8, space.get(), lcpl, H5P_DEFAULT, H5P_DEFAULT),
                    "H5Dcreate2", name, file),
           H5Dclose);
  if (n > 0) check(H5Dwrite(d.get(), H5T_NATIVE_UINT8, H5S_ALL, H5S_ALL, H5P_DEFAULT, bytes.data()), "H5Dwrite", name, file);
}

std::string read_bytes(hid_t loc, const std::string& name, const std::string& file) {
  Handle d(check_id(H5Dopen2(loc, name.c_str(), H5P_DEFAULT), "H5Dopen2", name, file), H5Dclose);
  Handle space(check_id(H5Dget_space(d.get()), "H5Dget_space", name, file), H5Sclose);
  const hssize_t n = H5Sget_simple_extent_npoints(space.get());
  if (n < 0) h5::fail("H5Sget_simple_extent_npoints", name, file);
  std::string s(static_cast<std::size_t>(n), '\0');
  if (n > 0) check(H5Dread(d.get(), H5T_NATIVE_UINT8, H5S_ALL, H5S_ALL, H5P_DEFAULT, s.data()), "H5Dread", name, file);
  return s;
}

Handle open_read(const std::string& path, const std::string& option) {
  if (!fs::exists(path))
    throw InputError(option, option == "--restart"
                                 ? "no checkpoint file '" + path +
                                       "': the run wrote none (time.checkpoint_interval = 0 and it was not stopped by "
                                       "SIGINT/SIGTERM), or it was moved"
                                 : "no file '" + path + "'");
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  const hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (f < 0) throw InputError(option, "cannot open '" + path + "' as HDF5 (" + h5::error_stack_text() + ")");
  return Handle(f, H5Fclose);
}

}  // namespace

std::string strip_partial(const std::string& run_path) {
  fs::path p(run_path);
  static const std::regex partial(R"((.*)\.partial-[0-9]+)");
  std::smatch m;
  const std::string stem = p.stem().string();
  if (std::regex_match(stem, m, partial)) p.replace_filename(m[1].str() + p.extension().string());
  return p.string();
}

std::string checkpoint_path(const std::string& run_path) {
  fs::path p(strip_partial(run_path));
  p.replace_filename(p.stem().string() + ".ckpt" + (p.has_extension() ? p.extension().string() : std::string(".h5")));
  return p.string();
}

std::string text_hash(const std::string& text) {
  std::uint64_t h = 1469598103934665603ull;
  for (const unsigned char c : text) {
    h ^= c;
    h *= 1099511628211ull;
  }
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(h));
  return buf;
}

void write_checkpoint(const std::string& path, const CheckpointMeta& meta, const std::vector<StateArchive>& ranks) {
  fs::path target(path);
  fs::path tmp = target;
  tmp.replace_filename(target.stem().string() + ".tmp-" + std::to_string(::getpid()) + target.extension().string());
  const std::string t = tmp.string();
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  try {
    {
      Handle f(check_id(H5Fcreate(t.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), "H5Fcreate", "/", t), H5Fclose);
      Handle g(check_id(H5Gcreate2(f.get(), "/checkpoint", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), "H5Gcreate2",
                        "/checkpoint", t),
               H5Gclose);
      put_str_attr(g.get(), "format", kFormat, t);
      put_attr(g.get(), "step", H5T_NATIVE_UINT64, &meta.step, t);
      put_attr(g.get(), "time", H5T_NATIVE_DOUBLE, &meta.time, t);
      put_attr(g.get(), "ranks", H5T_NATIVE_INT, &meta.ranks, t);
      put_attr(g.get(), "series_rows", H5T_NATIVE_UINT64, &meta.series_rows, t);
      put_attr(g.get(), "snapshots", H5T_NATIVE_UINT64, &meta.snapshots, t);
      put_str_attr(g.get(), "scene_hash", meta.scene_hash, t);
      put_str_attr(g.get(), "program_version", meta.program_version, t);
      put_str_attr(g.get(), "run_file", meta.run_file, t);
      Handle lcpl(check_id(H5Pcreate(H5P_LINK_CREATE), "H5Pcreate", "/", t), H5Pclose);
      check(H5Pset_create_intermediate_group(lcpl.get(), 1), "H5Pset_create_intermediate_group", "/", t);
      write_bytes(g.get(), "scene", meta.scene_text, lcpl.get(), t);  // a dataset: no 64 KiB attribute limit
      if (!meta.restart_changes.empty()) write_bytes(g.get(), "restart_changes", meta.restart_changes, lcpl.get(), t);
      for (std::size_t r = 0; r < ranks.size(); ++r) {
        const std::string rg = "rank_" + std::to_string(r);
        Handle gr(check_id(H5Gcreate2(g.get(), rg.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), "H5Gcreate2", rg, t),
                  H5Gclose);
        for (const auto& [k, v] : ranks[r].entries) write_bytes(gr.get(), k, v, lcpl.get(), t);
      }
      check(H5Fflush(f.get(), H5F_SCOPE_GLOBAL), "H5Fflush", "/", t);
      const hid_t id = f.release();
      check(H5Fclose(id), "H5Fclose", "/", t);
    }
    const int fd = ::open(t.c_str(), O_RDONLY);
    if (fd >= 0) {
      ::fsync(fd);
      ::close(fd);
    }
    std::error_code ec;
    fs::rename(tmp, target, ec);
    if (ec) throw std::runtime_error("cannot rename '" + t + "' to '" + path + "': " + ec.message());
  } catch (...) {
    std::error_code ec;
    fs::remove(tmp, ec);
    throw;
  }
}

CheckpointMeta read_checkpoint_meta(const std::string& path, const std::string& option) {
  Handle f = open_read(path, option);
  if (H5Lexists(f.get(), "/checkpoint", H5P_DEFAULT) <= 0)
    throw InputError(option, "'" + path + "' holds no checkpoint (/checkpoint is missing)");
  Handle g(check_id(H5Gopen2(f.get(), "/checkpoint", H5P_DEFAULT), "H5Gopen2", "/checkpoint", path), H5Gclose);
  CheckpointMeta m;
  if (get_str_attr(g.get(), "format", path) != kFormat)
    throw InputError(option, "'" + path + "' is a checkpoint of another format (expected " + kFormat + ")");
  m.step = get_attr<std::uint64_t>(g.get(), "step", H5T_NATIVE_UINT64, path);
  m.time = get_attr<double>(g.get(), "time", H5T_NATIVE_DOUBLE, path);
  m.ranks = get_attr<int>(g.get(), "ranks", H5T_NATIVE_INT, path);
  m.series_rows = get_attr<std::uint64_t>(g.get(), "series_rows", H5T_NATIVE_UINT64, path);
  m.snapshots = get_attr<std::uint64_t>(g.get(), "snapshots", H5T_NATIVE_UINT64, path);
  m.scene_hash = get_str_attr(g.get(), "scene_hash", path);
  m.program_version = get_str_attr(g.get(), "program_version", path);
  m.run_file = get_str_attr(g.get(), "run_file", path);
  m.scene_text = read_bytes(g.get(), "scene", path);
  if (H5Lexists(g.get(), "restart_changes", H5P_DEFAULT) > 0) m.restart_changes = read_bytes(g.get(), "restart_changes", path);
  return m;
}

namespace {
herr_t collect_dataset(hid_t loc, const char* name, const H5L_info_t*, void* data) {
  H5O_info_t info;
  if (H5Oget_info_by_name(loc, name, &info, H5P_DEFAULT) < 0) return -1;
  if (info.type == H5O_TYPE_DATASET) static_cast<std::vector<std::string>*>(data)->push_back(name);
  return 0;
}
}  // namespace

StateArchive read_checkpoint_rank(const std::string& path, int rank, const std::string& option) {
  Handle f = open_read(path, option);
  const std::string g = "/checkpoint/rank_" + std::to_string(rank);
  if (H5Lexists(f.get(), "/checkpoint", H5P_DEFAULT) <= 0 || H5Lexists(f.get(), g.c_str(), H5P_DEFAULT) <= 0)
    throw InputError(option, "'" + path + "' holds no state for rank " + std::to_string(rank));
  Handle grp(check_id(H5Gopen2(f.get(), g.c_str(), H5P_DEFAULT), "H5Gopen2", g, path), H5Gclose);
  std::vector<std::string> names;
  check(H5Lvisit(grp.get(), H5_INDEX_NAME, H5_ITER_INC, collect_dataset, &names), "H5Lvisit", g, path);
  StateArchive a;
  for (const auto& n : names) a.entries[n] = read_bytes(grp.get(), n, path);
  return a;
}

std::vector<SeriesRows> read_series_rows(const std::string& path, std::uint64_t all_rows, const std::string& group) {
  if (!fs::exists(path)) throw InputError("--restart", "no run file '" + path + "'");
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  const hid_t fid = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (fid < 0) throw InputError("--restart", "cannot open the run file '" + path + "' (" + h5::error_stack_text() + ")");
  Handle f(fid, H5Fclose);
  std::vector<SeriesRows> out;
  if (H5Lexists(f.get(), group.c_str(), H5P_DEFAULT) <= 0) {
    if (group != "/series") return out;
    throw InputError("--restart", "the run file '" + path + "' has no /series");
  }
  Handle grp(check_id(H5Gopen2(f.get(), group.c_str(), H5P_DEFAULT), "H5Gopen2", group, path), H5Gclose);
  std::vector<std::string> names;
  check(H5Lvisit(grp.get(), H5_INDEX_NAME, H5_ITER_INC, collect_dataset, &names), "H5Lvisit", group, path);
  for (const auto& n : names) {
    SeriesRows s;
    s.path = group + "/" + n;
    Handle d(check_id(H5Dopen2(grp.get(), n.c_str(), H5P_DEFAULT), "H5Dopen2", s.path, path), H5Dclose);
    Handle space(check_id(H5Dget_space(d.get()), "H5Dget_space", s.path, path), H5Sclose);
    const int rank = H5Sget_simple_extent_ndims(space.get());
    hsize_t dims[2] = {0, 1};
    if (rank < 1 || rank > 2 || H5Sget_simple_extent_dims(space.get(), dims, nullptr) < 0)
      throw InputError("--restart", "series '" + s.path + "' in '" + path + "' is not 1-D or 2-D");
    s.width = rank == 2 ? static_cast<int>(dims[1]) : 1;
    const std::uint64_t rows = all_rows == kAllRows ? dims[0] : all_rows;
    if (dims[0] < rows)
      throw InputError("--restart", "the run file '" + path + "' holds " + std::to_string(dims[0]) + " rows of " +
                                        s.path + ", the checkpoint needs " + std::to_string(rows) +
                                        " (is it the run file of this checkpoint?)");
    s.rows = rows;
    Handle type(check_id(H5Dget_type(d.get()), "H5Dget_type", s.path, path), H5Tclose);
    s.integer = H5Tget_class(type.get()) == H5T_INTEGER;
    const hsize_t start[2] = {0, 0}, count[2] = {rows, dims[1]};
    if (rank == 1) {
      const hsize_t st1 = 0, c1 = rows;
      check(H5Sselect_hyperslab(space.get(), H5S_SELECT_SET, &st1, nullptr, &c1, nullptr), "H5Sselect_hyperslab", s.path, path);
    } else {
      check(H5Sselect_hyperslab(space.get(), H5S_SELECT_SET, start, nullptr, count, nullptr), "H5Sselect_hyperslab",
            s.path, path);
    }
    const hsize_t nval = rows * static_cast<hsize_t>(s.width);
    Handle mem(check_id(H5Screate_simple(1, &nval, nullptr), "H5Screate_simple", s.path, path), H5Sclose);
    if (s.integer) {
      s.i64.resize(nval);
      if (nval) check(H5Dread(d.get(), H5T_NATIVE_INT64, mem.get(), space.get(), H5P_DEFAULT, s.i64.data()), "H5Dread", s.path, path);
    } else {
      s.f64.resize(nval);
      if (nval) check(H5Dread(d.get(), H5T_NATIVE_DOUBLE, mem.get(), space.get(), H5P_DEFAULT, s.f64.data()), "H5Dread", s.path, path);
    }
    out.push_back(std::move(s));
  }
  return out;
}

void copy_snapshots(const std::string& src, std::uint64_t count, RunFile& dst, int rank, int ranks) {
  if (count == 0) return;
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  const hid_t fid = H5Fopen(src.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (fid < 0) throw InputError("--restart", "cannot open the run file '" + src + "' (" + h5::error_stack_text() + ")");
  Handle f(fid, H5Fclose);
  for (std::uint64_t s = 0; s < count; ++s) {
    char name[32];
    std::snprintf(name, sizeof name, "/snapshots/%06llu", static_cast<unsigned long long>(s));
    if (H5Lexists(f.get(), "/snapshots", H5P_DEFAULT) <= 0 || H5Lexists(f.get(), name, H5P_DEFAULT) <= 0)
      throw InputError("--restart", "the run file '" + src + "' holds no snapshot " + name + ", the checkpoint counts " +
                                        std::to_string(count));
    Handle g(check_id(H5Gopen2(f.get(), name, H5P_DEFAULT), "H5Gopen2", name, src), H5Gclose);
    const double time = get_attr<double>(g.get(), "time", H5T_NATIVE_DOUBLE, src);
    const auto step = get_attr<std::uint64_t>(g.get(), "step", H5T_NATIVE_UINT64, src);
    std::vector<std::string> fields;
    check(H5Lvisit(g.get(), H5_INDEX_NAME, H5_ITER_INC, collect_dataset, &fields), "H5Lvisit", name, src);
    dst.begin_snapshot(time, step);
    for (const auto& fn : fields) {
      const std::string obj = std::string(name) + "/" + fn;
      Handle d(check_id(H5Dopen2(g.get(), fn.c_str(), H5P_DEFAULT), "H5Dopen2", obj, src), H5Dclose);
      Handle space(check_id(H5Dget_space(d.get()), "H5Dget_space", obj, src), H5Sclose);
      hsize_t dims[2] = {0, 1};
      const int nd = H5Sget_simple_extent_ndims(space.get());
      if (nd < 1 || nd > 2 || H5Sget_simple_extent_dims(space.get(), dims, nullptr) < 0)
        throw InputError("--restart", "snapshot field " + obj + " in '" + src + "' is not 1-D or 2-D");
      const std::uint64_t rows = dims[0];
      const int width = nd == 2 ? static_cast<int>(dims[1]) : 1;
      // This rank's equal share of the rows.
      const std::uint64_t lo = rows * static_cast<std::uint64_t>(rank) / static_cast<std::uint64_t>(ranks);
      const std::uint64_t hi = rows * static_cast<std::uint64_t>(rank + 1) / static_cast<std::uint64_t>(ranks);
      const std::uint64_t n = hi - lo;
      const hsize_t start[2] = {lo, 0}, cnt[2] = {n, static_cast<hsize_t>(width)};
      check(H5Sselect_hyperslab(space.get(), H5S_SELECT_SET, start, nullptr, cnt, nullptr), "H5Sselect_hyperslab", obj,
            src);
      const hsize_t nval = n * static_cast<hsize_t>(width);
      Handle mem(check_id(H5Screate_simple(1, &nval, nullptr), "H5Screate_simple", obj, src), H5Sclose);
      Handle type(check_id(H5Dget_type(d.get()), "H5Dget_type", obj, src), H5Tclose);
      std::string units;
      if (H5Aexists(d.get(), "units") > 0) units = get_str_attr(d.get(), "units", src);
      const FieldSlice slice{lo, rows};
      if (H5Tget_class(type.get()) == H5T_FLOAT) {
        std::vector<double> v(nval);
        if (nval) check(H5Dread(d.get(), H5T_NATIVE_DOUBLE, mem.get(), space.get(), H5P_DEFAULT, v.data()), "H5Dread", obj, src);
        dst.write_field(fn, v.data(), n, width, units, slice);
      } else if (H5Tget_size(type.get()) <= 4) {
        std::vector<std::int32_t> v(nval);
        if (nval) check(H5Dread(d.get(), H5T_NATIVE_INT32, mem.get(), space.get(), H5P_DEFAULT, v.data()), "H5Dread", obj, src);
        dst.write_field(fn, v.data(), n, width, units, slice);
      } else {
        std::vector<std::int64_t> v(nval);
        if (nval) check(H5Dread(d.get(), H5T_NATIVE_INT64, mem.get(), space.get(), H5P_DEFAULT, v.data()), "H5Dread", obj, src);
        dst.write_field(fn, v.data(), n, width, units, slice);
      }
    }
    dst.end_snapshot();
  }
}

}  // namespace hs::io
