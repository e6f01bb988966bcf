// A ridge's JSON: see ridge_json.h and docs/ridge.md.
#include "ridge/ridge_json.h"

#include "common/error.h"
#include "json/reader.h"
#include "ridge/definition.h"

#include <algorithm>
#include <filesystem>

namespace hs::rigid {

// Read with the shared reader (src/json/reader.h): JSON-pointer errors, did-you-mean on
// unknown keys, units in the messages. A null value means "not given" (ridge_def_to_json
// writes null for keel_width / sail_width). Ranges and cross-field rules are validate()'s.
namespace {

using Range = JsonRange;
const char* const kRidgeHelp = "see docs/ridge.md for the fields of a ridge definition";

const std::vector<std::string>& ridge_keys() {
  static const std::vector<std::string> k = {
      "name", "level_ice_thickness", "consolidated_layer_thickness", "consolidated_layer_width", "level_ice_margin",
      "ice_density", "water_density", "keel_depth", "keel_width", "shoulder_slope_deg", "keel_profile_csv",
      "keel_profile", "sail_height", "sail_width", "sail_slope_deg", "length", "end_walls", "block_thickness",
      "aspect_lognormal", "block_width_fraction", "max_tilt_deg", "fill_porosity", "placement_candidates", "seed",
      "settle", "joints", "profile_bin", "porosity_grid", "plate_width", "plates_joined"};
  return k;
}

void read_ridge_ice(const JsonObject& r, RidgeDef& d) {
  d.name = r.string("name", d.name, false, "free text, e.g. the scene name");
  d.level_ice_thickness = r.number("level_ice_thickness", d.level_ice_thickness, Range::any(), "m", "e.g. 0.6");
  d.consolidated_layer_thickness = r.number("consolidated_layer_thickness", d.consolidated_layer_thickness,
                                            Range::any(), "m", "e.g. 0.9");
  d.consolidated_layer_width = r.number("consolidated_layer_width", d.consolidated_layer_width, Range::any(), "m",
                                        "width of the layer, centred on x = 0, e.g. 20");
  d.level_ice_margin = r.number("level_ice_margin", d.level_ice_margin, Range::any(), "m",
                                "level ice beyond the keel and sail on each side, e.g. 10");
  d.ice_density = r.number("ice_density", d.ice_density, Range::any(), "kg/m^3", "e.g. 910");
  d.water_density = r.number("water_density", d.water_density, Range::any(), "kg/m^3", "e.g. 1025");
}

void read_keel_profile(const JsonObject& r, RidgeDef& d, const std::string& base_dir) {
  d.keel_profile_csv = r.string("keel_profile_csv", d.keel_profile_csv, false,
                                "a CSV file of position_m, depth_m, relative to the scene's directory");
  if (r.has("keel_profile")) {
    const nlohmann::json& a = r.array("keel_profile", "[position_m, depth_m] points");
    for (std::size_t i = 0; i < a.size(); ++i) {
      const std::string ep = r.at("keel_profile") + "/" + std::to_string(i);
      const Eigen::Vector2d e = json_vector<2>(a[i], ep, "m", "a profile point [position_m, depth_m]");
      const ProfilePoint pt{e[0], e[1]};
      if (pt.depth < 0.0)
        throw InputError(ep, "depth " + json_fmt(pt.depth) + " m must be >= 0 (m below the waterline)");
      if (!d.keel_profile.empty() && !(pt.position > d.keel_profile.back().position))
        throw InputError(ep, "position " + json_fmt(pt.position) + " m must be greater than the previous point's " +
                                 json_fmt(d.keel_profile.back().position) + " m: positions must increase strictly");
      d.keel_profile.push_back(pt);
    }
  } else if (!d.keel_profile_csv.empty()) {
    std::filesystem::path p(d.keel_profile_csv);
    if (p.is_relative() && !base_dir.empty()) p = std::filesystem::path(base_dir) / p;
    d.keel_profile = load_profile_csv(p.string());
  }
}

/// Keel and sail envelopes; the sail's defaults follow the keel's.
void read_ridge_shape(const JsonObject& r, RidgeDef& d, const std::string& base_dir) {
  d.keel_depth = r.number("keel_depth", d.keel_depth, Range::any(), "m", "keel depth below the waterline, e.g. 7.9");
  d.keel_width = r.number("keel_width", d.keel_width, Range::positive(), "m",
                          "keel width at the ice underside, or null for a triangle from shoulder_slope_deg");
  d.shoulder_slope_deg = r.number("shoulder_slope_deg", d.shoulder_slope_deg, Range::any(), "deg", "e.g. 6");
  d.sail_slope_deg = d.shoulder_slope_deg;
  d.sail_height = d.keel_depth / 4.4;
  read_keel_profile(r, d, base_dir);
  d.sail_height = r.number("sail_height", d.sail_height, Range::any(), "m",
                           "sail height above the waterline (default keel_depth / 4.4), 0 for no sail");
  d.sail_width = r.number("sail_width", d.sail_width, Range::positive(), "m",
                          "sail width at the ice top, or null for a triangle from sail_slope_deg");
  d.sail_slope_deg = r.number("sail_slope_deg", d.sail_slope_deg, Range::any(), "deg", "default shoulder_slope_deg");
  d.length = r.number("length", d.length, Range::any(), "m", "extent along the ridge (y), e.g. 200");
  d.end_walls = r.boolean("end_walls", d.end_walls);
}

void read_ridge_blocks(const JsonObject& r, RidgeDef& d) {
  d.block_thickness = r.number("block_thickness", d.level_ice_thickness, Range::any(), "m",
                               "default level_ice_thickness");
  if (r.has("aspect_lognormal")) {
    const JsonObject a = r.object("aspect_lognormal", {"mu", "sigma", "of"}, kRidgeHelp);
    d.aspect.mu = a.number("mu", d.aspect.mu, Range::any(), "", "e.g. 1.06");
    d.aspect.sigma = a.number("sigma", d.aspect.sigma, Range::any(), "", "e.g. 0.5");
    d.aspect.of_log = a.choice("of", "log", {"log", "ratio"},
                               "\"log\": ln(L/h) ~ N(mu, sigma); \"ratio\": L/h has mean mu and sd sigma") == "log";
  }
  const Eigen::Vector2d wf = r.vec<2>("block_width_fraction",
                                      Eigen::Vector2d(d.width_fraction_min, d.width_fraction_max), "",
                                      "[min, max] of block width / length, e.g. [0.5, 1]");
  d.width_fraction_min = wf[0];
  d.width_fraction_max = wf[1];
  d.max_tilt_deg = r.number("max_tilt_deg", d.max_tilt_deg, Range::any(), "deg", "90 for random orientations");
  d.fill_porosity = r.number("fill_porosity", d.fill_porosity, Range::any(), "", "e.g. 0.4");
  d.placement_candidates = r.integer<int>("placement_candidates", d.placement_candidates, Range::any(), "",
                                          "poses tried per block, e.g. 8");
  d.seed = r.integer<std::uint64_t>("seed", d.seed, Range::non_negative(), "", "a whole number >= 0, e.g. 1");
}

void read_ridge_settle(const JsonObject& r, RidgeSettleDef& s) {
  const JsonObject o = r.object("settle",
                                {"dt", "solver_iterations", "kinetic_energy_per_block", "max_displacement", "min_time",
                                 "max_time",
                                 "friction", "linear_drag", "quadratic_drag_cd", "speed_cap_factor", "allow_sleep",
                                 "compaction_friction", "compaction_time", "compaction_solver_iterations", "damping",
                                 "fixed_friction_directions"},
                                kRidgeHelp);
  const std::string hint = "see docs/ridge.md, settle";
  s.dt = o.number("dt", s.dt, Range::any(), "s", "rigid time step, e.g. 0.0333");
  s.solver_iterations = o.integer<int>("solver_iterations", s.solver_iterations, Range::any(), "", "e.g. 20");
  s.kinetic_energy_per_block =
      o.number("kinetic_energy_per_block", s.kinetic_energy_per_block, Range::any(), "J", "settled below, e.g. 0.01");
  s.max_displacement = o.number("max_displacement", s.max_displacement, Range::any(), "m",
                                "largest block displacement in the last second, e.g. 0.002 (0: not checked)");
  s.min_time = o.number("min_time", s.min_time, Range::any(), "s", hint);
  s.max_time = o.number("max_time", s.max_time, Range::any(), "s", hint);
  s.friction = o.number("friction", s.friction, Range::any(), "", "ice-ice Coulomb coefficient, e.g. 0.5");
  s.linear_drag = o.number("linear_drag", s.linear_drag, Range::any(), "Pa s/m", "e.g. 1000");
  s.quadratic_drag_cd = o.number("quadratic_drag_cd", s.quadratic_drag_cd, Range::any(), "", "e.g. 1");
  s.speed_cap_factor = o.number("speed_cap_factor", s.speed_cap_factor, Range::any(), "", "e.g. 0.25");
  s.allow_sleep = o.boolean("allow_sleep", s.allow_sleep);
  s.compaction_friction = o.number("compaction_friction", s.compaction_friction, Range::any(), "", "e.g. 0");
  s.compaction_time = o.number("compaction_time", s.compaction_time, Range::any(), "s", "0 for no compaction phase");
  s.damping = o.number("damping", s.damping, Range::any(), "1/s", "e.g. 5");
  s.fixed_friction_directions = o.boolean("fixed_friction_directions", s.fixed_friction_directions);
  s.compaction_solver_iterations =
      o.integer<int>("compaction_solver_iterations", s.compaction_solver_iterations, Range::any(), "", "e.g. 10");
}

}  // namespace

RidgeDef ridge_def_from_json(const nlohmann::json& j, const std::string& P, const std::string& base_dir) {
  RidgeDef d;
  const JsonObject r(j, P, ridge_keys(), kRidgeHelp, JsonNull::IsAbsent);
  read_ridge_ice(r, d);
  read_ridge_shape(r, d, base_dir);
  read_ridge_blocks(r, d);
  if (r.has("settle")) read_ridge_settle(r, d.settle);
  if (r.has("joints")) {
    const JsonObject o = r.object("joints", {"gap", "min_area", "to_ice"}, kRidgeHelp);
    d.joints.gap = o.number("gap", d.joints.gap, Range::any(), "m", "blocks closer than this touch, e.g. 0.02");
    d.joints.min_area = o.number("min_area", d.joints.min_area, Range::any(), "m^2", "e.g. 0.01");
    d.joints.to_ice = o.boolean("to_ice", d.joints.to_ice);
  }
  d.profile_bin = r.number("profile_bin", d.profile_bin, Range::any(), "m", "e.g. 1");
  d.porosity_grid = r.number("porosity_grid", d.porosity_grid, Range::any(), "m", "e.g. 0.25");
  d.sheet.plate_width = r.number("plate_width", d.sheet.plate_width, Range::any(), "m",
                                 "x width of the floating plate strips (ridges of a run scene), 0 for one plate per part");
  d.sheet.plates_joined = r.boolean("plates_joined", d.sheet.plates_joined);
  validate_ridge_def(d, P);
  return d;
}

nlohmann::json ridge_def_to_json(const RidgeDef& d) {
  nlohmann::json j;
  j["name"] = d.name;
  j["level_ice_thickness"] = d.level_ice_thickness;
  j["consolidated_layer_thickness"] = d.consolidated_layer_thickness;
  j["consolidated_layer_width"] = d.consolidated_layer_width;
  j["level_ice_margin"] = d.level_ice_margin;
  j["ice_density"] = d.ice_density;
  j["water_density"] = d.water_density;
  j["keel_depth"] = d.keel_depth;
  j["keel_width"] = d.keel_width > 0.0 ? nlohmann::json(d.keel_width) : nlohmann::json(nullptr);
  j["shoulder_slope_deg"] = d.shoulder_slope_deg;
  j["keel_profile_csv"] = d.keel_profile_csv;
  if (!d.keel_profile.empty()) {
    nlohmann::json a = nlohmann::json::array();
    for (const ProfilePoint& p : d.keel_profile) a.push_back({p.position, p.depth});
    j["keel_profile"] = a;
  }
  j["sail_height"] = d.sail_height;
  j["sail_width"] = d.sail_width > 0.0 ? nlohmann::json(d.sail_width) : nlohmann::json(nullptr);
  j["sail_slope_deg"] = d.sail_slope_deg;
  j["length"] = d.length;
  j["end_walls"] = d.end_walls;
  j["block_thickness"] = d.block_thickness;
  j["aspect_lognormal"] = {{"mu", d.aspect.mu}, {"sigma", d.aspect.sigma},
                           {"of", d.aspect.of_log ? "log" : "ratio"}};
  j["block_width_fraction"] = {d.width_fraction_min, d.width_fraction_max};
  j["max_tilt_deg"] = d.max_tilt_deg;
  j["fill_porosity"] = d.fill_porosity;
  j["placement_candidates"] = d.placement_candidates;
  j["seed"] = d.seed;
  j["settle"] = {{"dt", d.settle.dt},
                 {"solver_iterations", d.settle.solver_iterations},
                 {"kinetic_energy_per_block", d.settle.kinetic_energy_per_block},
                 {"max_displacement", d.settle.max_displacement},
                 {"min_time", d.settle.min_time},
                 {"max_time", d.settle.max_time},
                 {"friction", d.settle.friction},
                 {"linear_drag", d.settle.linear_drag},
                 {"quadratic_drag_cd", d.settle.quadratic_drag_cd},
                 {"speed_cap_factor", d.settle.speed_cap_factor},
                 {"allow_sleep", d.settle.allow_sleep},
                 {"compaction_friction", d.settle.compaction_friction},
                 {"compaction_time", d.settle.compaction_time},
                 {"compaction_solver_iterations", d.settle.compaction_solver_iterations},
                 {"damping", d.settle.damping},
                 {"fixed_friction_directions", d.settle.fixed_friction_directions}};
  j["joints"] = {{"gap", d.joints.gap}, {"min_area", d.joints.min_area}, {"to_ice", d.joints.to_ice}};
  j["profile_bin"] = d.profile_bin;
  j["porosity_grid"] = d.porosity_grid;
  j["plate_width"] = d.sheet.plate_width;
  j["plates_joined"] = d.sheet.plates_joined;
  return j;
}

nlohmann::json ridge_generation_json(const RidgeResult& r) {
  const RidgeDef& d = r.def;
  nlohmann::json j;
  j["ice_density"] = d.ice_density;
  j["water_density"] = d.water_density;
  j["friction"] = d.settle.friction;
  j["compaction_friction"] = d.settle.compaction_friction;
  j["level_ice_thickness"] = d.level_ice_thickness;
  j["consolidated_layer"] = {{"thickness", d.consolidated_layer_thickness},
                             {"width", d.consolidated_layer_width},
                             {"center_x", d.sheet.consolidated_layer_center_x}};
  if (!d.sheet.floating) {
    j["sheet"] = {{"kind", "fixed"}};
  } else {
    j["sheet"] = {{"kind", "floating"},
                  {"particle_diameter", d.sheet.particle_diameter},
                  {"plate_width", d.sheet.plate_width},
                  {"plates_joined", d.sheet.plates_joined},
                  {"level_ice", {{"top_z", d.sheet.level_top}, {"underside_z", d.sheet.level_underside}}},
                  {"consolidated_layer",
                   {{"top_z", d.sheet.layer_top}, {"underside_z", d.sheet.layer_underside}, {"width", d.sheet.layer_width}}}};
  }
  nlohmann::json plates = nlohmann::json::array();
  if (d.sheet.floating)
    for (const IceBox& b : r.ice)
      plates.push_back({{"x", {b.position.x() - b.half_extents.x(), b.position.x() + b.half_extents.x()}},
                        {"part", b.part},
                        {"lift", b.lift}});
  j["plates"] = plates;
  j["vertical_balance_N"] = {{"blocks", r.stats.block_net_buoyancy}, {"plates", r.stats.plate_net_buoyancy}};
  return j;
}

nlohmann::json ridge_report(const RidgeResult& r) {
  const RidgeStats& s = r.stats;
  nlohmann::json j;
  j["name"] = r.def.name;
  j["blocks"] = {{"keel", s.keel_blocks}, {"sail", s.sail_blocks}, {"total", r.blocks.size()}};
  j["joints"] = {{"total", s.joints}, {"to_ice", s.ice_joints}};
  j["block_volume_m3"] = {{"keel", s.keel_block_volume}, {"sail", s.sail_block_volume}};
  j["keel_target_volume_m3"] = s.keel_target_volume;
  j["keel_porosity"] = s.keel_porosity;
  j["core_porosity"] = s.core_porosity;
  j["keel_depth_m"] = {{"target", s.keel_depth_target}, {"achieved_p95", s.keel_depth_achieved}};
  j["sail_height_m"] = {{"target", s.sail_height_target}, {"achieved_p95", s.sail_height_achieved}};
  j["keel_profile_rms_error_m"] = s.keel_profile_rms_error;
  j["settle"] = {{"settled", s.settled},
                 {"time_s", s.settle_time},
                 {"compaction_end_s", s.compaction_time},
                 {"steps", s.settle_steps},
                 {"kinetic_energy_per_block_J", s.final_kinetic_energy_per_block},
                 {"kinetic_energy_per_awake_block_J", s.final_kinetic_energy_per_awake_block},
                 {"asleep_blocks", s.final_asleep_blocks},
                 {"kinetic_energy_median_J", s.final_kinetic_energy_median},
                 {"kinetic_energy_sail_fraction", s.final_kinetic_energy_sail_fraction},
                 {"last_second_displacement_m", {{"mean", s.final_mean_displacement}, {"max", s.final_max_displacement}}}};
  j["max_final_overlap_m"] = s.max_final_overlap;
  j["vertical_balance_N"] = {{"blocks_net_buoyancy", s.block_net_buoyancy},
                             {"plates_net_buoyancy", s.plate_net_buoyancy},
                             {"sum", s.block_net_buoyancy + s.plate_net_buoyancy}};
  if (r.def.sheet.floating) {
    double lo = 1e300, hi = -1e300, lmax = -1e300;
    for (const IceBox& b : r.ice) {
      lo = std::min(lo, b.lift);
      hi = std::max(hi, b.lift);
      if (b.part == 1) lmax = std::max(lmax, b.lift);
    }
    j["plate_lift_m"] = {{"min", lo}, {"max", hi}, {"consolidated_layer_max", lmax}};
  }
  j["wall_time_s"] = s.wall_time;
  return j;
}

}  // namespace hs::rigid
