// `hybridsim ridge scene.json [-o ridge.h5]`: builds a ridge (rigid blocks rising and
// settling under the ice) and saves it to HDF5 for later scenes.
#pragma once

#include <ostream>
#include <string>

namespace hs::app {

/// Returns the exit code. Throws hs::InputError for a bad scene (exit 2 in main), and, unless
/// `ignore_memory_limit`, when rigid::ridge_estimate exceeds the machine's available memory.
int ridge_command(const std::string& scene_path, const std::string& output, std::ostream& out,
                  bool ignore_memory_limit = false);

}  // namespace hs::app
