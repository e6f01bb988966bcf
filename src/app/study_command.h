// `hybridsim study STUDY.json` (docs/study.md): runs a study's members as child processes of
// this binary, resumably, and writes its member table, summary and front.
#pragma once

#include <cstdio>
#include <ostream>
#include <string>

namespace hs::app {

struct StudyOptions {
  std::string study_file;
  int jobs = 1;               ///< -j: members run at once
  bool dry_run = false;       ///< --dry-run: list the members and their estimated core-hours, run nothing
  bool retry_failed = false;  ///< --retry-failed: run the members whose last run failed again
  bool no_plot = false;       ///< --no-plot: write the tables only (no tools/plot_study.py)
};

/// Runs the study. Returns 0 when every member is done, 1 when some are not (failed, or stopped
/// without the study being stopped; the tables hold the others), 130 / 143 when SIGINT / SIGTERM stopped it (each running member was sent one SIGTERM
/// and left its checkpoint). Throws hs::InputError (exit 2) on a bad study file or member scene.
int study_command(const StudyOptions& opt, std::ostream& out, std::FILE* progress);

}  // namespace hs::app
