// RunFile: see run_file.h for the layout, the durability rule and the MPI notes.
#include "io/run_file.h"

#include "io/h5_handle.h"

#include <fcntl.h>
#include <hdf5.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <utility>
#include <vector>

#include "common/error.h"
#include "parallel/comm.h"

#include <mpi.h>

namespace hs::io {
namespace {

using h5::Handle;
using h5::fail;

// ---------------------------------------------------------------- HDF5 plumbing

enum class Elem { f64, i64, i32 };

std::size_t elem_size(Elem e) { return e == Elem::i32 ? 4 : 8; }
hid_t mem_type(Elem e) {
  switch (e) {
    case Elem::f64: return H5T_NATIVE_DOUBLE;
    case Elem::i64: return H5T_NATIVE_INT64;
    case Elem::i32: return H5T_NATIVE_INT32;
  }
  return H5T_NATIVE_DOUBLE;
}
hid_t file_type(Elem e) {
  switch (e) {
    case Elem::f64: return H5T_IEEE_F64LE;
    case Elem::i64: return H5T_STD_I64LE;
    case Elem::i32: return H5T_STD_I32LE;
  }
  return H5T_IEEE_F64LE;
}
const char* elem_name(Elem e) {
  switch (e) {
    case Elem::f64: return "double";
    case Elem::i64: return "int64";
    case Elem::i32: return "int32";
  }
  return "?";
}

std::string iso_time_utc_now() {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

std::string xml_escape(const std::string& s) {
  std::string out;
  out.reserve(s.size());
  for (char c : s) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&apos;"; break;
      default: out += c;
    }
  }
  return out;
}

std::string fmt_double(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

/// "/a/b/c": absolute, no empty, "." or ".." components, no trailing slash.
bool valid_object_path(const std::string& p) {
  if (p.size() < 2 || p.front() != '/' || p.back() == '/') return false;
  std::size_t start = 1;
  while (start <= p.size()) {
    std::size_t end = p.find('/', start);
    if (end == std::string::npos) end = p.size();
    const std::string part = p.substr(start, end - start);
    if (part.empty() || part == "." || part == "..") return false;
    start = end + 1;
  }
  return true;
}

bool is_prefix_path(const std::string& parent, const std::string& child) {
  return child.size() > parent.size() && child.compare(0, parent.size(), parent) == 0 &&
         child[parent.size()] == '/';
}

const char* xdmf_attribute_type(int width) {
  switch (width) {
    case 1: return "Scalar";
    case 3: return "Vector";
    case 6: return "Tensor6";
    case 9: return "Tensor";
    default: return "Matrix";
  }
}

/// Rows per chunk of a series dataset of `width` values: about 32 KiB, at least 64 rows.
hsize_t chunk_rows_for(int width) { return std::max<hsize_t>(64, 4096 / static_cast<hsize_t>(width)); }

std::uint64_t ceil_div(std::uint64_t a, std::uint64_t b) { return (a + b - 1) / b; }

/// An HDF5 error text that reports a full disk or the file size limit (the sec2 driver prints errno).
bool mentions_no_space(const std::string& text) {
  return text.find("errno = 28") != std::string::npos || text.find("errno = 27") != std::string::npos ||
         text.find("No space left") != std::string::npos || text.find("File too large") != std::string::npos;
}

}  // namespace

std::string partial_path(const std::string& path, const std::string& id) {
  const std::filesystem::path p(path);
  std::filesystem::path out = p;
  out.replace_filename(p.stem().string() + ".partial-" + id + p.extension().string());
  return out.string();
}

// ---------------------------------------------------------------- Impl

struct RunFile::Impl {
  struct Series {
    std::string path;
    int width = 1;
    std::string units, description;
    Elem type = Elem::f64;
    std::vector<double> buf_f64;
    std::vector<std::int64_t> buf_i64;
    std::uint64_t rows_written = 0;  // in the file
    std::uint64_t rows_total = 0;    // appended
    Handle dset;                     // created at the first flush
  };
  struct Slice {
    std::uint64_t offset = 0, n = 0;
    std::vector<unsigned char> bytes;
  };
  struct PendingField {
    std::string name;
    Elem type = Elem::f64;
    int width = 1;
    std::string units;
    std::uint64_t global_count = 0;
    std::vector<Slice> slices;
  };
  struct FieldInfo {
    std::string name;
    Elem type;
    int width;
    std::uint64_t count;
  };
  struct SnapshotInfo {
    std::string group;  // "/snapshots/000000"
    double time;
    std::uint64_t step;
    std::vector<FieldInfo> fields;
  };

  std::string path;         // the file HDF5 writes: target, or its partial name (write_to_partial)
  std::string target;       // where the result ends up (RunFile::path())
  std::string xdmf_path;    // the index written at each flush (next to `path`)
  std::string xdmf_target;  // the index of the committed file
  RunFileMeta meta;
  Handle file;
  /// A reservation or a flush failed: the file holds the last complete flush; close() must not
  /// write again (a failing H5Fclose leaves HDF5 to crash in its exit handler).
  bool write_failed = false;

  std::vector<Series> series;
  std::size_t buffered_bytes = 0;

  bool in_snapshot = false;
  double snap_time = 0.0;
  std::uint64_t snap_step = 0;
  std::vector<PendingField> pending;
  std::vector<SnapshotInfo> snapshots;
  Handle snapshots_group, times_dset, steps_dset;
  bool xdmf_dirty = false;

  // ---- checked HDF5 calls ----
  hid_t check_id(hid_t id, const char* call, const std::string& object) const {
    if (id < 0) fail(call, object, path);
    return id;
  }
  void check(herr_t e, const char* call, const std::string& object) const {
    if (e < 0) fail(call, object, path);
  }

  void write_string_attr(hid_t obj, const char* name, const std::string& value,
                         const std::string& object) const {
    Handle type(check_id(H5Tcopy(H5T_C_S1), "H5Tcopy", object), H5Tclose);
    check(H5Tset_size(type.get(), H5T_VARIABLE), "H5Tset_size", object);
    check(H5Tset_cset(type.get(), H5T_CSET_UTF8), "H5Tset_cset", object);
    Handle space(check_id(H5Screate(H5S_SCALAR), "H5Screate", object), H5Sclose);
    Handle attr(check_id(H5Acreate2(obj, name, type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT),
                         "H5Acreate2", object + "@" + name),
                H5Aclose);
    const char* p = value.c_str();
    check(H5Awrite(attr.get(), type.get(), &p), "H5Awrite", object + "@" + name);
  }

  void write_scalar_attr(hid_t obj, const char* name, hid_t ftype, hid_t mtype, const void* value,
                         const std::string& object) const {
    Handle space(check_id(H5Screate(H5S_SCALAR), "H5Screate", object), H5Sclose);
    Handle attr(check_id(H5Acreate2(obj, name, ftype, space.get(), H5P_DEFAULT, H5P_DEFAULT),
                         "H5Acreate2", object + "@" + name),
                H5Aclose);
    check(H5Awrite(attr.get(), mtype, value), "H5Awrite", object + "@" + name);
  }

  /// Chunked dataset of 0 rows that grows along its first dimension (1-D when width == 1).
  Handle create_extendible(const std::string& object, Elem type, int width) const {
    const int rank = width == 1 ? 1 : 2;
    const hsize_t dims[2] = {0, static_cast<hsize_t>(width)};
    const hsize_t maxdims[2] = {H5S_UNLIMITED, static_cast<hsize_t>(width)};
    // About 32 KiB per chunk, at least 64 rows.
    const hsize_t chunk_rows = chunk_rows_for(width);
    const hsize_t chunk[2] = {chunk_rows, static_cast<hsize_t>(width)};
    Handle space(check_id(H5Screate_simple(rank, dims, maxdims), "H5Screate_simple", object),
                 H5Sclose);
    Handle dcpl(check_id(H5Pcreate(H5P_DATASET_CREATE), "H5Pcreate", object), H5Pclose);
    check(H5Pset_chunk(dcpl.get(), rank, chunk), "H5Pset_chunk", object);
    Handle lcpl(check_id(H5Pcreate(H5P_LINK_CREATE), "H5Pcreate", object), H5Pclose);
    check(H5Pset_create_intermediate_group(lcpl.get(), 1), "H5Pset_create_intermediate_group",
          object);
    return Handle(check_id(H5Dcreate2(file.get(), object.c_str(), file_type(type), space.get(),
                                      lcpl.get(), dcpl.get(), H5P_DEFAULT),
                           "H5Dcreate2", object),
                  H5Dclose);
  }

  /// Appends `add` rows of `width` values to an extendible dataset holding `old_rows` rows.
  /// Under MPI every rank extends the dataset (collective) and rank 0 alone writes the rows
  /// (all ranks hold the same series rows).
  void append_rows(hid_t dset, const std::string& object, std::uint64_t old_rows, std::uint64_t add,
                   int width, Elem type, const void* data) const {
    if (add == 0) return;
    const int rank = width == 1 ? 1 : 2;
    const hsize_t new_dims[2] = {old_rows + add, static_cast<hsize_t>(width)};
    check(H5Dset_extent(dset, new_dims), "H5Dset_extent", object);
    if (series_writer()) write_rows(dset, object, old_rows, add, rank, width, type, data);
  }
  bool parallel() const { return meta.comm != nullptr && meta.comm->parallel(); }
  bool series_writer() const { return !parallel() || meta.comm->rank() == 0; }

  /// Writes rows [offset, offset + n) of an existing dataset.
  void write_rows(hid_t dset, const std::string& object, std::uint64_t offset, std::uint64_t n,
                  int rank, int width, Elem type, const void* data) const {
    if (n == 0) return;
    const hsize_t start[2] = {offset, 0};
    const hsize_t count[2] = {n, static_cast<hsize_t>(width)};
    Handle fspace(check_id(H5Dget_space(dset), "H5Dget_space", object), H5Sclose);
    check(H5Sselect_hyperslab(fspace.get(), H5S_SELECT_SET, start, nullptr, count, nullptr),
          "H5Sselect_hyperslab", object);
    Handle mspace(check_id(H5Screate_simple(rank, count, nullptr), "H5Screate_simple", object),
                  H5Sclose);
    check(H5Dwrite(dset, mem_type(type), mspace.get(), fspace.get(), H5P_DEFAULT, data), "H5Dwrite",
          object);
  }

  // ---- operations ----
  void flush_series() {
    for (Series& s : series) {
      if (!s.dset.valid()) {
        s.dset = create_extendible(s.path, s.type, s.width);
        write_string_attr(s.dset.get(), "units", s.units, s.path);
        write_string_attr(s.dset.get(), "description", s.description, s.path);
      }
      const std::uint64_t add = s.rows_total - s.rows_written;
      const void* data = s.type == Elem::f64 ? static_cast<const void*>(s.buf_f64.data())
                                             : static_cast<const void*>(s.buf_i64.data());
      append_rows(s.dset.get(), s.path, s.rows_written, add, s.width, s.type, data);
      s.rows_written = s.rows_total;
      s.buf_f64.clear();
      s.buf_i64.clear();
    }
    buffered_bytes = 0;
  }

  /// Upper bound of the bytes the next flush adds to the file: whole chunks for the buffered
  /// series rows, new datasets, B-tree nodes and a fixed margin for the rest of the metadata.
  std::uint64_t series_flush_bytes() const {
    std::uint64_t b = 64 * 1024;  // superblock, group heaps and B-trees, free-space slack
    for (const Series& s : series) {
      const std::uint64_t rows = chunk_rows_for(s.width);
      const std::uint64_t chunk = rows * static_cast<std::uint64_t>(s.width) * 8;
      if (!s.dset.valid()) b += 8192;  // object header, attributes, index (its chunk is counted below)
      const std::uint64_t chunks = ceil_div(s.rows_total, rows) - ceil_div(s.rows_written, rows);
      b += chunks * (chunk + 4096);  // each chunk and its share of a B-tree node
    }
    return b;
  }

  std::string no_space_text(int err) const {
    return "no space left for the output file '" + path + "' (" + std::strerror(err) +
           "); it holds the output up to the last complete flush";
  }

  /// Makes sure `bytes` more can be written past the file's end before HDF5 writes anything
  /// (serial files): on a full disk (ENOSPC) or at the file size limit (EFBIG) throws the
  /// "no space" error with the file still as the last complete flush left it. MPI-IO files
  /// are not checked (no descriptor).
  void reserve(std::uint64_t bytes) {
    if (parallel() || !file.valid()) return;
    void* handle = nullptr;
    haddr_t eoa = 0;
    if (H5Fget_vfd_handle(file.get(), H5P_DEFAULT, &handle) < 0 || handle == nullptr ||
        H5Fget_eoa(file.get(), &eoa) < 0) {
      h5::error_stack_text();  // (cleared) no reservation possible: write and see
      return;
    }
    const int fd = *static_cast<int*>(handle);
    // From the end of what is on disk when HDF5 has allocated space it has not written yet.
    struct stat st {};
    const haddr_t from = ::fstat(fd, &st) == 0 ? std::min<haddr_t>(eoa, static_cast<haddr_t>(st.st_size)) : eoa;
    const int rc = ::posix_fallocate(fd, static_cast<off_t>(from), static_cast<off_t>(eoa - from + bytes));
    if (rc == 0 || rc == EINVAL || rc == EOPNOTSUPP) return;  // (file system without it: unchecked)
    write_failed = true;
    // posix_fallocate may have extended the file partly: back to what HDF5 allocated.
    if (::ftruncate(fd, static_cast<off_t>(eoa)) != 0) { /* the tail past EOA is ignored by readers */ }
    throw std::runtime_error(no_space_text(rc));
  }

  /// The reserved space past HDF5's end of allocation is given back after a flush.
  void trim_to_eoa() {
    if (parallel()) return;
    void* handle = nullptr;
    haddr_t eoa = 0;
    if (H5Fget_vfd_handle(file.get(), H5P_DEFAULT, &handle) < 0 || handle == nullptr ||
        H5Fget_eoa(file.get(), &eoa) < 0) {
      h5::error_stack_text();
      return;
    }
    const int fd = *static_cast<int*>(handle);
    struct stat st {};
    if (::fstat(fd, &st) == 0 && static_cast<haddr_t>(st.st_size) > eoa &&
        ::ftruncate(fd, static_cast<off_t>(eoa)) != 0) { /* harmless: readers ignore bytes past EOA */ }
  }

  void flush() {
    if (!file.valid()) throw std::logic_error("hs::io::RunFile::flush: file '" + path + "' is closed");
    if (write_failed) throw std::runtime_error(no_space_text(ENOSPC));
    reserve(series_flush_bytes());
    try {
      flush_series();
      check(H5Fflush(file.get(), H5F_SCOPE_LOCAL), "H5Fflush", "/");
    } catch (const std::runtime_error& e) {
      write_failed = true;
      if (mentions_no_space(e.what())) throw std::runtime_error(no_space_text(ENOSPC) + ": " + e.what());
      throw;
    }
    trim_to_eoa();
    if (meta.fsync_on_flush && !parallel()) {  // (MPI-IO: the driver's handle is not a descriptor)
      void* handle = nullptr;
      check(H5Fget_vfd_handle(file.get(), H5P_DEFAULT, &handle), "H5Fget_vfd_handle", "/");
      if (handle != nullptr && ::fsync(*static_cast<int*>(handle)) != 0)
        throw std::runtime_error("fsync failed for '" + path + "': " + std::strerror(errno));
    }
    // After H5Fflush, so the index never names data that is not in the file yet.
    if (xdmf_dirty && meta.write_xdmf) {
      if (series_writer()) write_xdmf_atomic(xdmf_path);
      xdmf_dirty = false;
    }
  }

  void write_snapshot() {
    if (!snapshots_group.valid()) {
      snapshots_group = Handle(check_id(H5Gcreate2(file.get(), "/snapshots", H5P_DEFAULT,
                                                   H5P_DEFAULT, H5P_DEFAULT),
                                        "H5Gcreate2", "/snapshots"),
                               H5Gclose);
      times_dset = create_extendible("/snapshots/times", Elem::f64, 1);
      write_string_attr(times_dset.get(), "units", "s", "/snapshots/times");
      write_string_attr(times_dset.get(), "description", "simulated time of each snapshot",
                        "/snapshots/times");
      steps_dset = create_extendible("/snapshots/steps", Elem::i64, 1);
      write_string_attr(steps_dset.get(), "units", "1", "/snapshots/steps");
      write_string_attr(steps_dset.get(), "description", "time step number of each snapshot",
                        "/snapshots/steps");
    }
    const std::size_t index = snapshots.size();
    char name[32];
    std::snprintf(name, sizeof name, "/snapshots/%06zu", index);
    SnapshotInfo info{name, snap_time, snap_step, {}};

    Handle group(check_id(H5Gcreate2(file.get(), name, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
                          "H5Gcreate2", name),
                 H5Gclose);
    write_scalar_attr(group.get(), "time", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, &snap_time, name);
    write_scalar_attr(group.get(), "step", H5T_STD_U64LE, H5T_NATIVE_UINT64, &snap_step, name);

    for (const PendingField& f : pending) {
      const std::string object = info.group + "/" + f.name;
      const int rank = f.width == 1 ? 1 : 2;
      const hsize_t dims[2] = {f.global_count, static_cast<hsize_t>(f.width)};
      Handle space(check_id(H5Screate_simple(rank, dims, nullptr), "H5Screate_simple", object),
                   H5Sclose);
      // Contiguous: fixed size, and what collective MPI-IO writes handle best.
      Handle dset(check_id(H5Dcreate2(file.get(), object.c_str(), file_type(f.type), space.get(),
                                      H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
                           "H5Dcreate2", object),
                  H5Dclose);
      for (const Slice& s : f.slices)
        write_rows(dset.get(), object, s.offset, s.n, rank, f.width, f.type, s.bytes.data());
      write_string_attr(dset.get(), "units", f.units, object);
      info.fields.push_back({f.name, f.type, f.width, f.global_count});
    }

    append_rows(times_dset.get(), "/snapshots/times", index, 1, 1, Elem::f64, &snap_time);
    const auto step = static_cast<std::int64_t>(snap_step);
    append_rows(steps_dset.get(), "/snapshots/steps", index, 1, 1, Elem::i64, &step);
    snapshots.push_back(std::move(info));
    xdmf_dirty = true;
  }

  std::string xdmf_text(const std::string& h5_ref) const {
    std::string x;
    x += "<?xml version=\"1.0\" ?>\n";
    x += "<!DOCTYPE Xdmf SYSTEM \"Xdmf.dtd\" []>\n";
    x += "<Xdmf Version=\"3.0\" xmlns:xi=\"http://www.w3.org/2001/XInclude\">\n";
    x += "  <Domain>\n";
    x += "    <Grid Name=\"particles\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
    const std::string file_ref = xml_escape(h5_ref);
    auto data_item = [&](const FieldInfo& f, const std::string& group, const std::string& indent) {
      std::string d = indent + "<DataItem Dimensions=\"" + std::to_string(f.count);
      if (f.width != 1) {
        d += ' ';  // (not " " + to_string: GCC 12 -Wrestrict false positive)
        d += std::to_string(f.width);
      }
      d += "\" NumberType=\"";
      d += f.type == Elem::f64 ? "Float" : "Int";
      d += "\" Precision=\"" + std::to_string(elem_size(f.type)) + "\" Format=\"HDF\">";
      d += file_ref + ":" + xml_escape(group + "/" + f.name) + "</DataItem>\n";
      return d;
    };
    for (const SnapshotInfo& s : snapshots) {
      const FieldInfo* position = nullptr;
      for (const FieldInfo& f : s.fields)
        if (f.name == "position") position = &f;
      if (position == nullptr) continue;  // nothing to place the points with
      const std::string n = std::to_string(position->count);
      x += "      <Grid Name=\"" + xml_escape(s.group.substr(s.group.rfind('/') + 1)) +
           "\" GridType=\"Uniform\">\n";
      x += "        <Time Value=\"" + fmt_double(s.time) + "\" />\n";
      x += "        <Topology TopologyType=\"Polyvertex\" NumberOfElements=\"" + n +
           "\" NodesPerElement=\"1\" />\n";
      x += "        <Geometry GeometryType=\"XYZ\">\n";
      x += data_item(*position, s.group, "          ");
      x += "        </Geometry>\n";
      for (const FieldInfo& f : s.fields) {
        if (&f == position || f.count != position->count) continue;
        x += "        <Attribute Name=\"" + xml_escape(f.name) + "\" AttributeType=\"" +
             xdmf_attribute_type(f.width) + "\" Center=\"Node\">\n";
        x += data_item(f, s.group, "          ");
        x += "        </Attribute>\n";
      }
      x += "      </Grid>\n";
    }
    x += "    </Grid>\n";
    x += "  </Domain>\n";
    x += "</Xdmf>\n";
    return x;
  }

  /// How the XDMF file at `xpath` should name the HDF5 file: its bare name when both share a
  /// directory (the pair can be moved together), else its absolute path.
  std::string h5_reference_for(const std::string& xpath) const {
    namespace fs = std::filesystem;
    const fs::path h5 = fs::absolute(path).lexically_normal();
    const fs::path xd = fs::absolute(xpath).lexically_normal();
    if (h5.parent_path() == xd.parent_path()) return h5.filename().string();
    return h5.string();
  }

  void write_text_file(const std::string& target, const std::string& text) const {
    std::ofstream out(target, std::ios::binary | std::ios::trunc);
    out << text;
    out.close();
    if (!out) throw std::runtime_error("cannot write XDMF file '" + target + "'");
  }

  void write_xdmf_atomic(const std::string& xpath) const {
    const std::string tmp = xpath + ".tmp";
    write_text_file(tmp, xdmf_text(h5_reference_for(xpath)));
    std::error_code ec;
    std::filesystem::rename(tmp, xpath, ec);
    if (ec) throw std::runtime_error("cannot rename '" + tmp + "' to '" + xpath + "': " + ec.message());
  }

  /// `commit`: an explicit close(); with write_to_partial the partial file then replaces the target.
  void close(bool commit) {
    if (!file.valid()) return;
    std::exception_ptr error;
    try {
      in_snapshot = false;  // an unfinished snapshot is dropped
      pending.clear();
      if (!write_failed) flush();
    } catch (...) {
      error = std::current_exception();
    }
    for (Series& s : series) s.dset.reset();
    times_dset.reset();
    steps_dset.reset();
    snapshots_group.reset();
    const hid_t id = file.release();  // closed here, with the result checked
    if (H5Fclose(id) < 0 && !error) fail("H5Fclose", "/", path);
    if (error) std::rethrow_exception(error);
    if (commit && write_failed) throw std::runtime_error(no_space_text(ENOSPC));
    if (commit && path != target) commit_partial();
  }

  /// Renames the closed partial file (and its index) over the target. Under MPI rank 0 renames
  /// and every rank learns the outcome, so all throw or none.
  void commit_partial() {
    std::string err;
    if (series_writer()) {
      std::error_code ec;
      std::filesystem::rename(path, target, ec);
      if (ec) {
        err = "cannot rename '" + path + "' to '" + target + "': " + ec.message() + "; the output is in '" + path + "'";
      } else if (meta.write_xdmf) {
        std::filesystem::remove(xdmf_path, ec);
        if (snapshots.empty()) {
          std::filesystem::remove(xdmf_target, ec);  // an index of an older run would name missing data
        } else {
          const std::string written = path;
          path = target;  // the index names the committed file
          try {
            write_xdmf_atomic(xdmf_target);
          } catch (const std::exception& e) {
            err = e.what();
          }
          path = written;
        }
      }
    }
    if (parallel()) err = meta.comm->broadcast(err);
    path = target;
    xdmf_path = xdmf_target;
    if (!err.empty()) throw std::runtime_error(err);
  }

  int add_series(const std::string& path, int width, const std::string& units,
                 const std::string& description, Elem type);
  void add_field(const std::string& name, const void* data, std::size_t n, int width,
                 const std::string& units, FieldSlice slice, Elem type);

  // ---- argument checks ----
  Series& series_at(int id, const char* fn) {
    if (id < 0 || static_cast<std::size_t>(id) >= series.size())
      throw std::out_of_range(std::string("hs::io::RunFile::") + fn + ": no series with id " +
                              std::to_string(id));
    return series[static_cast<std::size_t>(id)];
  }
  void require_open(const char* fn) const {
    if (!file.valid())
      throw std::logic_error(std::string("hs::io::RunFile::") + fn + ": file '" + path +
                             "' is closed");
  }
};

// ---------------------------------------------------------------- RunFile

RunFile::Impl& RunFile::impl() const {
  if (!impl_) throw std::logic_error("hs::io::RunFile used after being moved from");
  return *impl_;
}

RunFile::RunFile(const std::string& path, RunFileMeta meta) : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.path = m.target = path;
  m.meta = std::move(meta);
  if (m.meta.write_xdmf) {
    m.xdmf_path = m.xdmf_target = m.meta.xdmf_path.empty()
                                      ? std::filesystem::path(path).replace_extension(".xmf").string()
                                      : m.meta.xdmf_path;
  }
  if (m.meta.write_to_partial) {  // rank 0 names it; every rank opens the same partial file
    const std::string id = m.parallel() ? m.meta.comm->broadcast(std::to_string(::getpid()))
                                        : std::to_string(::getpid());
    m.path = partial_path(path, id);
    if (m.meta.write_xdmf) m.xdmf_path = partial_path(m.xdmf_target, id);
  }
  // Errors become exceptions; HDF5 must not print its stack itself.
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);

  Handle fapl(m.check_id(H5Pcreate(H5P_FILE_ACCESS), "H5Pcreate", "/"), H5Pclose);
  if (m.parallel())  // one file for all ranks, through MPI-IO
    m.check(H5Pset_fapl_mpio(fapl.get(), reinterpret_cast<MPI_Comm>(m.meta.comm->native()), MPI_INFO_NULL),
            "H5Pset_fapl_mpio", "/");
  // 1.8 format: readable everywhere, dense attribute storage, no v3 superblock status flags.
  m.check(H5Pset_libver_bounds(fapl.get(), H5F_LIBVER_V18, H5F_LIBVER_V18), "H5Pset_libver_bounds",
          "/");
  // Lock where the file system can; do not fail where it cannot (some NFS/Lustre mounts).
  m.check(H5Pset_file_locking(fapl.get(), 1, 1), "H5Pset_file_locking", "/");
  const hid_t f = H5Fcreate(m.path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl.get());
  if (f < 0) {
    const std::string detail = h5::error_stack_text();
    throw InputError(m.path,
                     "cannot create the HDF5 output file; check that the directory exists and is "
                     "writable, and that no other program has the file open" +
                         (detail.empty() ? std::string() : " (HDF5: " + detail + ")"));
  }
  m.file = Handle(f, H5Fclose);
  try {
    m.reserve(m.meta.scene_text.size() + 65536);  // the root attributes
    const hid_t root = m.file.get();
    m.write_string_attr(root, "scene", m.meta.scene_text, "/");
    m.write_string_attr(root, "program_version", m.meta.program_version, "/");
    for (const auto& [name, value] : m.meta.root_attributes) m.write_string_attr(root, name.c_str(), value, "/");
    // Attribute values must agree on every rank: rank 0's clock.
    const std::string created = m.parallel() ? m.meta.comm->broadcast(iso_time_utc_now()) : iso_time_utc_now();
    m.write_string_attr(root, "created", created, "/");
    m.write_string_attr(root, "file_format", "hybridsim-run/1", "/");
    m.flush();
  } catch (...) {
    m.file.reset();
    if (m.path != m.target && m.series_writer()) {  // nothing of a run in it: no partial file left
      std::error_code ec;
      std::filesystem::remove(m.path, ec);
    }
    throw;
  }
}

RunFile::~RunFile() {
  if (!impl_) return;
  try {
    impl_->close(false);  // not committed: a partial file keeps its name
  } catch (const std::exception& e) {
    std::fprintf(stderr, "hs::io::RunFile: closing '%s' failed: %s\n", impl_->path.c_str(), e.what());
  }
}

RunFile::RunFile(RunFile&&) noexcept = default;
RunFile& RunFile::operator=(RunFile&& o) noexcept {
  if (this != &o) {
    RunFile old(std::move(*this));  // closes ours
    impl_ = std::move(o.impl_);
  }
  return *this;
}

int RunFile::Impl::add_series(const std::string& path, int width, const std::string& units,
                                const std::string& description, Elem type) {
  Impl& m = *this;
  m.require_open("add_series");
  if (!valid_object_path(path))
    throw std::invalid_argument("hs::io::RunFile::add_series: '" + path +
                                "' is not an absolute HDF5 path like /series/force");
  if (width < 1)
    throw std::invalid_argument("hs::io::RunFile::add_series: width of '" + path + "' must be >= 1");
  if (path == "/snapshots" || is_prefix_path("/snapshots", path))
    throw std::invalid_argument("hs::io::RunFile::add_series: '" + path + "' is under /snapshots");
  for (const auto& s : m.series) {
    if (s.path == path || is_prefix_path(s.path, path) || is_prefix_path(path, s.path))
      throw std::invalid_argument("hs::io::RunFile::add_series: '" + path +
                                  "' clashes with series '" + s.path + "'");
  }
  Series s;
  s.path = path;
  s.width = width;
  s.units = units;
  s.description = description;
  s.type = type;
  m.series.push_back(std::move(s));
  return static_cast<int>(m.series.size() - 1);
}

int RunFile::add_series(const std::string& path, int width, const std::string& units,
                        const std::string& description) {
  return impl().add_series(path, width, units, description, Elem::f64);
}

int RunFile::add_int_series(const std::string& path, int width, const std::string& units,
                            const std::string& description) {
  return impl().add_series(path, width, units, description, Elem::i64);
}

void RunFile::append(int series_id, const double* row) {
  Impl& m = impl();
  m.require_open("append");
  Impl::Series& s = m.series_at(series_id, "append");
  if (s.type != Elem::f64)
    throw std::invalid_argument("hs::io::RunFile::append: series '" + s.path +
                                "' holds integers; pass std::int64_t values");
  s.buf_f64.insert(s.buf_f64.end(), row, row + s.width);
  ++s.rows_total;
  m.buffered_bytes += sizeof(double) * static_cast<std::size_t>(s.width);
  if (m.buffered_bytes > m.meta.max_buffered_bytes) m.flush();
}

void RunFile::append(int series_id, const std::int64_t* row) {
  Impl& m = impl();
  m.require_open("append");
  Impl::Series& s = m.series_at(series_id, "append");
  if (s.type != Elem::i64)
    throw std::invalid_argument("hs::io::RunFile::append: series '" + s.path +
                                "' holds doubles; pass double values");
  s.buf_i64.insert(s.buf_i64.end(), row, row + s.width);
  ++s.rows_total;
  m.buffered_bytes += sizeof(std::int64_t) * static_cast<std::size_t>(s.width);
  if (m.buffered_bytes > m.meta.max_buffered_bytes) m.flush();
}

std::uint64_t RunFile::series_rows(int series_id) const {
  return impl().series_at(series_id, "series_rows").rows_total;
}

int RunFile::series_count() const { return static_cast<int>(impl().series.size()); }
const std::string& RunFile::series_path(int series_id) const { return impl().series_at(series_id, "series_path").path; }
int RunFile::series_width(int series_id) const { return impl().series_at(series_id, "series_width").width; }
bool RunFile::series_is_integer(int series_id) const {
  return impl().series_at(series_id, "series_is_integer").type == Elem::i64;
}

void RunFile::begin_snapshot(double time, std::uint64_t step) {
  Impl& m = impl();
  m.require_open("begin_snapshot");
  if (m.in_snapshot)
    throw std::logic_error("hs::io::RunFile::begin_snapshot: the previous snapshot was not ended");
  m.in_snapshot = true;
  m.snap_time = time;
  m.snap_step = step;
  m.pending.clear();
}

void RunFile::Impl::add_field(const std::string& name, const void* data, std::size_t n, int width,
                               const std::string& units, FieldSlice slice, Elem type) {
  Impl& m = *this;
  m.require_open("write_field");
  const std::string fn = "hs::io::RunFile::write_field('" + name + "'): ";
  if (!m.in_snapshot) throw std::logic_error(fn + "call begin_snapshot first");
  if (name.empty() || name.find('/') != std::string::npos || name == "." || name == "..")
    throw std::invalid_argument(fn + "a field name is one HDF5 link name (no '/')");
  if (width < 1) throw std::invalid_argument(fn + "width must be >= 1");
  if (name == "position" && width != 3) throw std::invalid_argument(fn + "position needs width 3");
  if (slice.global_offset + n > slice.global_count)
    throw std::invalid_argument(fn + "rows [" + std::to_string(slice.global_offset) + ", " +
                                std::to_string(slice.global_offset + n) + ") exceed global count " +
                                std::to_string(slice.global_count));
  if (n > 0 && data == nullptr) throw std::invalid_argument(fn + "null data");

  PendingField* field = nullptr;
  for (auto& f : m.pending)
    if (f.name == name) field = &f;
  if (field == nullptr) {
    m.pending.push_back({name, type, width, units, slice.global_count, {}});
    field = &m.pending.back();
  } else if (field->type != type || field->width != width || field->units != units ||
             field->global_count != slice.global_count) {
    throw std::invalid_argument(fn + "slices disagree on type, width, units or global count (first: " +
                                elem_name(field->type) + " x" + std::to_string(field->width) +
                                " [" + field->units + "] of " + std::to_string(field->global_count) +
                                " rows)");
  }
  Slice s;
  s.offset = slice.global_offset;
  s.n = n;
  const std::size_t bytes = n * static_cast<std::size_t>(width) * elem_size(type);
  s.bytes.resize(bytes);
  if (bytes > 0) std::memcpy(s.bytes.data(), data, bytes);
  field->slices.push_back(std::move(s));
}

void RunFile::write_field(const std::string& name, const double* data, std::size_t n, int width,
                          const std::string& units, FieldSlice slice) {
  impl().add_field(name, data, n, width, units, slice, Elem::f64);
}
void RunFile::write_field(const std::string& name, const std::int64_t* data, std::size_t n,
                          int width, const std::string& units, FieldSlice slice) {
  impl().add_field(name, data, n, width, units, slice, Elem::i64);
}
void RunFile::write_field(const std::string& name, const std::int32_t* data, std::size_t n,
                          int width, const std::string& units, FieldSlice slice) {
  impl().add_field(name, data, n, width, units, slice, Elem::i32);
}
void RunFile::write_field(const std::string& name, const double* data, std::size_t n, int width,
                          const std::string& units) {
  write_field(name, data, n, width, units, FieldSlice::whole(n));
}
void RunFile::write_field(const std::string& name, const std::int64_t* data, std::size_t n,
                          int width, const std::string& units) {
  write_field(name, data, n, width, units, FieldSlice::whole(n));
}
void RunFile::write_field(const std::string& name, const std::int32_t* data, std::size_t n,
                          int width, const std::string& units) {
  write_field(name, data, n, width, units, FieldSlice::whole(n));
}

void RunFile::end_snapshot() {
  Impl& m = impl();
  m.require_open("end_snapshot");
  if (!m.in_snapshot) throw std::logic_error("hs::io::RunFile::end_snapshot: no snapshot begun");
  // Serial: this process owns every row, so the slices must add up to the whole field.
  // (Under MPI the sum over ranks does; the caller's offsets come from a prefix sum.)
  for (const auto& f : m.pending) {
    if (m.parallel()) break;
    std::uint64_t rows = 0;
    for (const auto& s : f.slices) rows += s.n;
    if (rows != f.global_count)
      throw std::invalid_argument("hs::io::RunFile::end_snapshot: field '" + f.name + "' got " +
                                  std::to_string(rows) + " of its " +
                                  std::to_string(f.global_count) + " rows");
  }
  if (m.write_failed) throw std::runtime_error(m.no_space_text(ENOSPC));
  std::uint64_t bytes = m.series_flush_bytes() + 16384;
  for (const auto& f : m.pending) {
    bytes += 4096;
    for (const auto& s : f.slices) bytes += s.bytes.size();
  }
  m.reserve(bytes);  // the snapshot's raw data is written by write_snapshot, before the flush
  try {
    m.write_snapshot();
  } catch (const std::runtime_error& e) {
    m.write_failed = true;
    if (mentions_no_space(e.what())) throw std::runtime_error(m.no_space_text(ENOSPC) + ": " + e.what());
    throw;
  }
  m.in_snapshot = false;
  m.pending.clear();
  m.flush();
}

std::size_t RunFile::snapshot_count() const { return impl().snapshots.size(); }

void RunFile::flush() { impl().flush(); }

void RunFile::write_xdmf(const std::string& xdmf_path) const {
  const Impl& m = impl();
  m.write_xdmf_atomic(xdmf_path);
}

void RunFile::close() { impl().close(true); }

bool RunFile::is_open() const { return impl_ && impl_->file.valid(); }

const std::string& RunFile::path() const { return impl().target; }

const std::string& RunFile::writing_path() const { return impl().path; }

const std::string& RunFile::xdmf_path() const { return impl().xdmf_path; }

}  // namespace hs::io
