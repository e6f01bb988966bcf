// The build's arithmetic identity: what must be equal for two binaries to compute the same bits
// (version, commit, compiler and the flags that change the arithmetic). A relaxation cached by
// one build is reused only by a build with the same identity (sim/relaxation_cache.h).
#pragma once

#include <nlohmann/json.hpp>

namespace hs::sim {

/// {"version", "commit", "compiler", "flags"}: HYBRIDSIM_VERSION; the git commit the binary was
/// built from ("+dirty.<hash of the uncommitted diff>" when the tree had changes, "unknown"
/// outside git; cmake/build_commit.cmake); the compiler and version; the build type, the
/// compile flags and the instruction-set macros the compiler set (fma, avx2, avx512f).
nlohmann::json build_identity();

}  // namespace hs::sim
