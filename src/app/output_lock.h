// One writer per output: a run holds `<file>.lock` beside each file it writes (the run file and
// its checkpoint) for its lifetime, so that a second run on the same output is refused before it
// writes anything (docs/output.md, "Where the file is written").
//
// The lock is flock(2) on the lock file, which holds the holder's PID and command line. The
// kernel releases it when the holder's process ends in any way (SIGKILL, a crash), so a killed
// run leaves at most a lock file that nobody holds, which the next run takes over; a run that
// returns removes its lock files.
#pragma once

#include <string>
#include <vector>

namespace hs::par {
class Comm;
}

namespace hs::app {

/// A file to lock, and how a refusal names it: `option` is the InputError path ("-o",
/// "--restart") and `what` the file's role ("the output file").
struct LockedFile {
  std::string path;
  std::string what;
  std::string option;
};

/// The locks a run holds; released (and their files removed) by the destructor.
class OutputLocks {
 public:
  OutputLocks() = default;
  /// Takes `<path>.lock` of each file (on rank 0; the others wait for its verdict). Throws
  /// hs::InputError on every rank (exit 2) when another process holds one: the message names
  /// the file, the lock file and the holder (PID, and its command line where /proc or the lock
  /// file gives it). Locks taken before the refusal are released.
  OutputLocks(const std::vector<LockedFile>& files, const par::Comm& comm);
  OutputLocks(OutputLocks&& o) noexcept;
  OutputLocks& operator=(OutputLocks&& o) noexcept;
  OutputLocks(const OutputLocks&) = delete;
  OutputLocks& operator=(const OutputLocks&) = delete;
  ~OutputLocks();

  /// The lock files held (rank 0; empty on the others).
  std::vector<std::string> held() const;

 private:
  void release() noexcept;
  struct Held {
    int fd;
    std::string lock_path;
  };
  std::vector<Held> held_;
};

/// `<path>.lock`.
std::string lock_path_of(const std::string& path);

}  // namespace hs::app
