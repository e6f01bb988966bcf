// Built-in benchmarks: `hybridsim bench NAME` prints one JSON object.
#pragma once

#include "parallel/comm.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <ostream>
#include <limits>
#include <string>
#include <vector>

namespace hs::app {

/// Names of the built-in benchmarks.
std::vector<std::string> benchmark_names();

struct BenchOptions {
  /// granular: also write the settled pack as a LAMMPS data file here (tools/bench/granular.lmp).
  std::string lammps_data;
  /// hybrid: the ridge file (default: ridge_paper_size_ridge.h5 in the cache directory).
  std::string ridge;
  /// hybrid: DEM steps timed (0 = 200).
  std::uint64_t steps = 0;
  /// hybrid: every block stepped at every rigid step (the far-sleep rule off), for comparison.
  bool no_far_sleep = false;
  /// hybrid: the pier and the particle sheet 300 m from the ridge (nothing touches a block, every
  /// block asleep): what holding the ridge costs when nothing happens near it.
  bool idle = false;
  /// hybrid: the ridge as generated (under fixed boxes), not settled again in the bench's world
  /// (its sheet and pier): that ridge is in motion there.
  bool as_generated = false;
  /// hybrid: the pier's axis x, m (NaN: 3 m outside the keel's -x toe); the sheet spans
  /// [x + 7.5, x + 34] m in front of it.
  double pier_x = std::numeric_limits<double>::quiet_NaN();
};

/// Runs benchmark `name`, prints its JSON result (one object, one line) to `out`.
/// Returns the process exit code (0 ok, 2 unknown name).
/// `bench hybrid` (bench_hybrid.cpp).
nlohmann::json hybrid_benchmark(const par::Comm& comm, const BenchOptions& opt);

/// The first "model name" of /proc/cpuinfo ("unknown" without one), for a benchmark's record.
std::string cpu_model();

int run_benchmark(const std::string& name, std::ostream& out, std::ostream& err,
                  const par::Comm& comm = par::serial(), const BenchOptions& opt = {});

}  // namespace hs::app
