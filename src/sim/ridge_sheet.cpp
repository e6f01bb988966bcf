#include "sim/ridge_sheet.h"

#include "bonded/hcp_lattice.h"
#include "common/error.h"
#include "common/ice_formulas.h"
#include "json/reader.h"
#include "ridge/definition.h"
#include "ridge/ridge_json.h"
#include "sim/build.h"

#include <algorithm>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <cmath>
#include <utility>
#include <vector>

namespace hs::sim {

SheetGeometry sheet_geometry(const scene::Scene& s) {
  SheetGeometry g;
  g.D = s.material.particle_diameter;
  g.c = bonded::hcp_layer_spacing(g.D);
  const IceLayout L = ice_layout(s);
  g.layers = L.layers;
  g.total_layers = L.layers;
  if (s.ice.has_consolidated_layer) {
    g.total_layers = L.consolidated_layers;
    const double draft_c =
        s.water.enabled ? flotation_draft(g.total_layers * g.c, s.material.density, s.water.density) : 0.0;
    const double draft_l = s.water.enabled ? flotation_draft(L.layers * g.c, s.material.density, s.water.density) : 0.0;
    const long extra = std::lround((draft_c - draft_l) / g.c);
    g.below = static_cast<std::size_t>(std::clamp<long>(extra, 0, static_cast<long>(g.total_layers - L.layers)));
  }
  g.level_box_bottom = L.bottom_z;
  g.box_bottom = L.bottom_z - static_cast<double>(g.below) * g.c;
  const double r = 0.5 * g.D;
  // Layer k's centres lie at (k + 1/2) c above the box bottom (hcp_fill_box).
  g.level_underside = g.level_box_bottom + 0.5 * g.c - r;
  g.level_top = g.level_box_bottom + (static_cast<double>(g.layers) - 0.5) * g.c + r;
  g.layer_underside = g.box_bottom + 0.5 * g.c - r;
  g.layer_top = g.box_bottom + (static_cast<double>(g.total_layers) - 0.5) * g.c + r;
  return g;
}

namespace {

double block_density(const scene::Scene& s) { return s.blocks.density > 0.0 ? s.blocks.density : s.material.density; }
double block_friction(const scene::Scene& s) {
  return s.blocks.friction >= 0.0 ? s.blocks.friction : s.material.friction;
}

/// The "ridge" value's JSON: the object itself, or the file a string names (relative to
/// `base`). `where`: that file ("" inline); `ridge_base`: the directory relative paths inside
/// the definition (keel_profile_csv) are resolved against.
nlohmann::json ridge_section_json(const nlohmann::json& v, const std::string& base, std::string& ridge_base,
                                  std::string& where) {
  ridge_base = base;
  where = "";
  if (!v.is_string()) return v;
  std::filesystem::path p(v.get<std::string>());
  if (p.is_relative() && !base.empty()) p = std::filesystem::path(base) / p;
  where = p.string();
  ridge_base = p.parent_path().string();
  try {
    return read_json_file(where, "ridge definition file (named by /ridge)");
  } catch (const InputError& e) {
    throw InputError("/ridge", e.what());
  }
}

/// ridge_def_from_json with the errors of a definition read from a file naming that file.
rigid::RidgeDef parse_section(const nlohmann::json& rj, const std::string& ridge_base, const std::string& where) {
  try {
    return rigid::ridge_def_from_json(rj, "/ridge", ridge_base);
  } catch (const InputError& e) {
    if (where.empty()) throw;
    const std::string what = e.what();
    const std::string msg = what.size() > e.path().size() + 2 ? what.substr(e.path().size() + 2) : what;
    throw InputError(e.path(), "(in " + where + ") " + msg);
  }
}

/// A run scene's ridge: its ice from the scene (apply_run_scene). A value the ridge
/// section sets itself must agree with the scene's: the ridge is generated with the run's ice.
void take_run_ice(rigid::RidgeDef& def, const nlohmann::json& rj, const scene::Scene& s, const std::string& where) {
  rigid::RidgeDef from_scene = def;
  apply_run_scene(from_scene, s);
  struct Pair {
    const char* ridge_key;  ///< "a" or "a/b"
    std::string scene_path;
    double scene_value;
  };
  const bool cl = s.ice.has_consolidated_layer;
  const std::vector<Pair> pairs = {
      {"ice_density", scene_sets(s, "/blocks/density") ? "/blocks/density" : "/material/density",
       from_scene.ice_density},
      {"water_density", "/water/density", from_scene.water_density},
      {"settle/friction", scene_sets(s, "/blocks/friction") ? "/blocks/friction" : "/material/friction",
       from_scene.settle.friction},
      {"level_ice_thickness", "/ice/thickness", from_scene.level_ice_thickness},
      {"consolidated_layer_thickness", cl ? "/ice/consolidated_layer/thickness" : "/ice/thickness (no consolidated layer)",
       from_scene.consolidated_layer_thickness},
      {"consolidated_layer_width", cl ? "/ice/consolidated_layer/width" : "/ice/consolidated_layer (absent: width 0)",
       from_scene.consolidated_layer_width},
  };
  for (const Pair& p : pairs) {
    const nlohmann::json::json_pointer ptr(std::string("/") + p.ridge_key);
    if (!rj.contains(ptr) || rj.at(ptr).is_null()) continue;
    const nlohmann::json& v = rj.at(ptr);
    if (!v.is_number()) continue;  // ridge_def_from_json has refused it already
    const double x = v.get<double>();
    if (std::abs(x - p.scene_value) <= 1e-12 * std::max(1.0, std::abs(x))) continue;
    throw InputError(std::string("/ridge/") + p.ridge_key,
                     (where.empty() ? std::string() : "(in " + where + ") ") + json_fmt(x) + " differs from " +
                         p.scene_path + " = " + json_fmt(p.scene_value) +
                         ": a ridge generated from a run scene uses the run's ice; remove /ridge/" + p.ridge_key +
                         " (the scene's value is taken) or make the two equal");
  }
  if (cl && std::abs(s.ice.consolidated_layer.center_x - s.blocks.offset.x()) > 1e-12)
    throw InputError("/ice/consolidated_layer/center_x",
                     json_fmt(s.ice.consolidated_layer.center_x) + " m, but the ridge's axis (x = 0 in the ridge "
                     "file) lands at /blocks/offset/0 = " + json_fmt(s.blocks.offset.x()) +
                     " m: the keel must sit under the consolidated layer; make them equal");
  def = from_scene;
}


}  // namespace

void apply_run_scene(rigid::RidgeDef& d, const scene::Scene& s) {
  d.ice_density = block_density(s);
  d.water_density = s.water.density;
  d.settle.friction = block_friction(s);
  d.level_ice_thickness = s.ice.thickness;
  if (s.ice.has_consolidated_layer) {
    d.consolidated_layer_thickness = s.ice.consolidated_layer.thickness;
    d.consolidated_layer_width = s.ice.consolidated_layer.width;
  } else {
    d.consolidated_layer_thickness = s.ice.thickness;
    d.consolidated_layer_width = 0.0;
  }
  const SheetGeometry g = sheet_geometry(s);
  d.sheet.floating = true;
  d.sheet.level_top = g.level_top;
  d.sheet.level_underside = g.level_underside;
  d.sheet.layer_top = g.layer_top;
  d.sheet.layer_underside = g.layer_underside;
  d.sheet.particle_diameter = g.D;
  d.sheet.layer_width = s.ice.has_consolidated_layer ? s.ice.consolidated_layer.width + g.D : 0.0;
  d.sheet.consolidated_layer_center_x = s.ice.has_consolidated_layer ? s.ice.consolidated_layer.center_x : 0.0;
}

bool scene_sets(const scene::Scene& s, const char* pointer) {
  return s.json.is_object() && s.json.contains(nlohmann::json::json_pointer(pointer));
}

void check_ridge_generation(const rigid::RidgeResult& r, const scene::Scene& s, const std::string& path) {
  if (!s.blocks.check_ridge_generation) return;  // bench hybrid (scene.h)
  const std::string fix = "regenerate the ridge with this scene's ice: `hybridsim ridge <this scene>.json` "
                          "(a run scene with a \"ridge\" section, docs/ridge.md), or make the scene match the file";
  if (!r.def.sheet.floating)
    throw InputError("/blocks/ridge_file",
                     path + " was generated under fixed ice boxes (a standalone ridge scene), not under this run's "
                            "floating particle sheet, so its keel is not in equilibrium with the run's ice; " + fix);
  rigid::RidgeDef want = r.def;
  apply_run_scene(want, s);
  const rigid::RidgeDef& got = r.def;
  std::vector<std::string> bad;
  auto cmp = [&](const std::string& field, double scene_value, double file_value, const std::string& unit) {
    if (std::abs(scene_value - file_value) <= 1e-9 * std::max(1.0, std::abs(file_value))) return;
    bad.push_back(field + " is " + json_fmt(scene_value) + unit + " in the scene, " + json_fmt(file_value) + unit +
                  " in the ridge file");
  };
  cmp(scene_sets(s, "/blocks/density") ? "/blocks/density" : "/material/density", want.ice_density, got.ice_density,
      " kg/m^3");
  cmp(scene_sets(s, "/blocks/friction") ? "/blocks/friction" : "/material/friction", want.settle.friction,
      got.settle.friction, "");
  cmp("/water/density", want.water_density, got.water_density, " kg/m^3");
  cmp("/ice/thickness", want.level_ice_thickness, got.level_ice_thickness, " m");
  if (s.ice.has_consolidated_layer != (got.consolidated_layer_width > 0.0)) {
    bad.push_back(std::string("/ice/consolidated_layer is ") + (s.ice.has_consolidated_layer ? "given" : "absent") +
                  " in the scene, the ridge file was made " + (got.consolidated_layer_width > 0.0 ? "with" : "without") +
                  " one");
  } else if (s.ice.has_consolidated_layer) {
    cmp("/ice/consolidated_layer/thickness", want.consolidated_layer_thickness, got.consolidated_layer_thickness, " m");
    cmp("/ice/consolidated_layer/width", want.consolidated_layer_width, got.consolidated_layer_width, " m");
    // The ridge frame has its axis at x = 0: the blocks land at x + blocks.offset.x.
    cmp("/ice/consolidated_layer/center_x (- /blocks/offset/0)", s.ice.consolidated_layer.center_x - s.blocks.offset.x(),
        got.sheet.consolidated_layer_center_x, " m");
  }
  const bool sheet_differs =
      std::abs(want.sheet.level_top - got.sheet.level_top) > 1e-9 ||
      std::abs(want.sheet.level_underside - got.sheet.level_underside) > 1e-9 ||
      std::abs(want.sheet.layer_top - got.sheet.layer_top) > 1e-9 ||
      std::abs(want.sheet.layer_underside - got.sheet.layer_underside) > 1e-9 ||
      std::abs(want.sheet.layer_width - got.sheet.layer_width) > 1e-9;
  // The sheet follows from density, water and thickness: named on its own only when none of
  // those differs (the particle diameter or the water level then moved it).
  if (sheet_differs && bad.empty())
    bad.push_back("the particle sheet (/material/particle_diameter " + json_fmt(s.material.particle_diameter) +
                  " m in the scene, " + json_fmt(got.sheet.particle_diameter) +
                  " m in the ridge file; /water/level) lies elsewhere: level ice " + json_fmt(want.sheet.level_underside) +
                  " .. " + json_fmt(want.sheet.level_top) + " m in the scene, " +
                  json_fmt(got.sheet.level_underside) + " .. " + json_fmt(got.sheet.level_top) +
                  " m in the file; consolidated layer " + json_fmt(want.sheet.layer_underside) + " .. " +
                  json_fmt(want.sheet.layer_top) + " m, " + json_fmt(got.sheet.layer_underside) + " .. " +
                  json_fmt(got.sheet.layer_top) + " m");
  if (!bad.empty()) {
    std::string msg = path + " was generated with other ice than this scene's: ";
    for (std::size_t i = 0; i < bad.size(); ++i) msg += (i ? "; " : "") + bad[i];
    throw InputError("/blocks/ridge_file", msg + ". " + fix);
  }
  if (scene_sets(s, "/ridge")) check_ridge_definition(r, s, path);
}

void check_ridge_definition(const rigid::RidgeResult& r, const scene::Scene& s, const std::string& path) {
  std::string where;
  rigid::RidgeDef want;
  try {
    want = run_scene_ridge_def(s, nullptr, &where);
  } catch (const InputError& e) {  // the section itself is unreadable: say why the run reads it
    const std::string what = e.what();
    const std::string msg = what.size() > e.path().size() + 2 ? what.substr(e.path().size() + 2) : what;
    throw InputError(e.path(), msg + " (the run reads /ridge to check that " + path +
                                   " was made from it; remove /ridge from the scene to run the file as it is)");
  }
  const nlohmann::json a = rigid::ridge_def_to_json(want).flatten();
  const nlohmann::json b = rigid::ridge_def_to_json(r.def).flatten();
  std::vector<std::string> bad;
  auto value = [](const nlohmann::json& j, const std::string& k) {
    const auto it = j.find(k);
    return it == j.end() ? std::string("absent") : it->dump();
  };
  for (const auto& [k, v] : a.items())
    if (k != "/name" && value(b, k) != v.dump()) bad.push_back(k + " is " + v.dump() + " there, " + value(b, k) + " in the file");
  for (const auto& [k, v] : b.items())
    if (!a.contains(k)) bad.push_back(k + " is absent there, " + v.dump() + " in the file");
  if (bad.empty()) return;
  const std::size_t shown = std::min<std::size_t>(bad.size(), 6);
  std::string msg = path + " was generated from another ridge definition than the scene's /ridge" +
                    (where.empty() ? std::string() : " (" + where + ")") + ": ";
  for (std::size_t i = 0; i < shown; ++i) msg += (i ? "; " : "") + bad[i];
  if (shown < bad.size()) msg += "; and " + std::to_string(bad.size() - shown) + " more";
  throw InputError("/blocks/ridge_file",
                   msg + ". The file is out of date: make it again with `hybridsim ridge <this scene>.json` (it is "
                         "written to /blocks/ridge_file), or remove /ridge from the scene to run the file as it is");
}

rigid::RidgeDef ridge_def_from_section(const nlohmann::json& v, const std::string& base_dir, std::string* ridge_base) {
  std::string rb, where;
  const nlohmann::json rj = ridge_section_json(v, base_dir, rb, where);
  rigid::RidgeDef d = parse_section(rj, rb, where);
  if (ridge_base) *ridge_base = rb;
  return d;
}

rigid::RidgeDef run_scene_ridge_def(const scene::Scene& s, std::string* ridge_base, std::string* where) {
  if (!scene_sets(s, "/ridge"))
    throw InputError("/ridge", "missing: the ridge definition (an object, or the path of a JSON file holding one; "
                               "docs/ridge.md)");
  std::string rb, w;
  const nlohmann::json rj = ridge_section_json(s.json.at("ridge"), s.base_dir, rb, w);
  rigid::RidgeDef d = parse_section(rj, rb, w);
  take_run_ice(d, rj, s, w);
  if (s.seed != 0) d.seed = s.seed;  // the ensemble member's ridge (docs/ridge.md, "A ridge per seed")
  if (d.name.empty()) d.name = s.name;
  if (ridge_base) *ridge_base = rb;
  if (where) *where = w;
  return d;
}

double sheet_lift(const rigid::RidgeResult& r, double x) {
  if (!r.def.sheet.floating || r.ice.empty()) return 0.0;
  // Each plate's lift over its width but for a ramp of 2 r across every boundary (r = 1 m or a
  // quarter of the plate): the lattice stays continuous where two plates ended at other heights.
  std::vector<std::pair<double, double>> pts;
  pts.reserve(2 * r.ice.size());
  for (const auto& b : r.ice) {
    const double h = b.half_extents.x(), ramp = std::min(1.0, 0.5 * h);
    pts.emplace_back(b.position.x() - h + ramp, b.lift);
    pts.emplace_back(b.position.x() + h - ramp, b.lift);
  }
  std::sort(pts.begin(), pts.end());
  if (x <= pts.front().first) return pts.front().second;
  if (x >= pts.back().first) return pts.back().second;
  const auto it = std::upper_bound(pts.begin(), pts.end(), std::make_pair(x, -1e300));
  const auto& [x1, l1] = *it;
  const auto& [x0, l0] = *(it - 1);
  return x1 > x0 ? l0 + (l1 - l0) * (x - x0) / (x1 - x0) : l1;
}

}  // namespace hs::sim
