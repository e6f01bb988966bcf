// Checkpoint and restart of `hybridsim run` (docs/output.md, "Checkpoints"): what the run loop
// calls to write a checkpoint after a step (every time.checkpoint_interval, and when a
// SIGINT/SIGTERM stops the run) and, with --restart, to continue from one.
//
// A checkpoint holds each rank's whole state (engine, hybrid system with its rigid world,
// recorders) and the number of series rows that belong to it; the rows themselves stay in the
// run file. A restart builds the scene as usual, replaces the state with the checkpoint's,
// copies those rows (and the snapshots written up to the checkpoint) into the new output and
// continues with the next step: at the same rank count the result is bit-identical to the run
// that was never stopped.
#pragma once

#include "common/state_archive.h"
#include "io/checkpoint_file.h"

#include <cstdio>
#include <string>
#include <vector>

namespace hs::io {
class RunFile;
}
namespace hs::par {
class Comm;
}
namespace hs::scene {
struct Scene;
}
namespace hs::sim {
class Simulation;
class Recorders;
}

namespace hs::app {

/// The scene's identity for a checkpoint: FNV-1a of its JSON (overrides applied), leaving out
/// /time/checkpoint_interval, /output and /stability, which may change between the two runs
/// (the stability limits are checks, not physics; Restart::changes lists a change).
std::string scene_identity(const scene::Scene& s, std::string* canonical_text = nullptr);

/// A checkpoint read for --restart, before the output file is created.
struct Restart {
  std::string run_file;         ///< the run file whose series rows continue (may be a partial name)
  std::string checkpoint_file;  ///< <run>.ckpt.h5
  io::CheckpointMeta meta;
  StateArchive state;           ///< this rank's (same rank count)
  std::vector<StateArchive> all;  ///< every saved rank's (another rank count)
  std::vector<io::SeriesRows> series;
  /// The stability limits changed by the restarts that led to the checkpoint's state (carried in
  /// the checkpoint) and by this one, "at step 79230 (t = 18.9987 s) /stability/max_overlap_ratio:
  /// 0.5 -> 0.75": this restart's are printed; all are kept in the run file's root attribute
  /// "restart_changes" (a JSON array) and in the checkpoints the continued run writes.
  std::vector<std::string> changes;
  std::size_t carried_changes = 0;  ///< how many of `changes` came with the checkpoint
};

/// The run file and the checkpoint that --restart `arg` names (a run file "out.h5", its partial
/// name, or "out.ckpt.h5"), without reading them.
struct RestartFiles {
  std::string run_file;         ///< may be a partial name
  std::string checkpoint_file;
};
RestartFiles restart_files(const std::string& arg);

/// Reads the checkpoint of `arg` (a run file "out.h5", its partial name, or "out.ckpt.h5") and
/// the run file's series rows up to it. hs::InputError("--restart", ...) (exit 2) when there is
/// no checkpoint, it was written for another scene (the first differing JSON path is named), or
/// the run file holds fewer rows than the checkpoint needs. At another rank count every rank
/// reads every saved rank's state (restored as their union, redistributed).
Restart read_restart(const std::string& arg, const scene::Scene& s, const par::Comm& comm);

/// Restores the simulation and the recorders from `r`, copies the snapshots up to the checkpoint
/// and appends the saved series rows to `file` (whose series the recorders have declared).
/// Returns the last completed step.
std::uint64_t apply_restart(Restart& r, sim::Simulation& sim, sim::Recorders& rec, io::RunFile& file,
                            std::FILE* progress);

/// Writes the checkpoint of the state after the current step (collective under MPI; rank 0
/// writes the file): flushes `file` first so that it holds every row the checkpoint counts.
/// `restart_changes`: Restart::changes of the run (none for a run that was not restarted).
void write_checkpoint(const std::string& ckpt_path, const scene::Scene& s, const sim::Simulation& sim,
                      const sim::Recorders& rec, io::RunFile& file, const par::Comm& comm,
                      const std::vector<std::string>& restart_changes);

}  // namespace hs::app
