// Built-in benchmarks: `hybridsim bench NAME` prints one JSON object.
#pragma once

#include "parallel/comm.h"

#include <ostream>
#include <string>
#include <vector>

namespace hs::app {

/// Names of the built-in benchmarks.
std::vector<std::string> benchmark_names();

/// Runs benchmark `name`, prints its JSON result (one object, one line) to `out`.
/// Returns the process exit code (0 ok, 2 unknown name).
int run_benchmark(const std::string& name, std::ostream& out, std::ostream& err,
                  const par::Comm& comm = par::serial());

}  // namespace hs::app
