// The process side of `hybridsim study`: runs members as child processes (fork/exec), at most N at
// once, measures each one's wall time and resources (wait4), and passes SIGINT/SIGTERM on.
#pragma once

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

namespace hs::app {

/// One child process to run: its argv (argv[0] found on PATH when it has no '/') and the log file
/// its stdout and stderr are appended to.
struct StudyJob {
  std::size_t member = 0;  ///< index of the member in the study
  std::vector<std::string> argv;
  std::string log;
};

/// How a child ended.
struct StudyJobEnd {
  int exit_code = -1;          ///< exit status, or 128 + the signal that killed it
  bool stopped = false;        ///< the study passed a SIGINT/SIGTERM on to it
  double wall_seconds = 0.0;   ///< from fork to wait4
  double core_seconds = 0.0;   ///< ru_utime + ru_stime of wait4 (the child and the children it waited for)
  double max_rss_mib = 0.0;    ///< ru_maxrss (the largest single process among them)
};

/// Runs `queue` in order, at most `jobs` at once; each child in its own process group (a Ctrl-C at
/// the terminal reaches the study alone, which sends each running child one SIGTERM: a second
/// signal would end a run without its checkpoint). After a SIGINT/SIGTERM no further job starts.
/// Calls `started` after each fork and `ended` after each wait, in this process. Returns the
/// signal that stopped the study, 0 when every job ran.
int run_study_jobs(const std::vector<StudyJob>& queue, int jobs, const std::function<void(const StudyJob&)>& started,
                   const std::function<void(const StudyJob&, const StudyJobEnd&)>& ended);

}  // namespace hs::app
