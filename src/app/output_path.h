// Checks on an output path made before any long work (`hybridsim run`, `hybridsim ridge`):
// the directory exists and is writable, and the path is not one of the run's input files.
#pragma once

#include <string>
#include <utility>
#include <vector>

namespace hs::app {

/// An input file of the command: what it is ("the scene file") and its path.
struct InputFile {
  std::string what;
  std::string path;
};

/// Throws hs::InputError(output, ...) (exit 2) when `output` (or `companion`, a file written next
/// to it such as the XDMF index; "" for none) resolves to one of `inputs` (symlinks followed,
/// hard links compared by inode), is a directory, or lies in a directory that does not exist or
/// is not writable. Every message names the path and the fix (`-o`).
void check_output_path(const std::string& output, const std::string& companion,
                       const std::vector<InputFile>& inputs);

}  // namespace hs::app
