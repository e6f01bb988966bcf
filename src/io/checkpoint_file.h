// Checkpoint files (docs/output.md, "Checkpoints"): the whole state of a run at the end of one
// step, for `hybridsim run scene.json --restart run.h5`.
//
// Layout of <run>.ckpt.h5 (beside the run file <run>.h5):
//   /checkpoint               attributes format ("hybridsim-checkpoint/1"), step, time [s], ranks,
//                             series_rows (rows of every /series in the run file that belong to the
//                             state), snapshots, scene_hash (FNV-1a 64 of the scene JSON), scene
//                             (JSON text), program_version, run_file (the run file's target path)
//   /checkpoint/rank_<k>/...  rank k's state: one 1-D uint8 dataset per archive entry, named by its
//                             key ("engine/x", "hybrid/rigid/manifolds", ...), the raw bytes of the
//                             array (common/state_archive.h)
// Atomic: written to "<run>.ckpt.tmp-<pid>.h5" in the same directory, flushed, fsync'ed and
// renamed over <run>.ckpt.h5, so the checkpoint on disk is always a complete one (the previous
// one until the rename).
#pragma once

#include "common/state_archive.h"

#include <cstdint>
#include <string>
#include <vector>

namespace hs::io {

struct CheckpointMeta {
  std::uint64_t step = 0;
  double time = 0.0;
  int ranks = 1;
  std::uint64_t series_rows = 0;
  std::uint64_t snapshots = 0;
  std::string scene_hash;
  std::string scene_text;
  std::string program_version;
  std::string run_file;
  /// The stability limits changed by the restarts that led to this state (a JSON array of
  /// strings, app::Restart::changes); "" when none (and in older checkpoints).
  std::string restart_changes;
};

/// "dir/run.h5" or "dir/run.partial-123.h5" -> "dir/run.ckpt.h5".
std::string checkpoint_path(const std::string& run_path);
/// "dir/run.partial-123.h5" -> "dir/run.h5"; other names unchanged.
std::string strip_partial(const std::string& run_path);

/// FNV-1a 64-bit of `text`, 16 hex digits (stable across builds and machines).
std::string text_hash(const std::string& text);

/// Writes every rank's archive (ranks[k] = rank k's) atomically into `path` (serial HDF5; under
/// MPI rank 0 calls this with the gathered archives). Throws std::runtime_error naming the file.
void write_checkpoint(const std::string& path, const CheckpointMeta& meta, const std::vector<StateArchive>& ranks);

/// The attributes of a checkpoint; hs::InputError(option, ...) when `path` is missing or holds
/// no /checkpoint. `option`: the command-line option that named the file (a relaxation file,
/// sim/relaxation_cache.h, is a checkpoint of the state at t = 0).
CheckpointMeta read_checkpoint_meta(const std::string& path, const std::string& option = "--restart");
/// Rank k's archive.
StateArchive read_checkpoint_rank(const std::string& path, int rank, const std::string& option = "--restart");

/// One series of a run file, its first `rows` rows.
struct SeriesRows {
  std::string path;  ///< "/series/..."
  int width = 1;
  bool integer = false;
  std::uint64_t rows = 0;
  std::vector<double> f64;
  std::vector<std::int64_t> i64;
};
/// Every dataset under `group` (/series of a run file, or another group of row series) of the
/// run file at `path`, each cut to its first `rows` rows; hs::InputError("--restart", ...) when
/// the file cannot be read or a series holds fewer rows. A missing group other than /series
/// gives no series. rows = kAllRows: every row of each series.
inline constexpr std::uint64_t kAllRows = ~std::uint64_t{0};
std::vector<SeriesRows> read_series_rows(const std::string& path, std::uint64_t rows,
                                         const std::string& group = "/series");

class RunFile;

/// Copies the first `count` snapshots of the run file at `src` into `dst` (same fields, units,
/// times and steps), one snapshot in memory at a time. Collective under MPI (every rank of
/// `dst` calls it with its rank and the rank count; each writes an equal share of the rows).
/// hs::InputError("--restart", ...) when `src` holds fewer snapshots.
void copy_snapshots(const std::string& src, std::uint64_t count, RunFile& dst, int rank, int ranks);

}  // namespace hs::io
