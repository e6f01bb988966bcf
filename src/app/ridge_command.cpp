#include "app/ridge_command.h"

#include "common/did_you_mean.h"
#include "common/error.h"
#include "rigid/ridge.h"
#include "io/ridge_file.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <unistd.h>

namespace hs::app {

int ridge_command(const std::string& scene_path, const std::string& output, std::ostream& out) {
  std::ifstream in(scene_path);
  if (!in) throw InputError(scene_path, "cannot open the scene file; check the path");
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(in);
  } catch (const nlohmann::json::parse_error& e) {
    throw InputError(scene_path, std::string("invalid JSON: ") + e.what());
  }
  if (!j.is_object()) throw InputError("/", "a ridge scene must be a JSON object with \"name\" and \"ridge\"");
  const std::vector<std::string> allowed = {"name", "description", "ridge"};
  for (const auto& [k, v] : j.items())
    if (std::find(allowed.begin(), allowed.end(), k) == allowed.end())
      throw InputError("/" + k, "unknown key \"" + k + "\"" + did_you_mean(k, allowed) +
                                    "; a ridge scene has: name, description, ridge");
  if (!j.contains("ridge")) throw InputError("/ridge", "missing: the ridge definition (see docs/ridge.md)");
  const std::string name = j.value("name", std::filesystem::path(scene_path).stem().string());
  const std::string base = std::filesystem::path(scene_path).parent_path().string();
  const rigid::RidgeDef def = rigid::ridge_def_from_json(j["ridge"], "/ridge", base);
  const bool tty = isatty(fileno(stderr));
  auto progress = [&](const rigid::RidgeProgress& p) {
    std::fprintf(stderr, "%s[ridge] %-7s t = %7.2f / %.0f s  KE/block = %.3e J  blocks = %zu%s", tty ? "\r" : "",
                 p.phase, p.time, p.max_time, p.kinetic_energy_per_block, p.blocks, tty ? "" : "\n");
  };
  const rigid::RidgeResult r = rigid::generate_ridge(def, progress);
  if (tty) std::fprintf(stderr, "\n");
  const std::string path = output.empty() ? name + "_ridge.h5" : output;
  io::save_ridge(path, r);
  nlohmann::json rep = rigid::ridge_report(r);
  rep["output"] = path;
  out << rep.dump(2) << std::endl;
  return 0;
}

}  // namespace hs::app
