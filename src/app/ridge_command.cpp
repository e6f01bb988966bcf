#include "app/ridge_command.h"

#include "app/output_path.h"
#include "common/error.h"
#include "json/reader.h"
#include "sim/build.h"
#include "rigid/ridge.h"
#include "io/ridge_file.h"
#include "io/run_file.h"

#include <nlohmann/json.hpp>

#include <cstdio>
#include <filesystem>
#include <stdexcept>
#include <system_error>
#include <unistd.h>

namespace hs::app {

int ridge_command(const std::string& scene_path, const std::string& output, std::ostream& out,
                  bool ignore_memory_limit) {
  const nlohmann::json j = read_json_file(scene_path, "ridge scene file");
  const JsonObject root(j, "", {"name", "description", "ridge"},
                        "a ridge scene is {\"name\": ..., \"ridge\": {...}}, see docs/ridge.md");
  if (!root.has("ridge")) root.missing("ridge", "the ridge definition, see docs/ridge.md");
  const std::string name = root.string("name", std::filesystem::path(scene_path).stem().string(), false,
                                       "the scene name, e.g. \"ridge_keel_8m\"");
  root.string("description", "", false, "free text");
  const std::string base = std::filesystem::path(scene_path).parent_path().string();
  const rigid::RidgeDef def = rigid::ridge_def_from_json(root.raw("ridge"), root.at("ridge"), base);
  // Before the generation (minutes): a path that cannot be written fails now, exit 2.
  const std::string path = output.empty() ? name + "_ridge.h5" : output;
  std::filesystem::path keel = def.keel_profile_csv;
  if (!keel.empty() && keel.is_relative() && !base.empty()) keel = std::filesystem::path(base) / keel;
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
    std::fprintf(stderr, "%s[ridge] %-7s t = %7.2f / %.0f s  KE/block = %.3e J  blocks = %zu%s", tty ? "\r" : "",
                 p.phase, p.time, p.max_time, p.kinetic_energy_per_block, p.blocks, tty ? "" : "\n");
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
  out << rep.dump(2) << std::endl;
  return 0;
}

}  // namespace hs::app
