// The relaxation cache (docs/bridge.md, "The relaxation cache"): the state a relaxation before the
// freeze leaves (the relaxed and frozen ridge, the relaxed sheet, at t = 0), written once to a
// relaxation file keyed by everything that determines it, and loaded by a later run, restart
// or study member with the same key instead of relaxing; that run's series are bit-identical to
// those of the run that relaxed.
//
// The key (relaxation_key) is a JSON object: the scene as the run reads it (--set applied)
// without the fields that do not enter the relaxation (name, description, output, the run's
// duration and output intervals, stability limits, parallel settings, the ISO analysis inputs,
// the ridge definition), the ridge file and the structure's mesh file replaced by a hash
// of their content, and the build's arithmetic identity (build_identity.h). The file stores the
// key itself, not only its hash, so that a refusal names the first field that differs.
//
// A relaxation file is a checkpoint file (io/checkpoint_file.h) of the state at t = 0 without
// recorders: /checkpoint/scene holds the key, scene_hash its hash, rank_0 the engine's and the
// hybrid system's state. Written atomically (a temporary file renamed over the target), so two
// runs relaxing the same key at once leave one whole file.
#pragma once

#include "common/state_archive.h"
#include "scene/scene.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace hs::par {
class Comm;
}

namespace hs::sim {

/// Where build_simulation looks for and keeps relaxed states.
struct RelaxationCacheDef {
  /// The shared cache directory (entries relaxation/<key hash>.h5): looked up, and written when
  /// the relaxation runs. "" = none (--no-cache).
  std::string dir;
  /// --relaxation FILE: loaded when it exists (its key must match: else InputError naming the
  /// first differing field and both values), else the relaxation runs and is written there.
  std::string file;
  bool enabled() const { return !dir.empty() || !file.empty(); }
};

/// Where the relaxation a run starts from came from (/analysis/relaxation, the set-up lines).
struct RelaxationOrigin {
  std::string source;       ///< "computed", "loaded" (a relaxation file), "checkpoint" (--restart); "" none
  std::string file;         ///< the relaxation file loaded or written; "" none
  std::string key_hash;     ///< FNV-1a 64 of the key's JSON text; "" without a cache
  std::uint64_t steps_run = 0;  ///< DEM steps of relaxation this process ran (0 when loaded)
};

/// The shared cache directory: $HYBRIDSIM_CACHE, else $XDG_CACHE_HOME/hybridsim, else
/// $HOME/.cache/hybridsim; "" when none of them is set.
std::string default_cache_dir();

/// The key of the scene's relaxation (see above). InputError at /blocks/ridge_file or
/// /structure/mesh when a file whose content enters it cannot be read.
nlohmann::json relaxation_key(const scene::Scene& s);

/// FNV-1a 64 of a file's bytes, 16 hex digits; "" when it cannot be read.
std::string file_content_hash(const std::string& path);

/// "<dir>/relaxation/<key hash>.h5".
std::string relaxation_entry(const std::string& dir, const std::string& key_hash);

/// The state cached for `key`: the explicit file if given, else the cache directory's entry
/// (ignored, with a warning, when its key differs or it cannot be read). Collective under MPI:
/// rank 0 reads, every rank gets the state. Fills origin.key_hash, and origin.file and
/// origin.source = "loaded" when found.
std::optional<StateArchive> find_relaxation(const RelaxationCacheDef& def, const nlohmann::json& key,
                                            const par::Comm& comm, RelaxationOrigin& origin,
                                            std::vector<std::string>& warnings);

/// Writes `state` (engine/ and hybrid/ entries at t = 0) as the relaxation file of `key`: to the
/// explicit file if given, else the cache directory's entry (rank 0 only; atomic). A failure is a
/// warning: the run goes on. Sets origin.file to the file written.
void store_relaxation(const RelaxationCacheDef& def, const nlohmann::json& key, const StateArchive& state,
                      const par::Comm& comm, RelaxationOrigin& origin, std::vector<std::string>& warnings);

}  // namespace hs::sim
