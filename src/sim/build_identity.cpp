#include "sim/build_identity.h"

#include "build_commit.h"  // generated at every build (cmake/build_commit.cmake)

#include <string>

namespace hs::sim {

nlohmann::json build_identity() {
  std::string compiler;
#if defined(__clang__)
  compiler = std::string("Clang ") + __clang_version__;
#elif defined(__GNUC__)
  compiler = "GCC " + std::to_string(__GNUC__) + "." + std::to_string(__GNUC_MINOR__) + "." +
             std::to_string(__GNUC_PATCHLEVEL__);
#else
  compiler = "unknown compiler";
#endif
  std::string flags = HYBRIDSIM_BUILD_FLAGS;
#ifdef __FMA__
  flags += " fma";
#endif
#ifdef __AVX2__
  flags += " avx2";
#endif
#ifdef __AVX512F__
  flags += " avx512f";
#endif
#if defined(__SANITIZE_ADDRESS__)
  flags += " asan";
#endif
  return {{"version", HYBRIDSIM_VERSION}, {"commit", HYBRIDSIM_COMMIT}, {"compiler", compiler}, {"flags", flags}};
}

}  // namespace hs::sim
