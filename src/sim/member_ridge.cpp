// A ridge per seed: see member_ridge.h and docs/ridge.md, "A ridge per seed".
#include "sim/member_ridge.h"

#include "io/checkpoint_file.h"
#include "io/ridge_file.h"
#include "io/run_file.h"
#include "parallel/comm.h"
#include "ridge/ridge.h"
#include "ridge/ridge_json.h"
#include "sim/build_identity.h"
#include "sim/relaxation_cache.h"
#include "sim/ridge_sheet.h"

#include <unistd.h>

#include <filesystem>
#include <stdexcept>
#include <system_error>

namespace hs::sim {

namespace fs = std::filesystem;

bool ridge_per_seed(const scene::Scene& s) {
  return s.seed != 0 && s.has_blocks && s.json.is_object() && s.json.contains("ridge");
}

nlohmann::json member_ridge_key(const scene::Scene& s) {
  std::string ridge_base;
  const rigid::RidgeDef def = run_scene_ridge_def(s, &ridge_base);  // the seed applied
  std::string keel;
  if (!def.keel_profile_csv.empty()) {
    fs::path p = def.keel_profile_csv;
    if (p.is_relative() && !ridge_base.empty()) p = fs::path(ridge_base) / p;
    keel = "content fnv1a64 " + file_content_hash(p.string());
  }
  nlohmann::json d = rigid::ridge_def_to_json(def);
  d.erase("name");  // a label, not an input
  return {{"format", "hybridsim-ridge/1"}, {"build", build_identity()}, {"definition", d}, {"keel_profile", keel}};
}

MemberRidge prepare_member_ridge(scene::Scene& s, const std::string& dir, const std::string& fallback_dir,
                                 const par::Comm& comm, std::FILE* progress) {
  MemberRidge m;
  const nlohmann::json key = member_ridge_key(s);
  m.key_hash = io::text_hash(key.dump());
  m.path = !dir.empty() ? (fs::path(dir) / "ridge" / (m.key_hash + ".h5")).string()
                        : (fs::path(fallback_dir) / ("ridge-seed" + std::to_string(s.seed) + "-" + m.key_hash + ".h5"))
                              .string();
  std::string error;
  if (comm.rank() == 0 && !fs::exists(m.path)) {
    try {
      std::fprintf(progress, "hybridsim: generating the ridge of seed %llu into %s\n",
                   static_cast<unsigned long long>(s.seed), m.path.c_str());
      const rigid::RidgeResult r = rigid::generate_ridge(run_scene_ridge_def(s), {});
      const fs::path parent = fs::path(m.path).parent_path();
      if (!parent.empty()) fs::create_directories(parent);
      // Under a temporary name, then renamed: two members generating one key leave one whole file.
      const std::string partial = io::partial_path(m.path, std::to_string(::getpid()));
      io::save_ridge(partial, r);
      std::error_code ec;
      fs::rename(partial, m.path, ec);
      if (ec) throw std::runtime_error("cannot rename '" + partial + "' to '" + m.path + "': " + ec.message());
      m.generated = true;
    } catch (const std::exception& e) {
      error = e.what();
    }
  }
  error = comm.broadcast(error);
  if (!error.empty()) throw std::runtime_error("the ridge of seed " + std::to_string(s.seed) + ": " + error);
  m.generated = comm.broadcast(m.generated ? "1" : "0") == "1";
  s.blocks.ridge_file = m.path;
  s.blocks.ridge_file_path = m.path;
  return m;
}

}  // namespace hs::sim
