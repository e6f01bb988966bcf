// One HDF5 file per run: time series, particle snapshots and the XDMF index for ParaView.
//
// Layout (see docs/output.md):
//   /                       attributes scene (JSON text), program_version, created (ISO 8601 UTC),
//                           file_format ("hybridsim-run/1")
//   /series/...             one chunked, extendible dataset per series, n x width (width 1: 1-D);
//                           attributes units, description
//   /snapshots/times        1-D, time of each snapshot [s];  /snapshots/steps: 1-D, step number
//   /snapshots/000000/<f>   one dataset per particle field, count x width (width 1: 1-D);
//                           group attributes time [s], step; dataset attribute units
//   <file>.xmf              XDMF temporal collection over the snapshots (Polyvertex point clouds)
//
// Durability (tested by tests/io/test_run_file.cpp, "KilledChild..."):
//   The file is readable by h5dump/h5py/the HDF5 C API after the process is killed (SIGKILL) at any
//   moment outside flush()/end_snapshot()/close(), and then holds exactly what the last flush wrote
//   (a kill before the constructor returns may leave an empty file). About 90 random SIGKILLs of a
//   writer that spends most of its time inside flush() all left readable files, but a kill during
//   a flush is not guaranteed.
//   How: every HDF5 call that modifies the file happens inside flush() (which end_snapshot() and
//   close() call) and ends with H5Fflush. Between flushes, series rows and snapshot fields are only
//   buffered in memory, so nothing can leave the on-disk metadata half-updated (HDF5 1.10 gives no
//   such guarantee if the metadata cache evicts entries or reuses freed space between flushes).
//   The flush reaches the OS page cache, which survives a killed process; set
//   RunFileMeta::fsync_on_flush to survive a machine crash too.
//   SWMR (libver latest + H5F_ACC_SWMR_WRITE) was tried and rejected: (1) after SIGKILL the
//   superblock (v3) still says "open for write", so h5dump and h5py without swmr=True refuse to open
//   the file until `h5clear -s` is run; (2) HDF5 1.10 SWMR does not support creating groups,
//   datasets or attributes after H5Fstart_swmr_write, and every snapshot is a new group.
//   The file uses the HDF5 1.8 format (libver bounds V18..V18): readable by any HDF5 >= 1.8,
//   no superblock status flags, attributes larger than 64 KiB allowed.
//   With RunFileMeta::write_to_partial (hybridsim run) all of this happens in run.partial-<pid>.h5,
//   which only an explicit close() renames over run.h5 (docs/output.md, "Where the file is written").
//   While a run has the file open, HDF5 file locking keeps other HDF5 programs out; to peek at a
//   running simulation use `HDF5_USE_FILE_LOCKING=FALSE h5dump ...` (sees the last flush).
//
// MPI: this is the Open MPI build of HDF5, but with the default (sec2) file driver it does NOT need
//   MPI_Init (tested: create/write/close works in a plain process, without mpirun; HDF5 only asks
//   MPI_Initialized() at library start, which is legal before MPI_Init). Only the MPI-IO driver
//   (H5Pset_fapl_mpio) needs MPI_Init: without it Open MPI aborts the process ("MPI_Comm_dup() was
//   called before MPI_INIT"). If MPI is initialized, close the RunFile before MPI_Finalize (HDF5
//   shuts itself down at MPI_Finalize).
//   Parallel (RunFileMeta::comm with more than one rank): one file through MPI-IO. Every rank
//   constructs the RunFile with the communicator and calls add_series/append/flush/begin_snapshot/
//   write_field/end_snapshot in the same order (HDF5 metadata operations are collective; they all
//   happen inside flush()). Series rows: every rank appends the same rows, rank 0 alone writes
//   them. Snapshots: each rank writes its particles as the rows [global_offset, global_offset + n)
//   of a field of global_count rows (MPI_Exscan of owned counts), with independent raw-data I/O.
//   The XDMF index is written by rank 0; fsync_on_flush is ignored (H5Fflush syncs through MPI-IO).
//   The layout is the same as a serial run's; particle rows come in rank order (use global_id).
//
// Not thread-safe (Debian's HDF5 is not built thread-safe). HDF5's automatic error printing is turned
// off for the calling thread; HDF5 failures become std::runtime_error naming the call and object.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace hs::par {
class Comm;
}

namespace hs::io {

/// What a run file records about the run that produced it.
struct RunFileMeta {
  std::string scene_text;       ///< the scene JSON as read (root attribute "scene")
  std::string program_version;  ///< e.g. HYBRIDSIM_VERSION (root attribute "program_version")
  /// Further root string attributes (name, value), e.g. "calibrated_ice" (a JSON object).
  std::vector<std::pair<std::string, std::string>> root_attributes;
  /// XDMF index written next to the file on every flush that follows a new snapshot
  /// (atomically: temp file + rename). Empty: the HDF5 path with its extension replaced by ".xmf".
  std::string xdmf_path;
  bool write_xdmf = true;
  /// fsync(2) after each flush: survive power loss / kernel crash, not only a killed process.
  bool fsync_on_flush = false;
  /// MPI: every rank of this communicator opens the one file (MPI-IO) and makes the same calls
  /// in the same order; series rows come from rank 0, snapshot rows from each rank's slice.
  /// nullptr or a one-rank comm: the plain serial file.
  const par::Comm* comm = nullptr;
  /// Write to partial_path(path, <pid of rank 0>) (index: partial_path(xdmf_path, ...)) and rename
  /// it over `path` at a successful close(): an existing file at `path` is replaced only by a
  /// complete file. A file destroyed without close(), or whose close or a flush failed, keeps its
  /// partial name (it holds the output up to its last flush). false: write `path` directly.
  bool write_to_partial = false;
  /// Buffered series data above this many bytes triggers a flush on append.
  std::size_t max_buffered_bytes = std::size_t{64} << 20;
};

/// This rank's rows of a snapshot field: rows [global_offset, global_offset + n) of a dataset with
/// global_count rows. Serial runs write {0, n}.
struct FieldSlice {
  std::uint64_t global_offset = 0;
  std::uint64_t global_count = 0;
  static FieldSlice whole(std::uint64_t n) { return {0, n}; }
};

/// "dir/run.h5" -> "dir/run.partial-<id>.h5": the name a run writes under until its file is complete
/// (the extension is kept so that tools still recognise the file).
std::string partial_path(const std::string& path, const std::string& id);

class RunFile {
 public:
  /// Creates (truncates) the file (or, with RunFileMeta::write_to_partial, its partial name) and
  /// writes the root attributes, then flushes. Throws hs::InputError(path, ...) if the file cannot
  /// be created.
  /// Full disk: before HDF5 writes anything (each flush, each snapshot) the space for it is
  /// reserved (posix_fallocate past the end of allocation, given back after the flush); when that
  /// fails (ENOSPC, or EFBIG at RLIMIT_FSIZE) flush()/end_snapshot() throw std::runtime_error
  /// "no space left for the output file '<file>' ...", the file stays as the last complete flush
  /// left it and is no longer written (close() then only closes it). Serial files only.
  RunFile(const std::string& path, RunFileMeta meta);
  ~RunFile();  ///< close(); errors are reported on stderr, not thrown
  RunFile(RunFile&&) noexcept;
  RunFile& operator=(RunFile&&) noexcept;
  RunFile(const RunFile&) = delete;
  RunFile& operator=(const RunFile&) = delete;

  // ---- time series ----
  /// Declares a series stored at `path` (absolute, e.g. "/series/parts/cone/force"; missing groups
  /// are created). width >= 1 values per row; width 1 gives a 1-D dataset. Returns its id.
  /// The dataset appears in the file at the next flush.
  int add_series(const std::string& path, int width, const std::string& units,
                 const std::string& description);
  /// Same, with 64-bit integer values.
  int add_int_series(const std::string& path, int width, const std::string& units,
                     const std::string& description);
  /// Buffers one row of `width` values (copied). The overload must match the series' type.
  void append(int series_id, const double* row);
  void append(int series_id, const std::int64_t* row);
  /// Rows appended so far (flushed or not).
  std::uint64_t series_rows(int series_id) const;
  /// Series declared so far (ids 0 .. series_count() - 1), each one's path, width and type.
  int series_count() const;
  const std::string& series_path(int series_id) const;
  int series_width(int series_id) const;
  bool series_is_integer(int series_id) const;

  // ---- particle snapshots ----
  /// Starts snapshot number snapshot_count(): /snapshots/NNNNNN.
  void begin_snapshot(double time, std::uint64_t step);
  /// Adds a per-particle field: n rows of `width` values (row-major, copied), stored as the rows
  /// `slice` of /snapshots/NNNNNN/<name>. "position" (width 3) becomes the XDMF geometry.
  /// A field may be given in several slices; units and width must then agree.
  void write_field(const std::string& name, const double* data, std::size_t n, int width,
                   const std::string& units, FieldSlice slice);
  void write_field(const std::string& name, const std::int64_t* data, std::size_t n, int width,
                   const std::string& units, FieldSlice slice);
  void write_field(const std::string& name, const std::int32_t* data, std::size_t n, int width,
                   const std::string& units, FieldSlice slice);
  /// Serial shorthands: slice {0, n}.
  void write_field(const std::string& name, const double* data, std::size_t n, int width,
                   const std::string& units);
  void write_field(const std::string& name, const std::int64_t* data, std::size_t n, int width,
                   const std::string& units);
  void write_field(const std::string& name, const std::int32_t* data, std::size_t n, int width,
                   const std::string& units);
  /// Writes the snapshot and flushes.
  void end_snapshot();
  /// Snapshots completed by end_snapshot().
  std::size_t snapshot_count() const;

  // ---- durability ----
  /// Writes buffered series rows, updates the XDMF index, H5Fflush (see the header comment).
  void flush();
  /// Writes an XDMF index of the snapshots written so far to `xdmf_path`; dataset references use
  /// the HDF5 file's name relative to the XDMF file's directory when they share it.
  void write_xdmf(const std::string& xdmf_path) const;
  /// flush() and close the file; with write_to_partial, then rename it (and its index) over the
  /// target. Idempotent. The destructor closes without the rename.
  void close();

  bool is_open() const;
  /// The target path (where the file is after a committed close()).
  const std::string& path() const;
  /// The file being written: path(), or its partial name until a committed close().
  const std::string& writing_path() const;
  /// Where the automatic XDMF index goes ("" if RunFileMeta::write_xdmf is false).
  const std::string& xdmf_path() const;

 private:
  struct Impl;
  Impl& impl() const;  ///< throws std::logic_error on a moved-from RunFile
  std::unique_ptr<Impl> impl_;
};

}  // namespace hs::io
