// Built-in benchmarks: `hybridsim bench NAME` prints one JSON object.
#pragma once

#include "parallel/comm.h"

#include <ostream>
#include <string>
#include <vector>

namespace hs::app {

/// Names of the built-in benchmarks.
std::vector<std::string> benchmark_names();

struct BenchOptions {
  /// granular: also write the settled pack as a LAMMPS data file here (tools/bench/granular.lmp).
  std::string lammps_data;
};

/// Runs benchmark `name`, prints its JSON result (one object, one line) to `out`.
/// Returns the process exit code (0 ok, 2 unknown name).
int run_benchmark(const std::string& name, std::ostream& out, std::ostream& err,
                  const par::Comm& comm = par::serial(), const BenchOptions& opt = {});

}  // namespace hs::app
