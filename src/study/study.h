// A study (docs/study.md): one base scene run as many members, each a (variant, seed) pair; a
// variant is a named list of --set overrides, and a grid crosses lists of values of scene fields.
// This header reads and validates STUDY.json and lists the members; running them is
// `hybridsim study` (src/app/study_command.cpp), their statistics are summary.h.
#pragma once

#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace hs::study {

/// A named list of --set overrides ("path=value", as `hybridsim run --set`).
struct Variant {
  std::string name;
  std::vector<std::string> overrides;
  /// Its seeds: "variant_seeds"[name], else the study's "seeds".
  std::vector<std::int64_t> seeds;
};

/// One run of the study: a variant with one seed.
struct Member {
  std::string variant;
  std::int64_t seed = 0;
  /// Every --set of the run in order: the study's `set`, the variant's, then seed=<seed>.
  std::vector<std::string> overrides;
  /// "<variant>/seed<k>": stable across invocations, the key of the state file.
  std::string id() const { return variant + "/seed" + std::to_string(seed); }
  /// The run file relative to the output directory: "<variant>/seed<k>.h5".
  std::filesystem::path output_rel() const { return std::filesystem::path(variant) / ("seed" + std::to_string(seed) + ".h5"); }
};

/// STUDY.json as read and checked. Paths are resolved against the study file's directory.
struct StudyDef {
  std::string name;                       ///< the study file's stem ("level_ice_smoke")
  std::filesystem::path study_file;
  std::filesystem::path base_scene;       ///< "base"
  std::filesystem::path output_dir;       ///< "output_dir"; default <study dir>/<name>
  std::vector<std::int64_t> seeds;        ///< "seeds": a list, or a count n = 1..n (each variant's, unless
                                          ///< "variant_seeds" gives it its own: Variant::seeds)
  std::vector<std::string> common;        ///< "set": overrides of every member, before the variant's
  std::vector<Variant> variants;          ///< "variants" x "grid", in name order
  std::string reference;                  ///< "reference": a variant name, "" for none
  std::string primary_metric;             ///< "primary_metric": the front's metric, "" = the first
  int mpi_ranks = 1;                      ///< "mpi_ranks": > 1 runs each member under mpirun -np K
  std::string mpirun = "mpirun";          ///< "mpirun": the launcher (and its options, split at spaces) when mpi_ranks > 1
  /// "windows": metric windows (docs/metrics.md, "Windows") the members' metrics are computed
  /// with, checked by sim::metric_windows_from_json; null: the metrics the run files hold.
  nlohmann::json windows;

  /// Every member, variant by variant (name order), seeds in the order given.
  std::vector<Member> members() const;
};

/// Reads and validates a study document; `study_file` resolves its relative paths and names
/// the study. Throws hs::InputError at the JSON pointer of the bad field ("/seeds", "/variants/a/0").
StudyDef parse_study(const nlohmann::json& doc, const std::filesystem::path& study_file);

/// Reads the file (hs::InputError when it cannot be read or parsed) and parse_study.
StudyDef load_study_file(const std::filesystem::path& study_file);

}  // namespace hs::study
