#include "app/ridge_command.h"

#include "app/output_path.h"
#include "common/error.h"
#include "json/reader.h"
#include "scene/scene.h"
#include "sim/build.h"
#include "sim/ridge_sheet.h"
#include "ridge/ridge.h"
#include "ridge/ridge_json.h"
#include "io/ridge_file.h"
#include "io/run_file.h"

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <optional>
#include <vector>
#include <filesystem>
#include <stdexcept>
#include <system_error>
#include <unistd.h>

namespace hs::app {

int ridge_command(const std::string& scene_path, const std::string& output, std::ostream& out,
                  bool ignore_memory_limit) {
  const nlohmann::json j = read_json_file(scene_path, "ridge scene file");
  const std::string base = std::filesystem::path(scene_path).parent_path().string();
  // A standalone ridge scene has only name, description and ridge; anything else makes it a
  // run scene whose ice the ridge is generated with (docs/ridge.md, "From a run scene").
  bool run_scene = false;
  for (const auto& [k, v] : j.items())
    if (k != "name" && k != "description" && k != "ridge") run_scene = true;
  std::optional<scene::Scene> scene;
  std::string path = output;
  if (run_scene) {
    if (!j.contains("ridge"))
      throw InputError("/ridge", "missing: a run scene given to `hybridsim ridge` needs a \"ridge\" section (the "
                                 "ridge definition or the path of a JSON file holding it, docs/ridge.md)");
    // The scene's blocks.ridge_file is what this command makes: parse the scene without it
    // (one placeholder block keeps the blocks section valid), then take the path.
    nlohmann::json js = j;
    std::string ridge_file;
    if (js.contains("blocks") && js["blocks"].is_object() && js["blocks"].contains("ridge_file") &&
        js["blocks"]["ridge_file"].is_string()) {
      ridge_file = js["blocks"]["ridge_file"].get<std::string>();
      js["blocks"].erase("ridge_file");
      js["blocks"]["list"] = nlohmann::json::array({{{"half_extents", {0.1, 0.1, 0.1}}, {"position", {0, 0, -50}}}});
    }
    scene = scene::parse_scene(js, base);
    if (path.empty()) {
      if (ridge_file.empty())
        throw InputError("/blocks/ridge_file", "missing: where should the ridge go? Give blocks.ridge_file (relative "
                                               "to the scene) or -o <file>");
      std::filesystem::path fp(ridge_file);
      path = fp.is_absolute() || base.empty() ? fp.string() : (std::filesystem::path(base) / fp).string();
    }
  }
  std::vector<std::string> keys = {"name", "description", "ridge"};
  if (run_scene)
    for (const auto& [k, v] : j.items()) keys.push_back(k);  // parse_scene has checked them
  const JsonObject root(j, "", keys,
                        "a ridge scene is {\"name\": ..., \"ridge\": {...}}, or a run scene with a \"ridge\" section; "
                        "see docs/ridge.md");
  if (!root.has("ridge")) root.missing("ridge", "the ridge definition, see docs/ridge.md");
  const std::string name = run_scene ? scene->name
                                     : root.string("name", std::filesystem::path(scene_path).stem().string(), false,
                                                   "the scene name, e.g. \"ridge_keel_8m\"");
  if (!run_scene) root.string("description", "", false, "free text");
  std::string ridge_base;
  rigid::RidgeDef def = run_scene ? sim::run_scene_ridge_def(*scene, &ridge_base)
                                  : sim::ridge_def_from_section(root.raw("ridge"), base, &ridge_base);
  if (run_scene && def.name.empty()) def.name = name;
  // Before the generation (minutes): a path that cannot be written fails now, exit 2.
  if (path.empty()) path = name + "_ridge.h5";
  std::filesystem::path keel = def.keel_profile_csv;
  if (!keel.empty() && keel.is_relative() && !ridge_base.empty()) keel = std::filesystem::path(ridge_base) / keel;
  check_output_path(path, "", {{"the ridge scene file", scene_path}, {"the keel profile", keel.string()}});
  if (!ignore_memory_limit) {
    // Before anything is generated: the blocks must fit in the machine's memory.
    const rigid::RidgeEstimate est = rigid::ridge_estimate(def);
    const double avail = sim::available_memory_bytes();
    if (avail >= 0 && est.bytes > avail)
      throw InputError("/ridge", "about " + json_fmt(est.blocks) + " blocks (~" + json_fmt(est.bytes / 1073741824.0) +
                                     " GiB) would be generated but only " + json_fmt(avail / 1073741824.0) +
                                     " GiB is available (MemAvailable in /proc/meminfo): the count is (1 - "
                                     "/ridge/fill_porosity) x the keel and sail volume (/ridge/keel_depth, "
                                     "/ridge/shoulder_slope_deg, /ridge/sail_height, /ridge/length = " +
                                     json_fmt(def.length) + " m) / the mean block volume (/ridge/block_thickness = " +
                                     json_fmt(def.block_thickness) + " m cubed x the aspect ratio squared); shorten "
                                     "the ridge or use thicker blocks, or pass --ignore-memory-limit to try anyway");
  }
  const bool tty = isatty(fileno(stderr));
  auto progress = [&](const rigid::RidgeProgress& p) {
    char disp[64] = "";
    if (p.max_displacement >= 0.0 && std::isfinite(p.max_displacement))
      std::snprintf(disp, sizeof disp, "  max moved in 1 s = %.2e m", p.max_displacement);
    std::fprintf(stderr, "%s[ridge] %-7s t = %7.2f / %.0f s  KE/block = %.3e J  blocks = %zu%s%s", tty ? "\r" : "",
                 p.phase, p.time, p.max_time, p.kinetic_energy_per_block, p.blocks, disp, tty ? "" : "\n");
  };
  const rigid::RidgeResult r = rigid::generate_ridge(def, progress);
  if (tty) std::fprintf(stderr, "\n");
  // Written under a partial name and renamed: an existing ridge file is replaced only by a whole one.
  const std::string partial = io::partial_path(path, std::to_string(::getpid()));
  try {
    io::save_ridge(partial, r);
  } catch (...) {
    std::error_code ec;
    std::filesystem::remove(partial, ec);
    throw;
  }
  std::error_code ec;
  std::filesystem::rename(partial, path, ec);
  if (ec) throw std::runtime_error("cannot rename '" + partial + "' to '" + path + "': " + ec.message());
  nlohmann::json rep = rigid::ridge_report(r);
  rep["output"] = path;
  rep["generation"] = rigid::ridge_generation_json(r);
  out << rep.dump(2) << std::endl;
  return 0;
}

}  // namespace hs::app
