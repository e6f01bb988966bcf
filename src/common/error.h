// Error types shared by all modules.
#pragma once

#include <stdexcept>
#include <string>

namespace hs {

/// Bad user input (scene, mesh, CLI value). `path` is the JSON path or file that is
/// wrong (e.g. "/ice/thickness" or "meshes/pier.stl"); the message says what is allowed
/// and how to fix it. The CLI turns it into exit code 2.
class InputError : public std::runtime_error {
 public:
  InputError(std::string path, const std::string& message)
      : std::runtime_error(path.empty() ? message : path + ": " + message), path_(std::move(path)) {}
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

/// The simulation became unphysical (non-finite state, runaway speed, excessive
/// overlap). Carries a diagnostic; the CLI turns it into exit code 3.
class SimulationError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace hs
