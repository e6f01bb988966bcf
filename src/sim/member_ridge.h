// A ridge per seed (docs/ridge.md, "A ridge per seed"): a run scene with a "ridge" definition and
// a top-level `seed` other than 0 runs on the ridge that definition generates with that seed (the
// definition's own seed overridden), not on blocks.ridge_file as given. The ridge is generated
// once into the cache directory, keyed by the definition as the run reads it (the scene's ice
// applied, the seed included), the keel profile's content and the build's identity, and reused
// by every later run with that key; the relaxation of it is then cached as any other
// (relaxation_cache.h). Seed 0 or absent: blocks.ridge_file as given.
#pragma once

#include "scene/scene.h"

#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>

namespace hs::par {
class Comm;
}

namespace hs::sim {

/// Whether the scene's ridge is generated per seed (a "ridge" section, blocks, seed != 0).
bool ridge_per_seed(const scene::Scene& s);

/// The key of the scene's ridge per seed: {"format", "build", "definition", "keel_profile"}.
nlohmann::json member_ridge_key(const scene::Scene& s);

/// Where the ridge of the scene's seed is, and whether this call generated it.
struct MemberRidge {
  std::string path;
  std::string key_hash;
  bool generated = false;
};

/// The ridge of the scene's seed: "<dir>/ridge/<key hash>.h5" when it exists (a whole file: it is
/// written under a temporary name and renamed), else generated there first (rank 0; the others
/// wait). `dir` "" (no cache): "<fallback_dir>/ridge-seed<seed>-<key hash>.h5". The scene's
/// blocks.ridge_file and ridge_file_path then name it (its JSON keeps the path as written: the
/// checkpoint's scene identity does not depend on the cache directory). Progress lines of a generation go to `progress`. Collective.
MemberRidge prepare_member_ridge(scene::Scene& s, const std::string& dir, const std::string& fallback_dir,
                                 const par::Comm& comm, std::FILE* progress);

}  // namespace hs::sim
