// The relaxation cache: see relaxation_cache.h and docs/bridge.md, "The relaxation cache".
#include "sim/relaxation_cache.h"

#include "common/error.h"
#include "io/checkpoint_file.h"
#include "json/reader.h"
#include "parallel/comm.h"
#include "sim/build_identity.h"

#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>

namespace hs::sim {

namespace {

namespace fs = std::filesystem;

const char* const kKeyFormat = "hybridsim-relaxation/1";
const char* const kExplicit = "--relaxation";

/// The value at JSON pointer `at` of `j`, as text ("(absent)" when it has none).
std::string value_at(const nlohmann::json& j, const std::string& at) {
  try {
    return j.at(nlohmann::json::json_pointer(at == "/" ? "" : at)).dump();
  } catch (const std::exception&) {
    return "(absent)";
  }
}

/// "" when the file at `path` holds `key`; else why not (the first differing field and both values).
std::string key_mismatch(const io::CheckpointMeta& meta, const nlohmann::json& key) {
  nlohmann::json saved;
  try {
    saved = nlohmann::json::parse(meta.scene_text);
  } catch (const std::exception&) {
    return "its key is not JSON (not a relaxation file?)";
  }
  const std::string at = json_first_difference(saved, key);
  if (at.empty()) return "";
  return "its key differs first at " + at + ": " + value_at(saved, at) + " in the file, " + value_at(key, at) +
         " for this run";
}

/// Rank 0's outcome of the look-up, for every rank: 'S' + the state, 'N' none, 'E' + an error.
std::string lookup_on_rank0(const RelaxationCacheDef& def, const nlohmann::json& key, const std::string& hash,
                            std::string& file, std::vector<std::string>& warnings) {
  if (!def.file.empty()) {
    file = def.file;
    if (!fs::exists(def.file)) return "N";  // relaxed and written there
    try {
      const io::CheckpointMeta meta = io::read_checkpoint_meta(def.file, kExplicit);
      const std::string why = key_mismatch(meta, key);
      if (!why.empty())
        return "E'" + def.file + "' is the relaxation of another scene or build: " + why +
               ". Give the relaxation file of this scene and build, or leave --relaxation out (the run then relaxes, "
               "or finds its own in the cache)";
      return "S" + io::read_checkpoint_rank(def.file, 0, kExplicit).serialize();
    } catch (const InputError& e) {
      return std::string("E") + e.what();
    }
  }
  file = relaxation_entry(def.dir, hash);
  if (!fs::exists(file)) return "N";
  try {
    const io::CheckpointMeta meta = io::read_checkpoint_meta(file, kExplicit);
    const std::string why = key_mismatch(meta, key);
    if (!why.empty()) {
      warnings.push_back("relaxation cache: '" + file + "' is not this scene's relaxation (" + why +
                         "); relaxing and writing a new entry");
      return "N";
    }
    return "S" + io::read_checkpoint_rank(file, 0, kExplicit).serialize();
  } catch (const std::exception& e) {
    warnings.push_back("relaxation cache: '" + file + "' cannot be read (" + e.what() +
                       "); relaxing and writing a new entry");
    return "N";
  }
}

}  // namespace

std::string default_cache_dir() {
  const auto env = [](const char* name) {
    const char* v = std::getenv(name);
    return std::string(v ? v : "");
  };
  if (!env("HYBRIDSIM_CACHE").empty()) return env("HYBRIDSIM_CACHE");
  if (!env("XDG_CACHE_HOME").empty()) return (fs::path(env("XDG_CACHE_HOME")) / "hybridsim").string();
  if (!env("HOME").empty()) return (fs::path(env("HOME")) / ".cache" / "hybridsim").string();
  return "";
}

std::string file_content_hash(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return "";
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  return io::text_hash(bytes);
}

nlohmann::json relaxation_key(const scene::Scene& s) {
  nlohmann::json sc = s.json.is_object() ? s.json : nlohmann::json::object();
  // Fields that do not enter the relaxation or the state it leaves at t = 0 (the ridge
  // definition enters through the ridge file's content; the seed stays: it draws the lattice's
  // perturbation).
  for (const char* k : {"name", "description", "output", "stability", "parallel", "analysis", "ridge"})
    sc.erase(k);
  if (sc.contains("time") && sc["time"].is_object())
    for (const char* k : {"duration", "output_interval", "snapshot_interval", "checkpoint_interval"})
      sc["time"].erase(k);
  // The conversion policy does not act before the freeze (bridge::HybridSystem::step): "never"
  // and "hybrid" relax alike, whatever the policy's region and safety factor, so members of a
  // study that differ only there share one relaxation. Not with far sleep, whose wake box is the
  // region in hybrid mode (region_awake), nor with all_at_start, which converts before relaxing.
  if (s.has_blocks && s.blocks.conversion != "all_at_start" && !s.blocks.far_sleep && sc.contains("blocks") &&
      sc["blocks"].is_object()) {
    nlohmann::json& b = sc["blocks"];
    b["conversion"] = "never or hybrid";
    b.erase("region");
    b.erase("safety_factor");
  }
  // Files by their content, not their name.
  const auto content = [](const std::string& path, const char* at) {
    const std::string h = file_content_hash(path);
    if (h.empty()) throw InputError(at, "cannot read '" + path + "' to key the relaxation cache");
    return "content fnv1a64 " + h;
  };
  if (s.has_blocks && !s.blocks.ridge_file_path.empty() && sc.contains("blocks") && sc["blocks"].is_object())
    sc["blocks"]["ridge_file"] = content(s.blocks.ridge_file_path, "/blocks/ridge_file");
  if (s.has_structure && s.structure.type == "mesh" && sc.contains("structure") && sc["structure"].is_object())
    sc["structure"]["mesh"] = content(s.structure.mesh_path, "/structure/mesh");
  return {{"format", kKeyFormat}, {"build", build_identity()}, {"scene", sc}};
}

std::string relaxation_entry(const std::string& dir, const std::string& key_hash) {
  return (fs::path(dir) / "relaxation" / (key_hash + ".h5")).string();
}

std::optional<StateArchive> find_relaxation(const RelaxationCacheDef& def, const nlohmann::json& key,
                                            const par::Comm& comm, RelaxationOrigin& origin,
                                            std::vector<std::string>& warnings) {
  origin.key_hash = io::text_hash(key.dump());
  std::string file, got;
  if (comm.rank() == 0) got = lookup_on_rank0(def, key, origin.key_hash, file, warnings);
  got = comm.broadcast(got);
  file = comm.broadcast(file);
  if (got.empty()) return std::nullopt;
  if (got[0] == 'E') throw InputError(kExplicit, got.substr(1));
  if (got[0] != 'S') return std::nullopt;
  StateArchive a;
  a.deserialize(got.data() + 1, got.size() - 1);
  origin.source = "loaded";
  origin.file = file;
  return a;
}

void store_relaxation(const RelaxationCacheDef& def, const nlohmann::json& key, const StateArchive& state,
                      const par::Comm& comm, RelaxationOrigin& origin, std::vector<std::string>& warnings) {
  const std::string path = !def.file.empty() ? def.file : relaxation_entry(def.dir, origin.key_hash);
  origin.file = path;
  if (comm.rank() != 0) return;
  try {
    const fs::path parent = fs::path(path).parent_path();
    if (!parent.empty()) fs::create_directories(parent);
    io::CheckpointMeta meta;
    meta.scene_text = key.dump();
    meta.scene_hash = origin.key_hash;
    meta.program_version = HYBRIDSIM_VERSION;
    meta.run_file = "(relaxation before the freeze)";
    io::write_checkpoint(path, meta, {state});
  } catch (const std::exception& e) {
    warnings.push_back("relaxation cache: the relaxed state could not be written to '" + path + "' (" + e.what() +
                       "); the run goes on, and the next run with this key relaxes again");
    origin.file.clear();
  }
}

}  // namespace hs::sim
