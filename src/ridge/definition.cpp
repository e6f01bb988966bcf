// The definition's geometry and checks: see definition.h and docs/ridge.md.
#include "ridge/definition.h"

#include "common/error.h"
#include "common/ice_formulas.h"
#include "json/reader.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>

namespace hs::rigid {

namespace {
constexpr double kDeg = 3.14159265358979323846 / 180.0;
}  // namespace

void AspectLognormal::log_params(double& m, double& s) const {
  if (of_log) {
    m = mu;
    s = sigma;
  } else {
    const double s2 = std::log(1.0 + sigma * sigma / (mu * mu));
    s = std::sqrt(s2);
    m = std::log(mu) - 0.5 * s2;
  }
}

double keel_half_width(const RidgeDef& d) {
  if (!d.keel_profile.empty())
    return std::max(std::abs(d.keel_profile.front().position), std::abs(d.keel_profile.back().position));
  const double dli = flotation_draft(d.level_ice_thickness, d.ice_density, d.water_density);
  if (d.keel_width > 0.0) return 0.5 * d.keel_width;
  return std::max(0.0, d.keel_depth - dli) / std::tan(d.shoulder_slope_deg * kDeg);
}

double sail_half_width(const RidgeDef& d) {
  if (d.sail_height <= 0.0) return 0.0;
  const double fli = flotation_freeboard(d.level_ice_thickness, d.ice_density, d.water_density);
  if (d.sail_width > 0.0) return 0.5 * d.sail_width;
  return std::max(0.0, d.sail_height - fli) / std::tan(d.sail_slope_deg * kDeg);
}

double layer_half_width(const RidgeDef& d) {
  return 0.5 * (d.sheet.floating && d.consolidated_layer_width > 0.0 ? d.sheet.layer_width : d.consolidated_layer_width);
}

double ice_draft(const RidgeDef& d, double x) {
  const bool in_layer = std::abs(x) < layer_half_width(d);
  if (d.sheet.floating) return -(in_layer ? d.sheet.layer_underside : d.sheet.level_underside);
  const double t = std::abs(x) < 0.5 * d.consolidated_layer_width ? d.consolidated_layer_thickness
                                                                  : d.level_ice_thickness;
  return flotation_draft(t, d.ice_density, d.water_density);
}
double ice_freeboard(const RidgeDef& d, double x) {
  const bool in_layer = std::abs(x) < layer_half_width(d);
  if (d.sheet.floating) return in_layer ? d.sheet.layer_top : d.sheet.level_top;
  const double t = std::abs(x) < 0.5 * d.consolidated_layer_width ? d.consolidated_layer_thickness
                                                                  : d.level_ice_thickness;
  return flotation_freeboard(t, d.ice_density, d.water_density);
}

double keel_target_depth(const RidgeDef& d, double x) {
  if (!d.keel_profile.empty()) {
    const auto& p = d.keel_profile;
    if (x < p.front().position || x > p.back().position) return 0.0;
    auto it = std::upper_bound(p.begin(), p.end(), x,
                               [](double v, const ProfilePoint& q) { return v < q.position; });
    if (it == p.end()) return p.back().depth;
    const ProfilePoint& b = *it;
    const ProfilePoint& a = *(it - 1);
    const double t = (x - a.position) / (b.position - a.position);
    return a.depth + t * (b.depth - a.depth);
  }
  const double hw = keel_half_width(d);
  if (std::abs(x) >= hw) return 0.0;
  const double dli = flotation_draft(d.level_ice_thickness, d.ice_density, d.water_density);
  return std::min(d.keel_depth, dli + (hw - std::abs(x)) * std::tan(d.shoulder_slope_deg * kDeg));
}

double sail_target_height(const RidgeDef& d, double x) {
  const double hw = sail_half_width(d);
  if (std::abs(x) >= hw) return 0.0;
  const double fli = flotation_freeboard(d.level_ice_thickness, d.ice_density, d.water_density);
  return std::min(d.sail_height, fli + (hw - std::abs(x)) * std::tan(d.sail_slope_deg * kDeg));
}

std::vector<ProfilePoint> load_profile_csv(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path, "cannot open the keel profile CSV");
  std::vector<ProfilePoint> pts;
  std::string line;
  int lineno = 0;
  bool first_content = true;
  auto parse = [](const std::string& s, double& v) {
    std::size_t a = s.find_first_not_of(" \t");
    std::size_t b = s.find_last_not_of(" \t");
    if (a == std::string::npos) return false;
    const std::string t = s.substr(a, b - a + 1);
    char* end = nullptr;
    v = std::strtod(t.c_str(), &end);
    return end == t.c_str() + t.size() && std::isfinite(v);
  };
  while (std::getline(in, line)) {
    ++lineno;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const std::size_t nb = line.find_first_not_of(" \t");
    if (nb == std::string::npos || line[nb] == '#') continue;
    std::vector<std::string> cols;
    std::stringstream ss(line);
    std::string c;
    while (std::getline(ss, c, ',')) cols.push_back(c);
    if (!line.empty() && line.back() == ',') cols.push_back("");
    double x = 0.0, dep = 0.0;
    const bool ok = cols.size() == 2 && parse(cols[0], x) && parse(cols[1], dep);
    if (!ok) {
      if (first_content) {  // header line
        first_content = false;
        continue;
      }
      throw InputError(path, "line " + std::to_string(lineno) +
                                 ": expected two comma-separated numbers 'position_m, depth_m', got '" +
                                 line + "'");
    }
    first_content = false;
    if (dep < 0.0)
      throw InputError(path, "line " + std::to_string(lineno) + ": depth_m must be >= 0 (m below the waterline)");
    if (!pts.empty() && !(x > pts.back().position))
      throw InputError(path, "line " + std::to_string(lineno) + ": position_m must increase strictly");
    pts.push_back({x, dep});
  }
  if (pts.size() < 2)
    throw InputError(path, "line " + std::to_string(lineno) + ": need at least two profile points");
  return pts;
}

void validate_ridge_def(const RidgeDef& d, const std::string& P) {
  auto req = [&](bool ok, const std::string& key, const std::string& msg) {
    if (!ok) throw InputError(P + "/" + key, msg);
  };
  req(d.level_ice_thickness > 0.0, "level_ice_thickness", "must be > 0 (m)");
  req(d.consolidated_layer_thickness > 0.0, "consolidated_layer_thickness", "must be > 0 (m)");
  req(d.consolidated_layer_width >= 0.0, "consolidated_layer_width", "must be >= 0 (m)");
  req(d.level_ice_margin >= 0.0, "level_ice_margin", "must be >= 0 (m)");
  req(d.ice_density > 0.0 && d.ice_density < d.water_density, "ice_density",
      "must be > 0 and below water_density (kg/m^3)");
  req(d.water_density > 0.0, "water_density", "must be > 0 (kg/m^3)");
  const double dli = flotation_draft(d.level_ice_thickness, d.ice_density, d.water_density);
  const double fli = d.level_ice_thickness - dli;
  req(d.shoulder_slope_deg > 0.0 && d.shoulder_slope_deg < 90.0, "shoulder_slope_deg",
      "must be in (0, 90) degrees");
  req(d.sail_slope_deg > 0.0 && d.sail_slope_deg < 90.0, "sail_slope_deg", "must be in (0, 90) degrees");
  if (d.keel_profile.empty()) {
    req(d.keel_depth > dli, "keel_depth",
        "must exceed the level-ice draft " + std::to_string(dli) + " m (m below the waterline)");
    if (d.keel_width > 0.0) {
      const double need = 2.0 * (d.keel_depth - dli) / std::tan(d.shoulder_slope_deg * kDeg);
      req(d.keel_width >= need, "keel_width",
          "is " + std::to_string(d.keel_width) + " m, but shoulders of " +
              std::to_string(d.shoulder_slope_deg) + " deg need at least " + std::to_string(need) +
              " m to reach keel_depth; widen it, steepen shoulder_slope_deg, or leave keel_width out "
              "(null: triangle from the slope)");
    }
  } else {
    req(d.keel_profile.size() >= 2, "keel_profile", "needs at least two points");
  }
  req(d.sail_height >= 0.0, "sail_height", "must be >= 0 (m above the waterline; 0: no sail)");
  if (d.sail_height > 0.0) {
    req(d.sail_height > fli, "sail_height",
        "must exceed the level-ice freeboard " + std::to_string(fli) + " m, or be 0 (no sail)");
    if (d.sail_width > 0.0) {
      const double need = 2.0 * (d.sail_height - fli) / std::tan(d.sail_slope_deg * kDeg);
      req(d.sail_width >= need, "sail_width",
          "must be at least " + std::to_string(need) + " m for the sail slope; or null");
    }
  }
  req(d.length > 0.0, "length", "must be > 0 (m)");
  req(d.block_thickness > 0.0, "block_thickness", "must be > 0 (m)");
  req(d.aspect.sigma >= 0.0, "aspect_lognormal/sigma", "must be >= 0");
  req(d.aspect.of_log || d.aspect.mu > 0.0, "aspect_lognormal/mu", "must be > 0 when of = \"ratio\"");
  req(d.width_fraction_min > 0.0 && d.width_fraction_min <= d.width_fraction_max &&
          d.width_fraction_max <= 1.0,
      "block_width_fraction", "must be [min, max] with 0 < min <= max <= 1");
  req(d.max_tilt_deg >= 0.0 && d.max_tilt_deg <= 90.0, "max_tilt_deg", "must be in [0, 90] degrees");
  req(d.fill_porosity >= 0.0 && d.fill_porosity < 0.9, "fill_porosity", "must be in [0, 0.9)");
  req(d.placement_candidates >= 1 && d.placement_candidates <= 1000, "placement_candidates",
      "must be in [1, 1000]");
  const RidgeSettleDef& s = d.settle;
  req(s.dt > 0.0 && s.dt <= 0.1, "settle/dt", "must be in (0, 0.1] s");
  req(s.linear_drag * s.dt / (d.ice_density * d.block_thickness) < 1.0, "settle/dt",
      "too large for the linear water drag: need linear_drag dt / (ice_density block_thickness) < 1");
  req(s.solver_iterations >= 1, "settle/solver_iterations", "must be >= 1");
  req(s.kinetic_energy_per_block > 0.0, "settle/kinetic_energy_per_block", "must be > 0 (J)");
  req(s.max_displacement >= 0.0, "settle/max_displacement", "must be >= 0 (m; 0 = not checked)");
  req(s.min_time >= 0.0, "settle/min_time", "must be >= 0 (s)");
  req(s.max_time >= s.min_time, "settle/max_time", "must be >= min_time (s)");
  req(s.friction >= 0.0, "settle/friction", "must be >= 0");
  req(s.compaction_friction >= 0.0, "settle/compaction_friction", "must be >= 0");
  req(s.compaction_time >= 0.0 && s.compaction_time <= s.max_time, "settle/compaction_time",
      "must be in [0, max_time] (s; 0: no compaction phase)");
  req(s.damping >= 0.0, "settle/damping", "must be >= 0 (1/s)");
  req(s.compaction_solver_iterations >= 1, "settle/compaction_solver_iterations", "must be >= 1");
  req(s.linear_drag >= 0.0, "settle/linear_drag", "must be >= 0 (Pa s/m)");
  req(s.quadratic_drag_cd >= 0.0, "settle/quadratic_drag_cd", "must be >= 0");
  req(s.speed_cap_factor > 0.0 && s.speed_cap_factor <= 0.5, "settle/speed_cap_factor",
      "must be in (0, 0.5]");
  req(d.joints.gap > 0.0, "joints/gap", "must be > 0 (m)");
  req(d.joints.min_area >= 0.0, "joints/min_area", "must be >= 0 (m^2)");
  req(d.profile_bin > 0.0, "profile_bin", "must be > 0 (m)");
  req(d.porosity_grid > 0.0, "porosity_grid", "must be > 0 (m)");
  req(d.sheet.plate_width >= 0.0, "plate_width", "must be >= 0 (m; 0: one plate per part)");
  if (d.sheet.floating) {
    const RidgeSheet& h = d.sheet;
    req(h.level_top > 0.0 && h.level_underside < 0.0 && h.layer_top > 0.0 && h.layer_underside < 0.0, "",
        "the run's sheet must float with its top above and its underside below the waterline (level ice " +
            json_fmt(h.level_underside) + " .. " + json_fmt(h.level_top) + " m, consolidated layer " +
            json_fmt(h.layer_underside) + " .. " + json_fmt(h.layer_top) + " m)");
    req(d.consolidated_layer_width <= 0.0 || h.layer_width >= d.consolidated_layer_width, "",
        "the run's consolidated layer (" + json_fmt(h.layer_width) + " m of particles) must be at least " +
            "consolidated_layer_width (" + json_fmt(d.consolidated_layer_width) + " m) wide");
  }
}

double plate_density(double top, double underside, double water_density) {
  if (!(top > 0.0 && underside < 0.0))
    throw InputError("", "a floating plate needs its top above and its underside below the waterline (top " +
                             json_fmt(top) + " m, underside " + json_fmt(underside) + " m)");
  return water_density * (-underside) / (top - underside);
}

}  // namespace hs::rigid
