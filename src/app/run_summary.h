// What `hybridsim run` prints: the set-up line(s) before the loop and the summary after it.
#pragma once

#include "scene/scene.h"
#include "sim/recorder.h"
#include "sim/report.h"
#include "sim/simulation.h"

#include <cstdint>
#include <cstdio>
#include <ostream>
#include <string>

namespace hs::par {
class Comm;
}

namespace hs::app {

/// Counted when the loop starts (all_at_start conversion has added the blocks' particles and bonds).
struct RunCounts {
  long long particles = 0, bonds = 0;
};

/// The set-up figures (particles, dt, steps; blocks and rigid step; MPI boxes) on `progress`.
/// Collective (global counts); returns them.
RunCounts print_setup(std::FILE* progress, const scene::Scene& s, const sim::Simulation& sim, double setup_seconds,
                      const par::Comm& comm);

struct RunEnd {
  RunCounts start;
  double wall_seconds = 0.0;  ///< of this process
  std::string output;
  std::uint64_t first_step = 0;  ///< the step this process started from (> 0 after a restart)
};

/// The end-of-run summary on `out`. Collective (the MPI figures are reduced over the ranks).
void print_summary(std::ostream& out, const scene::Scene& s, const sim::Simulation& sim, const sim::RunFigures& f,
                   const sim::RunReport& an, const RunEnd& end, const par::Comm& comm);

}  // namespace hs::app
