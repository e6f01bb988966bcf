#include "scene/scene.h"

#include "common/error.h"
#include "common/hcp_geometry.h"
#include "common/ice_formulas.h"
#include "json/reader.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>

namespace hs::scene {

using nlohmann::json;

namespace {

// ------------------------------------------------------------------ schema (keys only)
// The one list of keys per object; docs/scene.schema.json mirrors it (checked by a test).
const std::map<std::string, std::vector<std::string>>& schema_keys() {
  static const std::map<std::string, std::vector<std::string>> k = {
      {"", {"name", "description", "output", "seed", "time", "material", "bonds", "water", "gravity", "ice", "walls",
            "structure", "analysis", "stability", "parallel", "blocks", "ridge"}},
      {"/time", {"duration", "dt", "dt_alpha", "output_interval", "snapshot_interval", "checkpoint_interval"}},
      {"/material",
       {"density", "youngs_modulus", "poisson_ratio", "particle_diameter", "restitution", "friction",
        "contact_model", "stiffness", "stiffness_model", "flexural_strength", "tensile_strength"}},
      {"/bonds",
       {"tensile_strength", "shear_strength", "damping_ratio", "radius_ratio", "freeze_tensile_strength",
        "freeze_shear_strength", "freeze_strength_fraction", "compressive_strength_ratio",
        "crushed_contact", "crushed_set_depth", "strength_spread"}},
      {"/water", {"enabled", "level", "density", "linear_drag_per_area", "drag_coefficient", "current", "linear_drag"}},
      {"/ice", {"type", "thickness", "length", "width", "origin", "consolidated_layer"}},
      {"/ice/consolidated_layer", {"thickness", "width", "center_x"}},
      {"/walls/*", {"name", "point", "normal", "velocity", "friction"}},
      {"/structure", {"name", "type", "pier", "mesh", "position", "velocity", "friction"}},
      {"/structure/pier",
       {"waterline_diameter", "cone_angle_deg", "cone_top_z", "cone_bottom_z", "neck_height", "deck_z",
        "shaft_diameter", "shaft_bottom_z", "segments"}},
      {"/analysis",
       {"flexural_strength", "rubble_porosity", "rubble_slope_deg", "rubble_friction_angle_deg", "rubble_cohesion",
        "friction_ice_ice", "keel_depth", "rubble_height"}},
      {"/stability", {"max_speed", "max_overlap_ratio"}},
      {"/parallel", {"grid", "balance_interval", "cost"}},
      {"/blocks",
       {"ridge_file", "offset", "keep_x", "keep_y", "keep_sail", "loose_blocks", "list", "density", "friction", "linear_drag",
        "drag_coefficient", "solver_iterations", "solver_tolerance", "fixed_friction_directions", "friction_sees_torque", "rigid_dt", "conversion", "region",
        "safety_factor", "flexural_strength", "stress_time_constant", "relax", "far_sleep", "lattice"}},
      {"/blocks/relax", {"enabled", "max_time", "speed", "hold", "damping", "jointed_time", "lattice_time", "lattice_damping",
                         "hold_freeze_bonds"}},
      {"/blocks/far_sleep", {"enabled", "wake_distance", "speed", "still_time", "start_asleep", "wake_hops", "loads_wake_neighbours", "loads_held", "region_awake", "zone_wakes_neighbours"}},
      {"/blocks/list/*", {"half_extents", "position", "orientation", "velocity", "angular_velocity", "fixed"}},
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

using Range = JsonRange;

/// The reader of the scene object at `pointer`, allowing the keys the schema lists there.
JsonObject section(const json& j, const std::string& pointer) {
  return JsonObject(j, pointer, allowed_keys(pointer), "see docs/scene.md for this section's fields");
}
/// ... of the object at `key` of `parent` (which must be present).
JsonObject section(const JsonObject& parent, const std::string& key) {
  return section(parent.raw(key), parent.at(key));
}

std::string lower_name_ok(const std::string& s) {
  // Names become file names and HDF5 group names: letters, digits, '_', '-', '.'.
  for (char c : s)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.')) return std::string(1, c);
  return "";
}

void read_name(const JsonObject& o, const std::string& key, std::string& out, bool required) {
  out = o.string(key, out, required, "a short identifier such as \"demo\"");
  if (out.empty()) throw InputError(o.at(key), "must not be empty; use letters, digits, '_', '-' or '.'");
  const std::string bad = lower_name_ok(out);
  if (!bad.empty() || out == "." || out == "..")
    throw InputError(o.at(key), "\"" + out + "\" contains '" + bad +
                                    "'; names become file and HDF5 group names: use only letters, digits, "
                                    "'_', '-' and '.'");
}

// ------------------------------------------------------------------ one function per section
// Each reads its section of the scene into `s`, in the order of parse_scene; sections read
// later may use earlier ones (defaults from material, water level, analysis).

void read_top(const JsonObject& root, Scene& s) {
  read_name(root, "name", s.name, true);
  s.description = root.string("description", "", false, "free text");
  s.output = root.string("output", s.name + ".h5", false, "the output HDF5 file, e.g. \"run.h5\"");
  if (s.output.empty()) throw InputError("/output", "must not be empty; give a file name such as \"run.h5\"");
  s.seed = root.integer<std::uint64_t>("seed", 0, JsonRange::non_negative(), "",
                                       "a whole number >= 0, e.g. 7 (the ensemble member)");
}

}  // namespace

void check_step_count(const TimeDef& t, double dt, const std::string& dt_origin) {
  const double steps = t.duration / dt;
  if (!(steps <= kMaxSteps))
    throw InputError("/time/dt", "dt = " + json_fmt(dt) + " s" + dt_origin + " with /time/duration = " +
                                     json_fmt(t.duration) + " s gives " + json_fmt(steps) + " steps (limit " +
                                     json_fmt(kMaxSteps) + "); give a larger /time/dt (or 0 for Eq. 2) or a "
                                                           "shorter /time/duration");
}

namespace {

void read_time(const JsonObject& root, Scene& s) {
  if (!root.has("time")) root.missing("time", "at least {\"duration\": <seconds>}");
  const JsonObject o = section(root, "time");
  auto& t = s.time;
  t.duration = o.number("duration", 0, Range::positive(), "s", "give the simulated time in seconds, e.g. 10", true,
                        "simulated time, s");
  t.dt = o.number("dt", t.dt, Range::non_negative(), "s",
                  "give the time step in seconds, or 0 for the paper's Eq. 2 (alpha D sqrt(rho/E))");
  t.dt_alpha = o.number("dt_alpha", t.dt_alpha, {0.0, 1.0, true, false}, "",
                        "alpha of Eq. 2; 0.1 is the paper's value and is stable");
  t.output_interval = o.number("output_interval", t.output_interval, Range::positive(), "s",
                               "time between series rows, e.g. 0.01");
  t.snapshot_interval = o.number("snapshot_interval", t.snapshot_interval, Range::non_negative(), "s",
                                 "time between particle snapshots, or 0 for none");
  t.checkpoint_interval = o.number("checkpoint_interval", t.checkpoint_interval, Range::non_negative(), "s",
                                   "simulated time between checkpoints, or 0 for none (a SIGINT/SIGTERM stop always "
                                   "writes one)");
  if (t.dt > 0) check_step_count(t, t.dt);
  if (t.output_interval > t.duration)
    s.warnings.push_back("/time/output_interval: " + json_fmt(t.output_interval) + " s is longer than the duration " +
                         json_fmt(t.duration) + " s; the series will hold only the first row");
}

void read_material(const JsonObject& root, Scene& s) {
  if (!root.has("material")) return;
  const JsonObject o = section(root, "material");
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
  const std::string sm = o.choice("stiffness_model", "calibrated", {"calibrated", "paper_eq1"});
  m.stiffness_model = sm == "paper_eq1" ? StiffnessModel::PaperEq1 : StiffnessModel::Calibrated;
  if (o.has("stiffness")) {
    if (m.stiffness_model == StiffnessModel::Calibrated)
      throw InputError(o.at("stiffness"), "an explicit spring stiffness needs \"stiffness_model\": \"paper_eq1\"; "
                                          "the calibrated model derives the stiffness from youngs_modulus and "
                                          "poisson_ratio (remove \"stiffness\", or add \"stiffness_model\": "
                                          "\"paper_eq1\")");
    m.stiffness = o.number("stiffness", 0.0, Range::positive(), "N/m", "omit it for the paper's Eq. 1, pi E D / 12");
  }
  m.flexural_strength = o.number("flexural_strength", m.flexural_strength, Range::positive(), "Pa",
                                 "flexural strength of the ice (3-point bending), e.g. 0.5e6");
  m.tensile_strength = o.number("tensile_strength", m.tensile_strength, Range::non_negative(), "Pa",
                                "uniaxial tensile strength of the ice, e.g. 0.3e6 (a target for `hybridsim "
                                "calibrate`), 0 for none");
}

void read_bonds(const JsonObject& root, Scene& s) {
  if (!root.has("bonds")) return;
  const JsonObject o = section(root, "bonds");
  auto& b = s.bonds;
  b.tensile_strength = o.number("tensile_strength", b.tensile_strength, Range::positive(), "Pa",
                                "e.g. 0.6e6 (flexural strength of sea ice); use 1e30 for unbreakable bonds");
  b.shear_strength = o.number("shear_strength", b.shear_strength, Range::positive(), "Pa",
                              "e.g. 0.6e6; use 1e30 for unbreakable bonds");
  b.damping_ratio = o.number("damping_ratio", b.damping_ratio, {0.0, 1.0, false, false}, "",
                             "fraction of critical damping of each bond spring, e.g. 0.1");
  b.radius_ratio = o.number("radius_ratio", b.radius_ratio, {0.0, 1.0, true, false}, "",
                            "bond radius / particle radius, 1 for full-size bonds");
  b.freeze_tensile_strength = o.number("freeze_tensile_strength", b.freeze_tensile_strength, Range::positive(), "Pa",
                                       "freeze bonds are weak, e.g. 2e4");
  b.freeze_shear_strength =
      o.number("freeze_shear_strength", b.freeze_shear_strength, Range::positive(), "Pa", "e.g. 2e4");
  b.freeze_strength_fraction = o.number("freeze_strength_fraction", 0.0, {0.0, 1.0, false, true}, "",
                                        "freeze-bond strength as a fraction of the lattice bond's, e.g. 0.1");
  if (o.has("freeze_strength_fraction"))
    for (const char* k : {"freeze_tensile_strength", "freeze_shear_strength"})
      if (o.has(k))
        throw InputError(o.at(k), std::string("give the freeze-bond strength either as /bonds/") + k +
                                      " (Pa) or as /bonds/freeze_strength_fraction (of the lattice bond's), "
                                      "not both");
  b.compressive_strength_ratio =
      o.number("compressive_strength_ratio", b.compressive_strength_ratio, Range::positive(), "",
               "compressive strength of lattice and freeze bonds as a multiple of the lattice bond's tensile "
               "strength, e.g. 3 (leave it out for bonds that never fail in compression)");
  b.crushed_contact = o.choice("crushed_contact", b.crushed_contact, {"set", "elastic"});
  b.crushed_set_depth = o.number("crushed_set_depth", b.crushed_set_depth, {0.0, 1.0, true, true}, "",
                                 "overlap / smaller radius beyond which a broken bond's contact keeps a permanent "
                                 "set, e.g. 0.25");
  b.strength_spread = o.number("strength_spread", b.strength_spread, Range::non_negative(), "",
                               "relative standard deviation of each lattice bond's strengths (lognormal, mean "
                               "the bond strength), e.g. 0.2; 0 = every bond alike");
  b.strength_given = o.has("tensile_strength") || o.has("shear_strength");
  // "calibrated" derives the bond strength from material.flexural_strength: both at once would be
  // two answers to one question.
  const bool flex_given = root.has("material") && root.raw("material").contains("flexural_strength");
  if (b.strength_given && flex_given && s.material.stiffness_model == StiffnessModel::Calibrated)
    throw InputError(o.at(o.has("tensile_strength") ? "tensile_strength" : "shear_strength"),
                     "with the calibrated stiffness model the bond strength is derived from "
                     "/material/flexural_strength (" + json_fmt(s.material.flexural_strength) +
                         " Pa); give one of the two: remove this bond strength, or remove "
                         "/material/flexural_strength to set the bonds directly (or use "
                         "\"stiffness_model\": \"paper_eq1\")");
}

void read_water(const JsonObject& root, Scene& s) {
  if (!root.has("water")) return;
  const JsonObject o = section(root, "water");
  auto& w = s.water;
  w.enabled = o.boolean("enabled", w.enabled);
  w.level = o.number("level", w.level, Range::any(), "m", "z of the water surface");
  w.density = o.number("density", w.density, Range::positive(), "kg/m^3", "sea water is about 1025");
  if (o.has("linear_drag"))
    throw InputError(o.at("linear_drag"),
                     "water.linear_drag (N s/m per particle) was removed: blocks and particles now share one drag "
                     "law per m^2 of wetted surface. Use \"linear_drag_per_area\" (Pa s/m, default 1000) instead; "
                     "see docs/engine.md, \"Water drag\"");
  w.linear_drag_per_area = o.number("linear_drag_per_area", w.linear_drag_per_area, Range::non_negative(), "Pa s/m",
                                    "linear drag per m^2 of wetted surface (blocks and particles), e.g. 1000");
  w.drag_coefficient = o.number("drag_coefficient", w.drag_coefficient, Range::non_negative(), "",
                                "quadratic drag coefficient C_d on leading faces (blocks and particles), e.g. 1");
  w.current = o.vec<3>("current", w.current, "m/s", "water velocity [vx, vy, vz]");
}

void read_consolidated_layer(const JsonObject& ice_obj, IceDef& ice) {
  const JsonObject c = section(ice_obj, "consolidated_layer");
  auto& cl = ice.consolidated_layer;
  ice.has_consolidated_layer = true;
  cl.thickness = c.number("thickness", 0, Range::positive(), "m", "e.g. 0.9", true, "layer thickness, m");
  cl.width = c.number("width", 0, Range::positive(), "m", "extent of the band along x, e.g. 20", true,
                      "band width along x, m");
  cl.center_x = c.number("center_x", ice.origin[0] + 0.5 * ice.length, Range::any(), "m",
                         "x of the band's centre line");
  if (cl.thickness <= ice.thickness)
    throw InputError("/ice/consolidated_layer/thickness",
                     "value " + json_fmt(cl.thickness) + " m must be greater than the level ice thickness " +
                         json_fmt(ice.thickness) + " m; make it thicker or remove the consolidated_layer");
}

/// The sheet must hold at least one particle layer and one particle across.
void check_ice_size(Scene& s) {
  const auto& ice = s.ice;
  const double D = s.material.particle_diameter;
  const double c = hcp_layer_spacing(D);
  if (std::lround(ice.thickness / c) < 1)
    throw InputError("/ice/thickness", "thickness " + json_fmt(ice.thickness) + " m gives no particle layer with D = " +
                                           json_fmt(D) + " m (layer spacing " + json_fmt(c) + " m); use thickness >= " +
                                           json_fmt(0.5 * c) + " m or a smaller /material/particle_diameter");
  if (ice.length < D || ice.width < D)
    throw InputError(ice.length < D ? "/ice/length" : "/ice/width",
                     "the sheet must be at least one particle diameter (" + json_fmt(D) + " m) long and wide");
  if (ice.thickness / D < 3.0 - 1e-9)
    s.warnings.push_back("/ice/thickness: thickness / particle_diameter = " + json_fmt(ice.thickness / D) +
                         " < 3: too few layers to resolve bending; consider a smaller particle_diameter");
}

void read_ice(const JsonObject& root, Scene& s) {
  if (!root.has("ice"))
    throw InputError("/ice", "missing required section \"ice\": the scene has no particles; add e.g. "
                             "\"ice\": {\"thickness\": 0.6, \"length\": 20, \"width\": 10}");
  const JsonObject o = section(root, "ice");
  auto& ice = s.ice;
  s.has_ice = true;
  ice.type = o.choice("type", "level_ice", {"level_ice"});
  ice.thickness = o.number("thickness", 0, Range::positive(), "m", "e.g. 0.6", true, "ice thickness, m");
  ice.length =
      o.number("length", 0, Range::positive(), "m", "extent along x, e.g. 20", true, "sheet length along x, m");
  ice.width = o.number("width", 0, Range::positive(), "m", "extent along y, e.g. 10", true, "sheet width along y, m");
  const Eigen::Vector2d org = o.vec<2>("origin", Eigen::Vector2d(0, 0), "m", "[x, y] of the -x,-y corner");
  ice.origin = {org.x(), org.y()};
  check_ice_size(s);
  if (o.has("consolidated_layer")) read_consolidated_layer(o, ice);
  // The sheet's size is checked against the machine's memory when it is built
  // (sim::check_memory), not against a fixed count.
}

WallDef read_wall(const JsonObject& o, std::size_t k, const std::vector<WallDef>& earlier) {
  WallDef w;
  w.name = "wall" + std::to_string(k);
  read_name(o, "name", w.name, false);
  for (const auto& prev : earlier)
    if (prev.name == w.name)
      throw InputError(o.at("name"), "wall name \"" + w.name + "\" is used twice; names must be unique "
                                                               "(they name the force series)");
  if (!o.has("point")) o.missing("point", "a point on the plane [x, y, z], m");
  if (!o.has("normal")) o.missing("normal", "the plane's normal [nx, ny, nz], pointing towards the ice");
  w.point = o.vec<3>("point", w.point, "m", "a point on the plane [x, y, z]");
  w.normal = o.vec<3>("normal", w.normal, "", "normal pointing towards the ice, e.g. [1, 0, 0]");
  const double nn = w.normal.norm();
  if (!(nn > 1e-12))
    throw InputError(o.at("normal"), "the normal " + json_show(o.raw("normal")) +
                                         " has zero length; give a direction pointing towards the ice");
  w.normal /= nn;
  w.velocity = o.vec<3>("velocity", w.velocity, "m/s", "constant wall velocity [vx, vy, vz]");
  w.friction = o.number("friction", w.friction, Range::non_negative(), "", "ice-wall Coulomb coefficient");
  return w;
}

void read_walls(const JsonObject& root, Scene& s) {
  if (!root.has("walls")) return;
  const json& wj = root.array("walls", "wall objects [{...}, ...]");
  for (std::size_t k = 0; k < wj.size(); ++k)
    s.walls.push_back(read_wall(section(wj[k], "/walls/" + std::to_string(k)), k, s.walls));
}

void read_pier(const JsonObject& o, mesh::PierParams& pp) {
  const JsonObject p = section(o, "pier");
  const std::string hint = "see docs/scene.md, structure.pier";
  pp.waterline_diameter = p.number("waterline_diameter", pp.waterline_diameter, Range::any(), "m", hint);
  pp.cone_angle_deg = p.number("cone_angle_deg", pp.cone_angle_deg, Range::any(), "deg", hint);
  pp.cone_top_z = p.number("cone_top_z", pp.cone_top_z, Range::any(), "m", hint);
  pp.cone_bottom_z = p.number("cone_bottom_z", pp.cone_bottom_z, Range::any(), "m", hint);
  // The column above the cone ends at the deck (deck_z, default kPierDefaultDeckZ) or, when the
  // scene gives neck_height, that far above the cone top; not both.
  if (p.has("neck_height") && p.has("deck_z"))
    throw InputError("/structure/pier/deck_z", "give either deck_z (the top of the column above the cone, m) or "
                                               "neck_height (its height above cone_top_z), not both");
  const double deck_z = p.number("deck_z", mesh::kPierDefaultDeckZ, Range::any(), "m", hint);
  pp.neck_height = p.number("neck_height", deck_z - pp.cone_top_z, Range::any(), "m", hint);
  if (!p.has("neck_height") && !(pp.neck_height > 0.0))
    throw InputError("/structure/pier/deck_z", "deck_z = " + json_fmt(deck_z) + " m must be above cone_top_z = " +
                                                   json_fmt(pp.cone_top_z) + " m: the column rises from the cone "
                                                   "top to the deck; raise deck_z (default " +
                                                   json_fmt(mesh::kPierDefaultDeckZ) + " m)");
  pp.shaft_diameter = p.number("shaft_diameter", pp.shaft_diameter, Range::any(), "m", hint);
  pp.shaft_bottom_z = p.number("shaft_bottom_z", pp.shaft_bottom_z, Range::any(), "m", hint);
  pp.segments = p.integer<int>("segments", pp.segments, {3.0, 100000.0, false, false}, "",
                               "polygon corners per circle, an integer, e.g. 64");
}

void read_structure_mesh(const JsonObject& o, StructureDef& st, const std::string& base_dir) {
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

void read_structure(const JsonObject& root, Scene& s, const std::string& base_dir) {
  if (!root.has("structure")) return;
  const JsonObject o = section(root, "structure");
  auto& st = s.structure;
  s.has_structure = true;
  read_name(o, "name", st.name, false);
  st.type = o.choice("type", o.has("mesh") && !o.has("pier") ? "mesh" : "pier", {"pier", "mesh"});
  if (st.type == "pier") {
    if (o.has("mesh"))
      throw InputError("/structure/mesh", "a mesh file is only read with \"type\": \"mesh\"; remove \"mesh\" "
                                          "or set \"type\": \"mesh\"");
    if (o.has("pier")) read_pier(o, st.pier);
    mesh::validate_pier_params(st.pier, "/structure/pier");
  } else {
    read_structure_mesh(o, st, base_dir);
  }
  st.position = o.vec<3>("position", Vec3(0.0, 0.0, s.water.enabled ? s.water.level : 0.0), "m",
                         "[x, y, z] of the mesh origin (pier: its axis at the waterline)");
  st.velocity = o.vec<3>("velocity", st.velocity, "m/s", "constant velocity into the ice, e.g. [0.4, 0, 0]");
  st.friction = o.number("friction", st.friction, Range::non_negative(), "", "ice-structure Coulomb coefficient");
}

/// ISO 19906 inputs the ice and structure do not give.
void read_analysis(const JsonObject& root, Scene& s) {
  if (root.has("analysis")) {
    const JsonObject o = section(root, "analysis");
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
}

void read_stability(const JsonObject& root, Scene& s) {
  if (!root.has("stability")) return;
  const JsonObject o = section(root, "stability");
  s.stability.max_speed = o.number("max_speed", s.stability.max_speed, Range::positive(), "m/s",
                                   "speed above which the run stops as unstable, e.g. 100");
  s.stability.max_overlap_ratio = o.number("max_overlap_ratio", s.stability.max_overlap_ratio,
                                           {0.0, 2.0, true, false}, "",
                                           "overlap / radius above which the run stops, e.g. 0.5");
}

void read_parallel(const JsonObject& root, Scene& s) {
  if (!root.has("parallel")) return;
  const JsonObject o = section(root, "parallel");
  auto& p = s.parallel;
  if (o.has("grid")) {
    const Eigen::Vector3d g = o.vec<3>("grid", Eigen::Vector3d::Zero(), "",
                                       "boxes along x, y and z whose product is the MPI rank count, e.g. [4, 1, 1]");
    const bool auto_grid = g == Eigen::Vector3d::Zero();
    for (int a = 0; a < 3; ++a) {
      if (g[a] != std::floor(g[a]) || (!auto_grid && g[a] < 1) || g[a] > 65536)
        throw InputError("/parallel/grid/" + std::to_string(a),
                         "expected a whole number >= 1, got " + json_fmt(g[a]) +
                             "; give boxes per axis whose product is the rank count, or [0, 0, 0] to choose");
      p.grid[a] = static_cast<int>(g[a]);
    }
  }
  p.balance_interval = o.integer<std::uint64_t>("balance_interval", p.balance_interval, Range::non_negative(),
                                                "steps", "steps between load-balance checks, e.g. 500, or 0 to keep "
                                                         "the first cuts");
  p.cost = o.choice("cost", p.cost, {"work", "time"});
}

BlockItemDef read_block_item(const JsonObject& bo) {
  BlockItemDef it;
  it.half_extents = bo.vec<3>("half_extents", it.half_extents, "m", "half sizes along the block's axes");
  for (int a = 0; a < 3; ++a)
    if (!(it.half_extents[a] > 0.0))
      throw InputError(bo.at("half_extents") + "/" + std::to_string(a), "must be > 0 (m)");
  it.position = bo.vec<3>("position", it.position, "m", "centre of the block");
  const Eigen::Vector4d q =
      bo.vec<4>("orientation", Eigen::Vector4d(1, 0, 0, 0), "", "unit quaternion [w, x, y, z], body to world");
  if (!(q.norm() > 1e-12)) throw InputError(bo.at("orientation"), "must be a non-zero quaternion [w, x, y, z]");
  it.orientation = Quat(q[0], q[1], q[2], q[3]).normalized();
  it.velocity = bo.vec<3>("velocity", it.velocity, "m/s", "initial velocity");
  it.angular_velocity = bo.vec<3>("angular_velocity", it.angular_velocity, "rad/s", "initial angular velocity");
  it.fixed = bo.boolean("fixed", it.fixed);
  return it;
}

/// Where the blocks come from: a ridge file (cropped, shifted) and/or a list.
void read_block_sources(const JsonObject& o, BlocksDef& b, const std::string& base_dir) {
  b.ridge_file = o.string("ridge_file", "", false, "an HDF5 ridge file written by `hybridsim ridge`");
  if (!b.ridge_file.empty()) {
    const std::filesystem::path fp(b.ridge_file);
    b.ridge_file_path =
        fp.is_absolute() || base_dir.empty() ? fp.string() : (std::filesystem::path(base_dir) / fp).string();
    if (!std::filesystem::exists(b.ridge_file_path))
      throw InputError("/blocks/ridge_file", "cannot find " + b.ridge_file_path +
                                                 " (relative to the scene file); make it with `hybridsim ridge "
                                                 "<this scene>.json` (a scene with a \"ridge\" section) or "
                                                 "`hybridsim ridge <ridge scene>.json -o <file>`, or fix the path");
  }
  b.offset = o.vec<3>("offset", b.offset, "m", "shift of the ridge file's blocks, e.g. [30, 0, 0]");
  for (const char* key : {"keep_x", "keep_y"}) {
    const Eigen::Vector2d r = o.vec<2>(key, Eigen::Vector2d(-1e30, 1e30), "m",
                                       "[min, max] of the block centres kept from the ridge file (after offset)");
    if (!(r[0] < r[1])) throw InputError(o.at(key), "min must be < max; e.g. [-10, 10]");
    (std::string(key) == "keep_x" ? b.keep_x : b.keep_y) = {r[0], r[1]};
  }
  b.keep_sail = o.boolean("keep_sail", b.keep_sail);
  b.loose_blocks = o.choice("loose_blocks", b.loose_blocks, {"drop", "keep"});
  if (o.has("list")) {
    const json& arr = o.array("list", "blocks [{\"half_extents\": [..], \"position\": [..]}, ...]");
    for (std::size_t k = 0; k < arr.size(); ++k)
      b.list.push_back(read_block_item(section(arr[k], "/blocks/list/" + std::to_string(k))));
  }
  if (b.ridge_file.empty() && b.list.empty())
    throw InputError("/blocks", "no blocks: give \"ridge_file\" (from `hybridsim ridge`) or a \"list\", or remove "
                                "the \"blocks\" section");
}

void read_conversion_region(const JsonObject& o, ConversionRegionDef& g) {
  const JsonObject r = section(o, "region");
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

/// The relaxation before the freeze: false / true, or an object (on unless "enabled": false).
void read_relax(const JsonObject& o, BlocksDef::Relax& r) {
  if (o.raw("relax").is_boolean()) {
    r.enabled = o.boolean("relax", r.enabled);
    return;
  }
  const JsonObject x = section(o, "relax");
  r.enabled = x.boolean("enabled", true);  // an object turns it on unless it says otherwise
  r.max_time = x.number("max_time", r.max_time, Range::positive(), "s",
                        "simulated time the relaxation may take at most, e.g. 30");
  r.speed = x.number("speed", r.speed, Range::positive(), "m/s",
                     "at rest when every block and particle is slower than this, e.g. 0.002");
  r.hold = x.number("hold", r.hold, Range::non_negative(), "s", "how long the speeds must stay below speed, e.g. 1");
  r.damping = x.number("damping", r.damping, Range::non_negative(), "1/s",
                       "numerical velocity damping during the relaxation only (a set-up device), e.g. 0.5");
  r.jointed_time = x.number("jointed_time", r.jointed_time, Range::non_negative(), "s",
                            "a second stage with the joints between blocks held unbreakable, e.g. 2; 0 = none");
  r.lattice_time = x.number("lattice_time", r.lattice_time, Range::non_negative(), "s",
                            "all_at_start: the rigid blocks relax first, then convert and their lattices relax for "
                            "at most this long, e.g. 2; 0 = convert before the relaxation");
  if (x.has("lattice_damping"))
    r.lattice_damping = x.number("lattice_damping", r.damping, Range::non_negative(), "1/s",
                                 "the lattice stage's damping (all_at_start), e.g. 0.5; default: damping");
  r.hold_freeze_bonds = x.boolean("hold_freeze_bonds", r.hold_freeze_bonds);
}

/// Rigid ice blocks and their conversion.
void read_blocks(const JsonObject& root, Scene& s, const std::string& base_dir) {
  if (!root.has("blocks")) return;
  const JsonObject o = section(root, "blocks");
  auto& b = s.blocks;
  s.has_blocks = true;
  read_block_sources(o, b, base_dir);
  b.density = o.number("density", s.material.density, Range::positive(), "kg/m^3", "ice density, e.g. 920");
  b.friction = o.number("friction", s.material.friction, Range::non_negative(), "", "ice-ice Coulomb coefficient");
  for (const char* k : {"linear_drag", "drag_coefficient"})
    if (o.has(k))
      throw InputError(o.at(k), std::string("blocks.") + k + " was removed: blocks and particles share the water's "
                                "drag. Use water." + (k[0] == 'l' ? "linear_drag_per_area" : "drag_coefficient") +
                                " instead (docs/engine.md, \"Water drag\")");
  b.solver_iterations = o.integer<int>("solver_iterations", b.solver_iterations, {1.0, 1000.0}, "",
                                       "Bullet sequential-impulse iterations, e.g. 20");
  b.solver_tolerance = o.number("solver_tolerance", b.solver_tolerance, Range::non_negative(), "m/s",
                                "the velocity correction below which a solve stops early, e.g. 1e-4; "
                                "0 = every solve takes solver_iterations");
  b.fixed_friction_directions = o.boolean("fixed_friction_directions", b.fixed_friction_directions);
  b.friction_sees_torque = o.boolean("friction_sees_torque", b.friction_sees_torque);
  b.rigid_dt = o.number("rigid_dt", b.rigid_dt, Range::non_negative(), "s",
                        "rigid step; 0 = the largest the stability rule allows (docs/bridge.md)");
  b.conversion = o.choice("conversion", b.conversion, {"hybrid", "all_at_start", "never"});
  b.lattice = o.choice("lattice", b.lattice, {"block", "world"});
  b.safety_factor = o.number("safety_factor", b.safety_factor, Range::positive(), "",
                             "a block converts when its stress utilisation x safety_factor >= 1; > 1 converts earlier");
  b.flexural_strength = o.number("flexural_strength", s.analysis.flexural_strength, Range::positive(), "Pa",
                                 "flexural strength of a block, e.g. 0.5e6");
  b.stress_time_constant = o.number("stress_time_constant", b.stress_time_constant, Range::non_negative(), "s",
                                    "time constant of the filter on each block's stress utilisation, e.g. 0.05");
  if (o.has("region")) read_conversion_region(o, b.region);
  b.relax.enabled = !b.ridge_file.empty();  // on by default for a ridge; a list keeps its initial state
  if (o.has("relax")) read_relax(o, b.relax);
  if (o.has("far_sleep")) {  // docs/rigid.md, "Far sleep"
    const JsonObject f = section(o, "far_sleep");
    b.far_sleep = f.boolean("enabled", true);
    b.far_sleep_wake_distance = f.number("wake_distance", b.far_sleep_wake_distance, Range::non_negative(), "m",
                                         "blocks this close to the structure's bounding box never sleep, e.g. 2");
    b.far_sleep_speed = f.number("speed", b.far_sleep_speed, Range::positive(), "m/s",
                                 "a block slower than this is still, e.g. 0.01");
    b.far_sleep_still_time = f.number("still_time", b.far_sleep_still_time, Range::non_negative(), "s",
                                      "a block still this long (with its neighbours) falls asleep, e.g. 0.5");
    b.far_sleep_start_asleep = f.boolean("start_asleep", b.far_sleep_start_asleep);
    b.far_sleep_wake_hops = f.integer<int>("wake_hops", b.far_sleep_wake_hops, {0.0, 1000.0}, "",
                                           "blocks this many contacts or joints from a moving one are woken, e.g. 4");
    b.far_sleep_loads_wake_neighbours = f.boolean("loads_wake_neighbours", b.far_sleep_loads_wake_neighbours);
    b.far_sleep_loads_held = f.boolean("loads_held", b.far_sleep_loads_held);
    b.far_sleep_region_awake = f.boolean("region_awake", b.far_sleep_region_awake);
    b.far_sleep_zone_wakes_neighbours = f.boolean("zone_wakes_neighbours", b.far_sleep_zone_wakes_neighbours);
  }
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

namespace {

/// "ice.consolidated_layer.thickness" -> {"ice", "consolidated_layer", "thickness"}.
std::vector<std::string> split_dotted(const std::string& dotted) {
  std::vector<std::string> parts;
  std::size_t pos = 0;
  while (true) {
    const std::size_t dot = dotted.find('.', pos);
    parts.push_back(dotted.substr(pos, dot == std::string::npos ? std::string::npos : dot - pos));
    if (dot == std::string::npos) break;
    pos = dot + 1;
  }
  return parts;
}

/// One --set step into an array: the element `part` of `node` (at `ptr`); nullptr when `last`
/// (then the element is set to `value`).
json* override_array_step(json* node, const std::string& ptr, const std::string& part, bool last, const json& value) {
  const std::string child = ptr + "/" + part;
  if (!is_index(part))
    throw InputError(child, "\"" + part + "\" is not an index into the array at " + json_pointer_display(ptr) +
                                "; use a number, e.g. walls.0.velocity");
  const std::size_t idx = std::stoul(part);
  if (idx >= node->size())
    throw InputError(child, "index " + part + " is out of range: the array at " + ptr + " has " +
                                std::to_string(node->size()) + " elements (--set cannot add elements)");
  if (last) {
    (*node)[idx] = value;
    return nullptr;
  }
  return &(*node)[idx];
}

/// One --set step into an object: checks `part` against the schema at `ptr`.
json* override_object_step(json* node, const std::string& ptr, const std::string& part, bool last, const json& value,
                           const std::string& dotted) {
  const std::string child = ptr + "/" + part;
  const auto& allowed = allowed_keys(ptr);
  if (allowed.empty())
    throw InputError(child, "--set path \"" + dotted + "\" does not exist in the scene schema: " +
                                json_pointer_display(ptr) + " is not an object");
  if (std::find(allowed.begin(), allowed.end(), part) == allowed.end())
    throw InputError(child, "--set path \"" + dotted + "\" does not exist in the scene schema: " +
                                unknown_key_text(part, allowed));
  if (!node->is_object()) throw InputError(json_pointer_display(ptr), "expected an object, got " + json_got(*node));
  if (last) {
    (*node)[part] = value;
    return nullptr;
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
  return node;
}

}  // namespace

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
  } catch (const json::out_of_range&) {  // 1e400
    throw InputError("--set", "\"" + text + "\" in \"" + assignment +
                                  "\" is beyond the range of a double (about 1.8e308); give a finite value");
  }
  const std::vector<std::string> parts = split_dotted(dotted);
  if (!scene.is_object()) throw InputError("/", "the scene must be a JSON object {...}");
  json* node = &scene;
  std::string ptr;
  for (std::size_t k = 0; k < parts.size(); ++k) {
    const std::string& part = parts[k];
    const bool last = k + 1 == parts.size();
    if (part.empty()) throw InputError("--set " + dotted, "empty path component; write e.g. ice.thickness=0.9");
    node = node->is_array() ? override_array_step(node, ptr, part, last, value)
                            : override_object_step(node, ptr, part, last, value, dotted);
    if (node == nullptr) return;
    ptr += "/" + part;
  }
}

// ------------------------------------------------------------------ parse_scene

Scene parse_scene(const json& j, const std::string& base_dir) {
  Scene s;
  s.json = j;
  s.base_dir = base_dir;
  const JsonObject root = section(j, "");
  read_top(root, s);
  read_time(root, s);
  read_material(root, s);
  read_bonds(root, s);
  read_water(root, s);
  s.gravity = root.vec<3>("gravity", s.gravity, "m/s^2", "e.g. [0, 0, -9.81]");
  read_ice(root, s);
  read_walls(root, s);
  read_structure(root, s, base_dir);
  read_analysis(root, s);
  read_stability(root, s);
  read_parallel(root, s);
  read_blocks(root, s, base_dir);
  return s;
}

Scene load_scene_file(const std::string& path, const std::vector<std::string>& overrides) {
  json j = read_json_file(path);
  if (!j.is_object()) throw InputError("/", "the scene must be a JSON object {...}, got " + json_got(j));
  for (const auto& o : overrides) apply_override(j, o);
  return parse_scene(j, std::filesystem::path(path).parent_path().string());
}

}  // namespace hs::scene
