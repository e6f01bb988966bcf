#include "scene/scene.h"

#include "bonded/hcp_lattice.h"
#include "common/did_you_mean.h"
#include "common/error.h"
#include "common/ice_formulas.h"

#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>

namespace hs::scene {

using nlohmann::json;

namespace {

// ------------------------------------------------------------------ schema (keys only)
// The one list of keys per object; docs/scene.schema.json mirrors it (checked by a test).
const std::map<std::string, std::vector<std::string>>& schema_keys() {
  static const std::map<std::string, std::vector<std::string>> k = {
      {"", {"name", "description", "output", "time", "material", "bonds", "water", "gravity", "ice", "walls",
            "structure", "analysis", "stability", "parallel", "blocks"}},
      {"/time", {"duration", "dt", "dt_alpha", "output_interval", "snapshot_interval"}},
      {"/material",
       {"density", "youngs_modulus", "poisson_ratio", "particle_diameter", "restitution", "friction",
        "contact_model", "stiffness"}},
      {"/bonds",
       {"tensile_strength", "shear_strength", "damping_ratio", "radius_ratio", "freeze_tensile_strength",
        "freeze_shear_strength"}},
      {"/water", {"enabled", "level", "density", "linear_drag", "drag_coefficient", "current"}},
      {"/ice", {"type", "thickness", "length", "width", "origin", "consolidated_layer"}},
      {"/ice/consolidated_layer", {"thickness", "width", "center_x"}},
      {"/walls/*", {"name", "point", "normal", "velocity", "friction"}},
      {"/structure", {"name", "type", "pier", "mesh", "position", "velocity", "friction"}},
      {"/structure/pier",
       {"waterline_diameter", "cone_angle_deg", "cone_top_z", "cone_bottom_z", "neck_height", "shaft_diameter",
        "shaft_bottom_z", "segments"}},
      {"/analysis",
       {"flexural_strength", "rubble_porosity", "rubble_slope_deg", "rubble_friction_angle_deg", "rubble_cohesion",
        "friction_ice_ice", "keel_depth", "rubble_height"}},
      {"/stability", {"max_speed", "max_overlap_ratio"}},
      {"/parallel", {"grid", "balance_interval", "cost"}},
      {"/blocks",
       {"ridge_file", "offset", "keep_x", "keep_y", "keep_sail", "list", "density", "friction", "linear_drag",
        "drag_coefficient", "solver_iterations", "rigid_dt", "conversion", "region", "safety_factor",
        "flexural_strength", "stress_time_constant"}},
      {"/blocks/list/*", {"half_extents", "position", "orientation", "velocity", "angular_velocity"}},
      {"/blocks/region", {"shape", "offset", "radius", "z_min", "z_max", "half_extents"}},
  };
  return k;
}

bool is_index(const std::string& s) {
  return !s.empty() && s.size() < 10 && s.find_first_not_of("0123456789") == std::string::npos;
}

/// "/walls/3/normal" -> "/walls/*/normal".
std::string pattern_of(const std::string& pointer) {
  std::string out;
  std::size_t pos = 0;
  while (pos < pointer.size()) {
    const std::size_t next = pointer.find('/', pos + 1);
    const std::string part = pointer.substr(pos + 1, next == std::string::npos ? std::string::npos : next - pos - 1);
    out += "/" + (is_index(part) ? std::string("*") : part);
    if (next == std::string::npos) break;
    pos = next;
  }
  return out;
}

std::string show(const json& v) {
  std::string s = v.dump();
  if (s.size() > 60) s = s.substr(0, 57) + "...";
  return s;
}

std::string got(const json& v) {
  return std::string(v.type_name()) + " " + show(v);
}

std::string fmt(double x) {
  std::ostringstream s;
  s.precision(6);
  s << x;
  return s.str();
}

struct Range {
  double lo = -INFINITY, hi = INFINITY;
  bool lo_open = false, hi_open = false;
  static Range positive() { return {0.0, INFINITY, true, false}; }
  static Range non_negative() { return {0.0, INFINITY, false, false}; }
  static Range any() { return {}; }
  bool contains(double x) const {
    if (lo_open ? !(x > lo) : !(x >= lo)) return false;
    if (hi_open ? !(x < hi) : !(x <= hi)) return false;
    return true;
  }
  std::string describe(const std::string& unit) const {
    const std::string u = unit.empty() ? "" : " " + unit;
    std::string s;
    if (std::isfinite(lo)) s += (lo_open ? "> " : ">= ") + fmt(lo) + u;
    if (std::isfinite(hi)) s += (s.empty() ? "" : " and ") + std::string(hi_open ? "< " : "<= ") + fmt(hi) + u;
    return s.empty() ? "any finite number" : s;
  }
};

/// One JSON object being read: checks unknown keys at construction, then typed getters.
class Obj {
 public:
  Obj(const json& j, std::string ptr) : j_(j), ptr_(std::move(ptr)) {
    if (!j.is_object())
      throw InputError(ptr_.empty() ? "/" : ptr_, "expected an object {...}, got " + got(j) +
                                                      "; see docs/scene.md for this section's fields");
    const auto& allowed = allowed_keys(ptr_);
    for (const auto& [key, value] : j.items()) {
      if (std::find(allowed.begin(), allowed.end(), key) == allowed.end()) {
        std::string list;
        for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
        throw InputError(ptr_ + "/" + key, "unknown key \"" + key + "\"" + did_you_mean(key, allowed) +
                                               "; allowed here: " + list);
      }
    }
  }
  const std::string& ptr() const { return ptr_; }
  std::string at(const std::string& key) const { return ptr_ + "/" + key; }
  bool has(const std::string& key) const { return j_.contains(key); }
  const json& raw(const std::string& key) const { return j_.at(key); }

  [[noreturn]] void missing(const std::string& key, const std::string& what) const {
    throw InputError(at(key), "missing required field \"" + key + "\" (" + what + "); add it to the \"" +
                                  (ptr_.empty() ? std::string("top level") : ptr_.substr(1)) + "\" object");
  }

  double number(const std::string& key, double def, Range r, const std::string& unit, const std::string& hint,
                bool required = false, const std::string& what = "") const {
    if (!has(key)) {
      if (required) missing(key, what.empty() ? hint : what);
      return def;
    }
    const json& v = j_.at(key);
    if (!v.is_number())
      throw InputError(at(key), "expected a number" + (unit.empty() ? std::string() : " in " + unit) + ", got " +
                                    got(v) + "; " + hint);
    const double x = v.get<double>();
    if (!std::isfinite(x) || !r.contains(x))
      throw InputError(at(key), "value " + show(v) + (unit.empty() ? "" : " " + unit) + " is out of range: must be " +
                                    r.describe(unit) + "; " + hint);
    return x;
  }

  bool boolean(const std::string& key, bool def) const {
    if (!has(key)) return def;
    const json& v = j_.at(key);
    if (!v.is_boolean()) throw InputError(at(key), "expected true or false, got " + got(v));
    return v.get<bool>();
  }

  std::string string(const std::string& key, const std::string& def, bool required = false,
                     const std::string& what = "") const {
    if (!has(key)) {
      if (required) missing(key, what);
      return def;
    }
    const json& v = j_.at(key);
    if (!v.is_string()) throw InputError(at(key), "expected a string, got " + got(v) + "; " + what);
    return v.get<std::string>();
  }

  std::string choice(const std::string& key, const std::string& def, const std::vector<std::string>& allowed) const {
    const std::string s = string(key, def, false, "one of the allowed words");
    if (std::find(allowed.begin(), allowed.end(), s) == allowed.end()) {
      std::string list;
      for (const auto& a : allowed) list += (list.empty() ? "\"" : ", \"") + a + "\"";
      throw InputError(at(key), "\"" + s + "\" is not allowed" + did_you_mean(s, allowed) + "; use one of " + list);
    }
    return s;
  }

  template <int N>
  Eigen::Matrix<double, N, 1> vec(const std::string& key, const Eigen::Matrix<double, N, 1>& def,
                                  const std::string& unit, const std::string& hint) const {
    if (!has(key)) return def;
    const json& v = j_.at(key);
    if (!v.is_array() || v.size() != N)
      throw InputError(at(key), "expected an array of " + std::to_string(N) + " numbers" +
                                    (unit.empty() ? std::string() : " in " + unit) + ", got " + got(v) + "; " + hint);
    Eigen::Matrix<double, N, 1> out;
    for (int k = 0; k < N; ++k) {
      const json& e = v[k];
      if (!e.is_number() || !std::isfinite(e.get<double>()))
        throw InputError(at(key) + "/" + std::to_string(k), "expected a finite number, got " + got(e) + "; " + hint);
      out[k] = e.get<double>();
    }
    return out;
  }

 private:
  const json& j_;
  std::string ptr_;
};

std::string lower_name_ok(const std::string& s) {
  // Names become file names and HDF5 group names: letters, digits, '_', '-', '.'.
  for (char c : s)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.')) return std::string(1, c);
  return "";
}

void read_name(const Obj& o, const std::string& key, std::string& out, bool required) {
  out = o.string(key, out, required, "a short identifier such as \"demo\"");
  if (out.empty()) throw InputError(o.at(key), "must not be empty; use letters, digits, '_', '-' or '.'");
  const std::string bad = lower_name_ok(out);
  if (!bad.empty() || out == "." || out == "..")
    throw InputError(o.at(key), "\"" + out + "\" contains '" + bad +
                                    "'; names become file and HDF5 group names: use only letters, digits, "
                                    "'_', '-' and '.'");
}

}  // namespace

// ------------------------------------------------------------------ public helpers

const std::vector<std::string>& allowed_keys(const std::string& pointer) {
  static const std::vector<std::string> none;
  const auto& k = schema_keys();
  const auto it = k.find(pattern_of(pointer));
  return it == k.end() ? none : it->second;
}

double MaterialDef::effective_stiffness() const {
  return stiffness > 0.0 ? stiffness : eq1_contact_stiffness(youngs_modulus, particle_diameter);
}

json parse_json_text(const std::string& text, const std::string& source) {
  try {
    return json::parse(text);
  } catch (const json::parse_error& e) {
    // Byte offset -> line and column (1-based).
    std::size_t line = 1, col = 1;
    const std::size_t end = std::min<std::size_t>(e.byte == 0 ? 0 : e.byte - 1, text.size());
    for (std::size_t i = 0; i < end; ++i) {
      if (text[i] == '\n') {
        ++line;
        col = 1;
      } else {
        ++col;
      }
    }
    std::string what = e.what();
    // nlohmann: "[json.exception.parse_error.101] parse error at line 3, column 5: syntax error ..."
    const std::size_t colon = what.find(": ", what.find("parse error"));
    if (colon != std::string::npos) what = what.substr(colon + 2);
    throw InputError(source, "invalid JSON at line " + std::to_string(line) + ", column " + std::to_string(col) +
                                 ": " + what + "; fix the syntax there (a missing comma or quote, or a trailing "
                                               "comma, is the usual cause)");
  }
}

json read_json_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, std::string("cannot open the scene file: ") + std::strerror(errno) +
                                      "; check the path (relative paths start from the current directory)");
  std::stringstream ss;
  ss << in.rdbuf();
  return parse_json_text(ss.str(), path);
}

void apply_override(json& scene, const std::string& assignment) {
  const std::size_t eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0)
    throw InputError("--set", "\"" + assignment + "\" is not of the form path.to.field=value, e.g. ice.thickness=0.9");
  const std::string dotted = assignment.substr(0, eq);
  const std::string text = assignment.substr(eq + 1);
  json value;
  try {
    value = json::parse(text);
  } catch (const json::parse_error&) {
    value = text;  // plain words are strings: --set name=run2
  }
  std::vector<std::string> parts;
  {
    std::size_t pos = 0;
    while (true) {
      const std::size_t dot = dotted.find('.', pos);
      parts.push_back(dotted.substr(pos, dot == std::string::npos ? std::string::npos : dot - pos));
      if (dot == std::string::npos) break;
      pos = dot + 1;
    }
  }
  if (!scene.is_object()) throw InputError("/", "the scene must be a JSON object {...}");
  json* node = &scene;
  std::string ptr;
  for (std::size_t k = 0; k < parts.size(); ++k) {
    const std::string& part = parts[k];
    const bool last = k + 1 == parts.size();
    if (part.empty()) throw InputError("--set " + dotted, "empty path component; write e.g. ice.thickness=0.9");
    const std::string child = ptr + "/" + part;
    if (node->is_array()) {
      if (!is_index(part))
        throw InputError(child, "\"" + part + "\" is not an index into the array at " + (ptr.empty() ? "/" : ptr) +
                                    "; use a number, e.g. walls.0.velocity");
      const std::size_t idx = std::stoul(part);
      if (idx >= node->size())
        throw InputError(child, "index " + part + " is out of range: the array at " + ptr + " has " +
                                    std::to_string(node->size()) + " elements (--set cannot add elements)");
      if (last) {
        (*node)[idx] = value;
        return;
      }
      node = &(*node)[idx];
    } else {
      const auto& allowed = allowed_keys(ptr);
      if (allowed.empty())
        throw InputError(child, "--set path \"" + dotted + "\" does not exist in the scene schema: " +
                                    (ptr.empty() ? std::string("/") : ptr) + " is not an object");
      if (std::find(allowed.begin(), allowed.end(), part) == allowed.end()) {
        std::string list;
        for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
        throw InputError(child, "--set path \"" + dotted + "\" does not exist in the scene schema: unknown key \"" +
                                    part + "\"" + did_you_mean(part, allowed) + "; allowed here: " + list);
      }
      if (!node->is_object())
        throw InputError(ptr.empty() ? "/" : ptr, "expected an object, got " + got(*node));
      if (last) {
        (*node)[part] = value;
        return;
      }
      if (!node->contains(part)) {
        if (allowed_keys(child).empty())
          throw InputError(child, "--set path \"" + dotted + "\" goes below \"" + part +
                                      "\", which is absent from the scene; --set cannot create array elements, "
                                      "add them to the scene file");
        (*node)[part] = json::object();
      }
      node = &(*node)[part];
      if (!node->is_object() && !node->is_array())
        throw InputError(child, "--set path \"" + dotted + "\" goes below " + child + ", which is a " +
                                    node->type_name() + ", not an object");
    }
    ptr = child;
  }
}

// ------------------------------------------------------------------ parse_scene

Scene parse_scene(const json& j, const std::string& base_dir) {
  Scene s;
  s.json = j;
  const Obj root(j, "");
  read_name(root, "name", s.name, true);
  s.description = root.string("description", "", false, "free text");
  s.output = root.string("output", s.name + ".h5", false, "the output HDF5 file, e.g. \"run.h5\"");
  if (s.output.empty()) throw InputError("/output", "must not be empty; give a file name such as \"run.h5\"");

  // time
  if (!root.has("time")) root.missing("time", "at least {\"duration\": <seconds>}");
  {
    const Obj o(root.raw("time"), "/time");
    auto& t = s.time;
    t.duration = o.number("duration", 0, Range::positive(), "s", "give the simulated time in seconds, e.g. 10",
                          true, "simulated time, s");
    t.dt = o.number("dt", t.dt, Range::non_negative(), "s",
                    "give the time step in seconds, or 0 for the paper's Eq. 2 (alpha D sqrt(rho/E))");
    t.dt_alpha = o.number("dt_alpha", t.dt_alpha, {0.0, 1.0, true, false}, "",
                          "alpha of Eq. 2; 0.1 is the paper's value and is stable");
    t.output_interval = o.number("output_interval", t.output_interval, Range::positive(), "s",
                                 "time between series rows, e.g. 0.01");
    t.snapshot_interval = o.number("snapshot_interval", t.snapshot_interval, Range::non_negative(), "s",
                                   "time between particle snapshots, or 0 for none");
    if (t.output_interval > t.duration)
      s.warnings.push_back("/time/output_interval: " + fmt(t.output_interval) + " s is longer than the duration " +
                           fmt(t.duration) + " s; the series will hold only the first row");
  }

  // material
  if (root.has("material")) {
    const Obj o(root.raw("material"), "/material");
    auto& m = s.material;
    m.density = o.number("density", m.density, Range::positive(), "kg/m^3", "sea ice is about 920");
    m.youngs_modulus = o.number("youngs_modulus", m.youngs_modulus, Range::positive(), "Pa",
                                "e.g. 1e9 (the paper) or a reduced 1e8 for fast demos");
    m.poisson_ratio = o.number("poisson_ratio", m.poisson_ratio, {-1.0, 0.5, true, true}, "", "ice is about 0.3");
    m.particle_diameter = o.number("particle_diameter", m.particle_diameter, Range::positive(), "m",
                                   "the paper uses 0.5");
    m.restitution = o.number("restitution", m.restitution, {0.0, 1.0, true, false}, "",
                             "coefficient of restitution of contacts, e.g. 0.3");
    m.friction = o.number("friction", m.friction, Range::non_negative(), "", "Coulomb coefficient, e.g. 0.3");
    const std::string cm = o.choice("contact_model", contact_model_name(ContactModel::LinearSpringDashpot), contact_model_names());
    m.contact_model = contact_model_from_name(cm);
    if (o.has("stiffness"))
      m.stiffness = o.number("stiffness", 0.0, Range::positive(), "N/m",
                             "omit it for the paper's Eq. 1, pi E D / 12");
  }

  // bonds
  if (root.has("bonds")) {
    const Obj o(root.raw("bonds"), "/bonds");
    auto& b = s.bonds;
    b.tensile_strength = o.number("tensile_strength", b.tensile_strength, Range::positive(), "Pa",
                                  "e.g. 0.6e6 (flexural strength of sea ice); use 1e30 for unbreakable bonds");
    b.shear_strength = o.number("shear_strength", b.shear_strength, Range::positive(), "Pa",
                                "e.g. 0.6e6; use 1e30 for unbreakable bonds");
    b.damping_ratio = o.number("damping_ratio", b.damping_ratio, {0.0, 1.0, false, false}, "",
                               "fraction of critical damping of each bond spring, e.g. 0.1");
    b.radius_ratio = o.number("radius_ratio", b.radius_ratio, {0.0, 1.0, true, false}, "",
                              "bond radius / particle radius, 1 for full-size bonds");
    b.freeze_tensile_strength = o.number("freeze_tensile_strength", b.freeze_tensile_strength, Range::positive(),
                                         "Pa", "freeze bonds are weak, e.g. 2e4");
    b.freeze_shear_strength =
        o.number("freeze_shear_strength", b.freeze_shear_strength, Range::positive(), "Pa", "e.g. 2e4");
  }

  // water
  if (root.has("water")) {
    const Obj o(root.raw("water"), "/water");
    auto& w = s.water;
    w.enabled = o.boolean("enabled", w.enabled);
    w.level = o.number("level", w.level, Range::any(), "m", "z of the water surface");
    w.density = o.number("density", w.density, Range::positive(), "kg/m^3", "sea water is about 1025");
    w.linear_drag = o.number("linear_drag", w.linear_drag, Range::non_negative(), "N s/m",
                             "linear drag per particle, damps heave; 0 for none");
    w.drag_coefficient = o.number("drag_coefficient", w.drag_coefficient, Range::non_negative(), "",
                                  "quadratic drag coefficient C_d, e.g. 1; 0 for none");
    w.current = o.vec<3>("current", w.current, "m/s", "water velocity [vx, vy, vz]");
  }
  s.gravity = root.vec<3>("gravity", s.gravity, "m/s^2", "e.g. [0, 0, -9.81]");

  // ice
  if (!root.has("ice"))
    throw InputError("/ice", "missing required section \"ice\": the scene has no particles; add e.g. "
                             "\"ice\": {\"thickness\": 0.6, \"length\": 20, \"width\": 10}");
  {
    const Obj o(root.raw("ice"), "/ice");
    auto& ice = s.ice;
    s.has_ice = true;
    ice.type = o.choice("type", "level_ice", {"level_ice"});
    ice.thickness = o.number("thickness", 0, Range::positive(), "m", "e.g. 0.6", true, "ice thickness, m");
    ice.length = o.number("length", 0, Range::positive(), "m", "extent along x, e.g. 20", true,
                          "sheet length along x, m");
    ice.width = o.number("width", 0, Range::positive(), "m", "extent along y, e.g. 10", true,
                         "sheet width along y, m");
    const Eigen::Vector2d org = o.vec<2>("origin", Eigen::Vector2d(0, 0), "m", "[x, y] of the -x,-y corner");
    ice.origin = {org.x(), org.y()};
    const double D = s.material.particle_diameter;
    const double c = bonded::hcp_layer_spacing(D);
    if (std::lround(ice.thickness / c) < 1)
      throw InputError("/ice/thickness", "thickness " + fmt(ice.thickness) + " m gives no particle layer with D = " +
                                             fmt(D) + " m (layer spacing " + fmt(c) + " m); use thickness >= " +
                                             fmt(0.5 * c) + " m or a smaller /material/particle_diameter");
    if (ice.length < D || ice.width < D)
      throw InputError(ice.length < D ? "/ice/length" : "/ice/width",
                       "the sheet must be at least one particle diameter (" + fmt(D) + " m) long and wide");
    if (ice.thickness / D < 3.0 - 1e-9)
      s.warnings.push_back("/ice/thickness: thickness / particle_diameter = " + fmt(ice.thickness / D) +
                           " < 3: too few layers to resolve bending; consider a smaller particle_diameter");
    if (o.has("consolidated_layer")) {
      const Obj c(o.raw("consolidated_layer"), "/ice/consolidated_layer");
      auto& cl = ice.consolidated_layer;
      ice.has_consolidated_layer = true;
      cl.thickness = c.number("thickness", 0, Range::positive(), "m", "e.g. 0.9", true, "layer thickness, m");
      cl.width = c.number("width", 0, Range::positive(), "m", "extent of the band along x, e.g. 20", true,
                          "band width along x, m");
      cl.center_x = c.number("center_x", ice.origin[0] + 0.5 * ice.length, Range::any(), "m",
                             "x of the band's centre line");
      if (cl.thickness <= ice.thickness)
        throw InputError("/ice/consolidated_layer/thickness",
                         "value " + fmt(cl.thickness) + " m must be greater than the level ice thickness " +
                             fmt(ice.thickness) + " m; make it thicker or remove the consolidated_layer");
    }
    // Rough particle count guard: memory, not physics.
    const double per_layer = ice.length * ice.width / (D * D * std::sqrt(3.0) / 2.0);
    const double layers = std::round(std::max(ice.thickness, ice.has_consolidated_layer
                                                                  ? ice.consolidated_layer.thickness
                                                                  : 0.0) / c);
    if (per_layer * layers > 2e8)
      throw InputError("/ice", "about " + fmt(per_layer * layers) +
                                   " particles would be needed (limit 2e8, ~1 kB each); reduce the sheet size or "
                                   "increase /material/particle_diameter");
  }

  // walls
  if (root.has("walls")) {
    const json& wj = root.raw("walls");
    if (!wj.is_array())
      throw InputError("/walls", "expected an array of wall objects [{...}, ...], got " + got(wj));
    for (std::size_t k = 0; k < wj.size(); ++k) {
      const std::string p = "/walls/" + std::to_string(k);
      const Obj o(wj[k], p);
      WallDef w;
      w.name = "wall" + std::to_string(k);
      read_name(o, "name", w.name, false);
      for (const auto& prev : s.walls)
        if (prev.name == w.name)
          throw InputError(p + "/name", "wall name \"" + w.name + "\" is used twice; names must be unique "
                                                                  "(they name the force series)");
      if (!o.has("point")) o.missing("point", "a point on the plane [x, y, z], m");
      if (!o.has("normal")) o.missing("normal", "the plane's normal [nx, ny, nz], pointing towards the ice");
      w.point = o.vec<3>("point", w.point, "m", "a point on the plane [x, y, z]");
      w.normal = o.vec<3>("normal", w.normal, "", "normal pointing towards the ice, e.g. [1, 0, 0]");
      const double nn = w.normal.norm();
      if (!(nn > 1e-12))
        throw InputError(p + "/normal", "the normal " + show(o.raw("normal")) +
                                            " has zero length; give a direction pointing towards the ice");
      w.normal /= nn;
      w.velocity = o.vec<3>("velocity", w.velocity, "m/s", "constant wall velocity [vx, vy, vz]");
      w.friction = o.number("friction", w.friction, Range::non_negative(), "", "ice-wall Coulomb coefficient");
      s.walls.push_back(w);
    }
  }

  // structure
  if (root.has("structure")) {
    const Obj o(root.raw("structure"), "/structure");
    auto& st = s.structure;
    s.has_structure = true;
    read_name(o, "name", st.name, false);
    st.type = o.choice("type", o.has("mesh") && !o.has("pier") ? "mesh" : "pier", {"pier", "mesh"});
    if (st.type == "pier") {
      if (o.has("mesh"))
        throw InputError("/structure/mesh", "a mesh file is only read with \"type\": \"mesh\"; remove \"mesh\" "
                                            "or set \"type\": \"mesh\"");
      if (o.has("pier")) {
        const Obj p(o.raw("pier"), "/structure/pier");
        auto& pp = st.pier;
        const std::string hint = "see docs/scene.md, structure.pier";
        pp.waterline_diameter = p.number("waterline_diameter", pp.waterline_diameter, Range::any(), "m", hint);
        pp.cone_angle_deg = p.number("cone_angle_deg", pp.cone_angle_deg, Range::any(), "deg", hint);
        pp.cone_top_z = p.number("cone_top_z", pp.cone_top_z, Range::any(), "m", hint);
        pp.cone_bottom_z = p.number("cone_bottom_z", pp.cone_bottom_z, Range::any(), "m", hint);
        pp.neck_height = p.number("neck_height", pp.neck_height, Range::any(), "m", hint);
        pp.shaft_diameter = p.number("shaft_diameter", pp.shaft_diameter, Range::any(), "m", hint);
        pp.shaft_bottom_z = p.number("shaft_bottom_z", pp.shaft_bottom_z, Range::any(), "m", hint);
        const double seg = p.number("segments", pp.segments, {3.0, 100000.0, false, false}, "",
                                    "polygon corners per circle, an integer, e.g. 64");
        if (seg != std::floor(seg))
          throw InputError("/structure/pier/segments", "value " + fmt(seg) + " must be a whole number, e.g. 64");
        pp.segments = static_cast<int>(seg);
      }
      mesh::validate_pier_params(st.pier, "/structure/pier");
    } else {
      if (o.has("pier"))
        throw InputError("/structure/pier", "pier parameters are only used with \"type\": \"pier\"; remove "
                                            "\"pier\" or set \"type\": \"pier\"");
      st.mesh = o.string("mesh", "", true, "an STL or OBJ file, relative to the scene file's directory");
      if (st.mesh.empty()) throw InputError("/structure/mesh", "must not be empty; give an .stl or .obj file");
      namespace fs = std::filesystem;
      fs::path mp(st.mesh);
      if (mp.is_relative() && !base_dir.empty()) mp = fs::path(base_dir) / mp;
      st.mesh_path = mp.lexically_normal().string();
      std::error_code ec;
      if (!fs::is_regular_file(mp, ec))
        throw InputError("/structure/mesh", "mesh file \"" + st.mesh_path + "\" not found (relative paths start "
                                            "from the scene file's directory); check the name");
    }
    st.position = o.vec<3>("position", Vec3(0.0, 0.0, s.water.enabled ? s.water.level : 0.0), "m",
                           "[x, y, z] of the mesh origin (pier: its axis at the waterline)");
    st.velocity = o.vec<3>("velocity", st.velocity, "m/s", "constant velocity into the ice, e.g. [0.4, 0, 0]");
    st.friction = o.number("friction", st.friction, Range::non_negative(), "", "ice-structure Coulomb coefficient");
  }

  // analysis (ISO 19906 inputs the ice and structure do not give)
  if (root.has("analysis")) {
    const Obj o(root.raw("analysis"), "/analysis");
    auto& a = s.analysis;
    a.flexural_strength = o.number("flexural_strength", a.flexural_strength, Range::positive(), "Pa",
                                   "flexural strength of the ice, e.g. 0.5e6");
    a.rubble_porosity = o.number("rubble_porosity", a.rubble_porosity, {0.0, 1.0, false, true}, "", "e.g. 0.3");
    a.rubble_slope_deg = o.number("rubble_slope_deg", a.rubble_slope_deg, {0.0, 90.0, false, true}, "deg",
                                  "rubble pile slope, below the cone angle; 0 = 0.8 x the cone angle");
    a.rubble_friction_angle_deg = o.number("rubble_friction_angle_deg", a.rubble_friction_angle_deg,
                                           {0.0, 90.0, false, true}, "deg", "e.g. 30");
    a.rubble_cohesion = o.number("rubble_cohesion", a.rubble_cohesion, Range::non_negative(), "Pa", "e.g. 3e3");
    a.friction_ice_ice = o.number("friction_ice_ice", s.material.friction, Range::non_negative(), "",
                                  "ice-ice friction of the rubble; default material.friction");
    a.keel_depth = o.number("keel_depth", a.keel_depth, Range::non_negative(), "m", "0 for level ice");
    a.rubble_height = o.number("rubble_height", a.rubble_height, Range::non_negative(), "m",
                               "pile height for `hybridsim iso` on this scene; a run uses its own");
  }
  if (s.analysis.friction_ice_ice < 0) s.analysis.friction_ice_ice = s.material.friction;

  // stability
  if (root.has("stability")) {
    const Obj o(root.raw("stability"), "/stability");
    s.stability.max_speed = o.number("max_speed", s.stability.max_speed, Range::positive(), "m/s",
                                     "speed above which the run stops as unstable, e.g. 100");
    s.stability.max_overlap_ratio = o.number("max_overlap_ratio", s.stability.max_overlap_ratio,
                                             {0.0, 2.0, true, false}, "",
                                             "overlap / radius above which the run stops, e.g. 0.5");
  }

  // parallel
  if (root.has("parallel")) {
    const Obj o(root.raw("parallel"), "/parallel");
    auto& p = s.parallel;
    if (o.has("grid")) {
      const Eigen::Vector3d g = o.vec<3>("grid", Eigen::Vector3d::Zero(), "",
                                         "boxes along x, y and z whose product is the MPI rank count, e.g. [4, 1, 1]");
      const bool auto_grid = g == Eigen::Vector3d::Zero();
      for (int a = 0; a < 3; ++a) {
        if (g[a] != std::floor(g[a]) || (!auto_grid && g[a] < 1) || g[a] > 65536)
          throw InputError("/parallel/grid/" + std::to_string(a),
                           "expected a whole number >= 1, got " + fmt(g[a]) +
                               "; give boxes per axis whose product is the rank count, or [0, 0, 0] to choose");
        p.grid[a] = static_cast<int>(g[a]);
      }
    }
    p.balance_interval = static_cast<std::uint64_t>(
        o.number("balance_interval", static_cast<double>(p.balance_interval), Range::non_negative(), "steps",
                 "steps between load-balance checks, e.g. 500, or 0 to keep the first cuts"));
    p.cost = o.choice("cost", p.cost, {"work", "time"});
  }

  // blocks (rigid ice blocks and their conversion)
  if (root.has("blocks")) {
    const Obj o(root.raw("blocks"), "/blocks");
    auto& b = s.blocks;
    s.has_blocks = true;
    b.ridge_file = o.string("ridge_file", "", false, "an HDF5 ridge file written by `hybridsim ridge`");
    if (!b.ridge_file.empty()) {
      const std::filesystem::path fp(b.ridge_file);
      b.ridge_file_path = fp.is_absolute() || base_dir.empty() ? fp.string() : (std::filesystem::path(base_dir) / fp).string();
      if (!std::filesystem::exists(b.ridge_file_path))
        throw InputError("/blocks/ridge_file", "cannot find " + b.ridge_file_path +
                                                   " (relative to the scene file); make it with `hybridsim ridge "
                                                   "<ridge scene>.json -o <file>` or fix the path");
    }
    b.offset = o.vec<3>("offset", b.offset, "m", "shift of the ridge file's blocks, e.g. [30, 0, 0]");
    for (const char* key : {"keep_x", "keep_y"}) {
      const Eigen::Vector2d r = o.vec<2>(key, Eigen::Vector2d(-1e30, 1e30), "m",
                                         "[min, max] of the block centres kept from the ridge file (after offset)");
      if (!(r[0] < r[1])) throw InputError(o.at(key), "min must be < max; e.g. [-10, 10]");
      (std::string(key) == "keep_x" ? b.keep_x : b.keep_y) = {r[0], r[1]};
    }
    b.keep_sail = o.boolean("keep_sail", b.keep_sail);
    if (o.has("list")) {
      const json& arr = o.raw("list");
      if (!arr.is_array())
        throw InputError("/blocks/list", "expected an array of blocks [{\"half_extents\": [..], \"position\": [..]}, ...]");
      for (std::size_t k = 0; k < arr.size(); ++k) {
        const Obj bo(arr[k], "/blocks/list/" + std::to_string(k));
        BlockItemDef it;
        it.half_extents = bo.vec<3>("half_extents", it.half_extents, "m", "half sizes along the block's axes");
        for (int a = 0; a < 3; ++a)
          if (!(it.half_extents[a] > 0.0))
            throw InputError(bo.at("half_extents") + "/" + std::to_string(a), "must be > 0 (m)");
        it.position = bo.vec<3>("position", it.position, "m", "centre of the block");
        const Eigen::Vector4d q = bo.vec<4>("orientation", Eigen::Vector4d(1, 0, 0, 0), "",
                                            "unit quaternion [w, x, y, z], body to world");
        if (!(q.norm() > 1e-12)) throw InputError(bo.at("orientation"), "must be a non-zero quaternion [w, x, y, z]");
        it.orientation = Quat(q[0], q[1], q[2], q[3]).normalized();
        it.velocity = bo.vec<3>("velocity", it.velocity, "m/s", "initial velocity");
        it.angular_velocity = bo.vec<3>("angular_velocity", it.angular_velocity, "rad/s", "initial angular velocity");
        b.list.push_back(it);
      }
    }
    if (b.ridge_file.empty() && b.list.empty())
      throw InputError("/blocks", "no blocks: give \"ridge_file\" (from `hybridsim ridge`) or a \"list\", or remove "
                                  "the \"blocks\" section");
    b.density = o.number("density", s.material.density, Range::positive(), "kg/m^3", "ice density, e.g. 920");
    b.friction = o.number("friction", s.material.friction, Range::non_negative(), "", "ice-ice Coulomb coefficient");
    b.linear_drag = o.number("linear_drag", b.linear_drag, Range::non_negative(), "Pa s/m",
                             "linear drag per wetted face area (heave damper), e.g. 1000");
    b.drag_coefficient = o.number("drag_coefficient", b.drag_coefficient, Range::non_negative(), "", "e.g. 1.0");
    b.solver_iterations = static_cast<int>(o.number("solver_iterations", b.solver_iterations, {1.0, 1000.0}, "",
                                                    "Bullet sequential-impulse iterations, e.g. 20"));
    b.rigid_dt = o.number("rigid_dt", b.rigid_dt, Range::non_negative(), "s",
                          "rigid step; 0 = the largest the stability rule allows (docs/bridge.md)");
    b.conversion = o.choice("conversion", b.conversion, {"hybrid", "all_at_start", "never"});
    b.safety_factor = o.number("safety_factor", b.safety_factor, Range::positive(), "",
                               "a block converts when its stress utilisation x safety_factor >= 1; > 1 converts earlier");
    b.flexural_strength = o.number("flexural_strength", s.analysis.flexural_strength, Range::positive(), "Pa",
                                   "flexural strength of a block, e.g. 0.5e6");
    b.stress_time_constant = o.number("stress_time_constant", b.stress_time_constant, Range::non_negative(), "s",
                                      "time constant of the filter on each block's stress utilisation, e.g. 0.05");
    if (o.has("region")) {
      const Obj r(o.raw("region"), "/blocks/region");
      auto& g = b.region;
      g.shape = r.choice("shape", g.shape, {"cylinder", "box"});
      g.offset = r.vec<3>("offset", g.offset, "m", "centre relative to the structure's mesh origin");
      g.radius = r.number("radius", g.radius, Range::non_negative(), "m", "0 = structure radius + 5 m");
      g.z_min = r.number("z_min", g.z_min, Range::any(), "m", "bottom of the cylinder, relative to the offset");
      g.z_max = r.number("z_max", g.z_max, Range::any(), "m", "top of the cylinder, relative to the offset");
      if (!(g.z_min < g.z_max)) throw InputError("/blocks/region/z_max", "must be > z_min");
      g.half_extents = r.vec<3>("half_extents", g.half_extents, "m", "half sizes of the box region");
      if (g.shape == "box" && !(g.half_extents.minCoeff() > 0.0))
        throw InputError("/blocks/region/half_extents", "a box region needs three half extents > 0, e.g. [15, 15, 10]");
    }
  }
  return s;
}

Scene load_scene_file(const std::string& path, const std::vector<std::string>& overrides) {
  json j = read_json_file(path);
  if (!j.is_object()) throw InputError("/", "the scene must be a JSON object {...}, got " + got(j));
  for (const auto& o : overrides) apply_override(j, o);
  return parse_scene(j, std::filesystem::path(path).parent_path().string());
}

// ------------------------------------------------------------------ building

bonded::EngineDef engine_def(const Scene& s) {
  using namespace bonded;
  EngineDef d;
  const auto& m = s.material;
  d.dt = s.time.dt;
  d.dt_alpha = s.time.dt_alpha;
  d.youngs_modulus = m.youngs_modulus;
  d.poisson_ratio = m.poisson_ratio;
  d.density = m.density;
  d.gravity = s.gravity;
  d.contact_model = m.contact_model;
  const double k = m.effective_stiffness();
  d.contact.kn = d.contact.kt = k;
  d.contact.zeta_n = d.contact.zeta_t = damping_ratio_from_restitution(m.restitution);
  d.contact.mu = m.friction;
  d.hertz = HertzContactParams::from_material(m.youngs_modulus, m.poisson_ratio, m.restitution, m.friction);
  // Bonds: pair reduced mass and inertia of two lattice particles.
  const double D = m.particle_diameter, r = 0.5 * D;
  const double mass = m.density * hcp_cell_volume(D);
  const double inertia = 0.4 * mass * r * r;
  const auto& b = s.bonds;
  d.bond[static_cast<int>(BondKind::Lattice)] = ParallelBondParams::from_stiffness(
      k, k, b.radius_ratio * r, b.tensile_strength, b.shear_strength, b.damping_ratio, 0.5 * mass, 0.5 * inertia);
  d.bond[static_cast<int>(BondKind::Freeze)] =
      ParallelBondParams::from_stiffness(k, k, b.radius_ratio * r, b.freeze_tensile_strength,
                                         b.freeze_shear_strength, b.damping_ratio, 0.5 * mass, 0.5 * inertia);
  d.water.enabled = s.water.enabled;
  d.water.level = s.water.level;
  d.water.density = s.water.density;
  d.water.model = BuoyancyModel::Column;
  d.water.linear_drag = s.water.linear_drag;
  d.water.drag_coefficient = s.water.drag_coefficient;
  d.water.current = s.water.current;
  d.limits.max_speed = s.stability.max_speed;
  d.limits.max_overlap_ratio = s.stability.max_overlap_ratio;
  return d;
}

IceLayout ice_layout(const Scene& s) {
  IceLayout L;
  const double D = s.material.particle_diameter;
  const double c = bonded::hcp_layer_spacing(D);
  L.layers = static_cast<std::size_t>(std::max(1L, std::lround(s.ice.thickness / c)));
  const double h = L.layers * c;
  // Floating at equilibrium (Column buoyancy): draft h rho_i / rho_w, freeboard h (1 - rho_i/rho_w).
  // Without water the sheet rests with its bottom at z = 0.
  const double draft = s.water.enabled ? flotation_draft(h, s.material.density, s.water.density) : 0.0;
  const double level = s.water.enabled ? s.water.level : 0.0;
  L.bottom_z = level - draft;
  L.top_z = L.bottom_z + h;
  if (s.ice.has_consolidated_layer)
    L.consolidated_layers = static_cast<std::size_t>(
        std::max<long>(static_cast<long>(L.layers) + 1, std::lround(s.ice.consolidated_layer.thickness / c)));
  return L;
}

mesh::TriMesh structure_mesh(const Scene& s) {
  if (s.structure.type == "pier") return mesh::make_pier(s.structure.pier);
  try {
    return mesh::load_mesh(s.structure.mesh_path);
  } catch (const InputError& e) {
    throw InputError("/structure/mesh", "cannot use mesh file \"" + s.structure.mesh_path + "\": " + e.what());
  }
}

double structure_radius(const Scene& s, const mesh::TriMesh& m) {
  if (s.structure.type == "pier") return mesh::pier_cone_radius(s.structure.pier, s.structure.pier.cone_bottom_z);
  const mesh::Aabb b = mesh::bounding_box(m);
  return 0.5 * std::max(b.extent().x(), b.extent().y());
}

analysis::IsoInputs iso_inputs(const Scene& s, double rubble_height) {
  if (!s.has_structure)
    throw InputError("/structure", "the ISO 19906 estimate needs a cone: add \"structure\": {\"type\": \"pier\"}");
  if (s.structure.type != "pier")
    throw InputError("/structure/type", "the ISO 19906 estimate needs the parametric pier (waterline diameter and "
                                        "cone angle); a mesh structure does not give them");
  analysis::IsoInputs in;
  in.thickness = s.ice.has_consolidated_layer ? s.ice.consolidated_layer.thickness : s.ice.thickness;
  in.waterline_diameter = s.structure.pier.waterline_diameter;
  in.cone_angle_deg = s.structure.pier.cone_angle_deg;
  in.flexural_strength = s.analysis.flexural_strength;
  in.youngs_modulus = s.material.youngs_modulus;
  in.poisson_ratio = s.material.poisson_ratio;
  in.friction_ice_structure = s.structure.friction;
  in.friction_ice_ice = s.analysis.friction_ice_ice;
  in.ice_density = s.material.density;
  in.water_density = s.water.density;
  in.gravity = s.gravity.norm();
  in.rubble_height = rubble_height;
  in.rubble_porosity = s.analysis.rubble_porosity;
  in.rubble_cohesion = s.analysis.rubble_cohesion;
  in.rubble_slope_deg = s.analysis.rubble_slope_deg > 0 ? s.analysis.rubble_slope_deg : 0.8 * in.cone_angle_deg;
  in.rubble_friction_angle_deg = s.analysis.rubble_friction_angle_deg;
  in.keel_depth = s.analysis.keel_depth;
  return in;
}

Built build_engine(const Scene& s, bool check_dt) {
  using namespace bonded;
  Built out;
  out.engine = std::make_unique<Engine>(engine_def(s));
  Engine& e = *out.engine;
  const double D = s.material.particle_diameter;
  const double c = hcp_layer_spacing(D);
  const IceLayout L = ice_layout(s);
  out.layout = L;

  // One lattice for the whole sheet. With a consolidated layer the box is as thick as that
  // layer, hanging lower by the number of extra layers its own equilibrium draft needs (a
  // whole number of layers, so the lattice stays continuous), and the level ice keeps only
  // its own layers outside the band.
  std::size_t total_layers = L.layers;
  std::size_t below = 0;  // consolidated layers below the level ice's bottom layer
  if (s.ice.has_consolidated_layer) {
    total_layers = L.consolidated_layers;
    const double draft_c = s.water.enabled ? flotation_draft(total_layers * c, s.material.density, s.water.density) : 0.0;
    const double draft_l = s.water.enabled ? flotation_draft(L.layers * c, s.material.density, s.water.density) : 0.0;
    const long extra = std::lround((draft_c - draft_l) / c);
    below = static_cast<std::size_t>(std::clamp<long>(extra, 0, static_cast<long>(total_layers - L.layers)));
  }
  const double box_bottom = L.bottom_z - below * c;
  const Vec3 half(0.5 * s.ice.length, 0.5 * s.ice.width, 0.5 * total_layers * c);
  const Pose pose{Vec3(s.ice.origin[0] + half.x(), s.ice.origin[1] + half.y(), box_bottom + half.z()),
                  Quat::Identity()};
  const auto centres = hcp_fill_box(half, pose, D);

  ParticleInit p;
  p.radius = 0.5 * D;
  p.mass = s.material.density * hcp_cell_volume(D);
  p.buoyant_volume = hcp_cell_volume(D);
  e.particles().reserve(centres.size());
  const double level_lo = L.bottom_z - 0.25 * c, level_hi = L.top_z + 0.25 * c;
  // Keep the spheres that lie wholly inside the footprint, so that walls placed at the
  // sheet's edges (origin, origin + length/width) touch but do not overlap it.
  const double x0 = s.ice.origin[0], x1 = x0 + s.ice.length, y0 = s.ice.origin[1], y1 = y0 + s.ice.width;
  const double r = 0.5 * D, eps = 1e-9 * D;
  for (const auto& x : centres) {
    if (x.x() - r < x0 - eps || x.x() + r > x1 + eps || x.y() - r < y0 - eps || x.y() + r > y1 + eps) continue;
    if (s.ice.has_consolidated_layer) {
      const auto& cl = s.ice.consolidated_layer;
      const bool in_band = std::abs(x.x() - cl.center_x) <= 0.5 * cl.width;
      if (!in_band && (x.z() < level_lo || x.z() > level_hi)) continue;
    }
    p.x = x;
    e.add_particle(p);
  }
  out.particles = e.particles().size();
  out.bonds = e.bond_touching(0, e.particles().size(), BondKind::Lattice);

  for (const auto& w : s.walls) e.add_wall(PlaneWall{w.name, w.point, w.normal, w.velocity, w.friction});
  if (s.has_structure) {
    MeshWallDef md;
    md.name = s.structure.name;
    md.mesh = structure_mesh(s);
    out.structure_radius = structure_radius(s, md.mesh);
    md.position = s.structure.position;
    md.velocity = s.structure.velocity;
    md.friction = s.structure.friction;
    out.structure = e.add_mesh_wall(std::move(md));
    out.structure_parts = e.mesh_wall(out.structure).mesh.part_names;
  }
  if (check_dt) e.check_time_step();
  return out;
}

}  // namespace hs::scene
