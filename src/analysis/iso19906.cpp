// ISO 19906 cone loads; equations and sources in iso19906.h.
#include "analysis/iso19906.h"

#include "common/error.h"
#include "common/ice_formulas.h"
#include "json/reader.h"

#include <array>
#include <cmath>
#include <numbers>
#include <sstream>
#include <stdexcept>
#include <utility>

namespace hs::analysis {
namespace {

using Member = double IsoInputs::*;

/// One input: JSON key, field and unit (for messages).
struct Field {
  const char* key;
  Member member;
  const char* unit;
};

/// JSON key <-> field, in declaration order; the one list that keeps names in step.
constexpr std::array<Field, 19> kFields{{
    {"thickness", &IsoInputs::thickness, "m"},
    {"waterline_diameter", &IsoInputs::waterline_diameter, "m"},
    {"flexural_strength", &IsoInputs::flexural_strength, "Pa"},
    {"youngs_modulus", &IsoInputs::youngs_modulus, "Pa"},
    {"poisson_ratio", &IsoInputs::poisson_ratio, ""},
    {"cone_angle_deg", &IsoInputs::cone_angle_deg, "deg"},
    {"friction_ice_structure", &IsoInputs::friction_ice_structure, ""},
    {"friction_ice_ice", &IsoInputs::friction_ice_ice, ""},
    {"ice_density", &IsoInputs::ice_density, "kg/m^3"},
    {"water_density", &IsoInputs::water_density, "kg/m^3"},
    {"gravity", &IsoInputs::gravity, "m/s^2"},
    {"rubble_height", &IsoInputs::rubble_height, "m"},
    {"rubble_porosity", &IsoInputs::rubble_porosity, ""},
    {"rubble_cohesion", &IsoInputs::rubble_cohesion, "Pa"},
    {"rubble_slope_deg", &IsoInputs::rubble_slope_deg, "deg"},
    {"rubble_friction_angle_deg", &IsoInputs::rubble_friction_angle_deg, "deg"},
    {"keel_depth", &IsoInputs::keel_depth, "m"},
    {"keel_width", &IsoInputs::keel_width, "m"},
    {"keel_porosity", &IsoInputs::keel_porosity, ""},
}};

constexpr double kDeg = std::numbers::pi / 180.0;

/// Shortest text that reads back as the same double.
std::string num(double v) {
  std::string text;
  for (int digits = 6; digits <= 17; ++digits) {
    std::ostringstream out;
    out.precision(digits);
    out << v;
    text = out.str();
    double back = 0.0;
    std::istringstream(text) >> back;
    if (back == v) break;
  }
  return text;
}

class Checker {
 public:
  explicit Checker(const std::string& base) : base_(base) {}

  [[noreturn]] void fail(const char* key, double value, const std::string& allowed) const {
    throw InputError(base_ + "/" + key, "is " + num(value) + "; " + allowed);
  }
  void finite(const char* key, double v) const {
    if (!std::isfinite(v)) fail(key, v, "must be a finite number");
  }
  void positive(const char* key, double v, const char* unit) const {
    finite(key, v);
    if (!(v > 0.0)) fail(key, v, std::string("must be > 0 ") + unit);
  }
  void non_negative(const char* key, double v, const char* unit) const {
    finite(key, v);
    if (!(v >= 0.0)) fail(key, v, std::string("must be >= 0 ") + unit);
  }

 private:
  std::string base_;
};

}  // namespace

const std::vector<std::string>& iso_input_keys() {
  static const std::vector<std::string> keys = [] {
    std::vector<std::string> k;
    for (const auto& f : kFields) k.emplace_back(f.key);
    return k;
  }();
  return keys;
}

std::string iso_input_unit(const std::string& key) {
  for (const auto& f : kFields)
    if (key == f.key) return f.unit;
  throw std::out_of_range("not an ISO 19906 input: " + key);
}

void validate_iso_inputs(const IsoInputs& in, const std::string& base_path) {
  const Checker c(base_path);
  for (const auto& f : kFields) c.finite(f.key, in.*f.member);

  c.positive("thickness", in.thickness, "(m)");
  c.positive("waterline_diameter", in.waterline_diameter, "(m)");
  c.positive("flexural_strength", in.flexural_strength, "(Pa; sea ice is 0.3e6-0.7e6 Pa)");
  c.positive("youngs_modulus", in.youngs_modulus, "(Pa; sea ice is 1e9-9e9 Pa)");
  if (!(in.poisson_ratio >= 0.0 && in.poisson_ratio < 0.5))
    c.fail("poisson_ratio", in.poisson_ratio, "must be in [0, 0.5) (sea ice: 0.3)");
  if (!(in.cone_angle_deg > 0.0 && in.cone_angle_deg < 90.0))
    c.fail("cone_angle_deg", in.cone_angle_deg,
           "must be in (0, 90) degrees, measured from horizontal");
  c.non_negative("friction_ice_structure", in.friction_ice_structure, "(friction coefficient)");
  c.non_negative("friction_ice_ice", in.friction_ice_ice, "(friction coefficient)");
  c.positive("ice_density", in.ice_density, "(kg/m^3)");
  c.positive("water_density", in.water_density, "(kg/m^3)");
  if (!(in.ice_density < in.water_density))
    c.fail("ice_density", in.ice_density,
           "must be less than water_density (" + num(in.water_density) + " kg/m^3): the ice must float");
  c.positive("gravity", in.gravity, "(m/s^2)");
  c.non_negative("rubble_height", in.rubble_height, "(m)");
  if (!(in.rubble_porosity >= 0.0 && in.rubble_porosity < 1.0))
    c.fail("rubble_porosity", in.rubble_porosity, "must be in [0, 1) (typically 0.1-0.4)");
  if (!(in.keel_porosity >= 0.0 && in.keel_porosity < 1.0))
    c.fail("keel_porosity", in.keel_porosity, "must be in [0, 1) (typically 0.2-0.45)");
  c.non_negative("rubble_cohesion", in.rubble_cohesion, "(Pa)");
  if (!(in.rubble_slope_deg > 0.0 && in.rubble_slope_deg < in.cone_angle_deg))
    c.fail("rubble_slope_deg", in.rubble_slope_deg,
           "must be in (0, cone_angle_deg = " + num(in.cone_angle_deg) +
               ") degrees: the rubble pile is flatter than the cone");
  if (!(in.rubble_friction_angle_deg >= 0.0 && in.rubble_friction_angle_deg < 90.0))
    c.fail("rubble_friction_angle_deg", in.rubble_friction_angle_deg, "must be in [0, 90) degrees");
  c.non_negative("keel_depth", in.keel_depth, "(m; 0 = no keel)");
  c.non_negative("keel_width", in.keel_width, "(m; 0 = waterline_diameter)");

  const double a = in.cone_angle_deg * kDeg;
  const double mu = in.friction_ice_structure;
  if (!(std::cos(a) - mu * std::sin(a) > 0.0))
    c.fail("friction_ice_structure", mu,
           "the cone is self-locking: cos(a) - mu sin(a) must be > 0, i.e. mu < cot(a) = " +
               num(1.0 / std::tan(a)) + " for cone_angle_deg = " + num(in.cone_angle_deg) +
               "; the ice cannot ride up such a cone and the ISO formula does not apply");
  if (!(std::sin(a) - mu * std::cos(a) > 0.0))
    c.fail("friction_ice_structure", mu,
           "sin(a) - mu cos(a) must be > 0, i.e. mu < tan(a) = " + num(std::tan(a)) +
               " for cone_angle_deg = " + num(in.cone_angle_deg) +
               ": blocks at the top of the cone would not turn (H_T undefined)");

  // F_H denominator: 1 - H_B/(sigma_f l h) = 1 - 0.68 xi (rho_w g h / E)^(1/4).
  const double xi = (std::sin(a) + mu * std::cos(a)) / (std::cos(a) - mu * std::sin(a));
  const double ratio = 0.68 * xi *
      std::pow(in.water_density * in.gravity * in.thickness / in.youngs_modulus, 0.25);
  if (!(1.0 - ratio > 0.0))
    c.fail("cone_angle_deg", in.cone_angle_deg,
           "the Croasdale-Cammaert denominator 1 - H_B/(sigma_f l h) = 1 - 0.68 xi "
           "(rho_w g h/E)^(1/4) = " + num(1.0 - ratio) +
               " must be > 0: use a flatter cone, lower friction_ice_structure, thinner ice or "
               "a larger youngs_modulus");
}

double dem_over_iso(double dem_peak, const IsoResult& r) { return r.F_total > 0 ? dem_peak / r.F_total : 0.0; }

IsoResult compute_iso(const IsoInputs& in) {
  validate_iso_inputs(in);
  using std::cos;
  using std::pow;
  using std::sin;
  using std::tan;
  constexpr double pi = std::numbers::pi;

  const double h = in.thickness, w = in.waterline_diameter;
  const double sigma_f = in.flexural_strength, E = in.youngs_modulus, nu = in.poisson_ratio;
  const double a = in.cone_angle_deg * kDeg, th = in.rubble_slope_deg * kDeg;
  const double phi = in.rubble_friction_angle_deg * kDeg;
  const double mu = in.friction_ice_structure, mu_i = in.friction_ice_ice;
  const double rho_i = in.ice_density, rho_w = in.water_density, g = in.gravity;
  const double h_r = in.rubble_height, e = in.rubble_porosity, c = in.rubble_cohesion;
  const double h_k = in.keel_depth;
  const double w_k = in.keel_width > 0.0 ? in.keel_width : w;

  const double cot_a = 1.0 / tan(a), cot_th = 1.0 / tan(th);
  const double slope_factor = 1.0 - tan(th) / tan(a);   // (1 - tan th / tan a)
  const double gamma_r = rho_i * g * (1.0 - e);          // rubble weight density, N/m^3

  IsoResult r;
  r.xi = (sin(a) + mu * cos(a)) / (cos(a) - mu * sin(a));
  r.L_c = characteristic_length(E, h, rho_w, g, nu);
  r.l = w + pi * pi * r.L_c / 4.0;
  r.H_B = 0.68 * r.xi * sigma_f * pow(rho_w * g * pow(h, 5) / E, 0.25) * r.l;
  r.H_P = w * h_r * h_r * mu_i * gamma_r * slope_factor * slope_factor / (2.0 * tan(th));
  r.P = 0.5 * mu_i * (mu_i + mu) * gamma_r * h_r * h_r * sin(a) * (cot_th - cot_a) * slope_factor +
        0.5 * (mu_i + mu) * gamma_r * h_r * h_r * cos(a) * cot_a * slope_factor +
        h_r * h * rho_i * g * (sin(a) + mu * cos(a)) / sin(a);
  r.H_R = w * r.P / (cos(a) - mu * sin(a));
  r.H_L = r.xi * w * h_r * slope_factor *
          (0.5 * h_r * gamma_r * (cot_th - cot_a + tan(phi) * slope_factor) + c);
  r.H_T = 1.5 * w * h * h * rho_i * g * cos(a) / (sin(a) - mu * cos(a));
  r.F_H = (r.H_B + r.H_P + r.H_R + r.H_L + r.H_T) / (1.0 - r.H_B / (sigma_f * r.l * h));

  const double mu_phi = tan(pi / 4.0 + phi / 2.0);
  const double gamma_e = (1.0 - in.keel_porosity) * (rho_w - rho_i) * g;  // buoyant weight density of the keel
  r.F_K = h_k > 0.0
              ? mu_phi * h_k * w_k * (h_k * mu_phi * gamma_e / 2.0 + 2.0 * c) * (1.0 + h_k / (6.0 * w_k))
              : 0.0;
  r.F_total = r.F_H + r.F_K;
  return r;
}

IsoInputs iso_inputs_from_json(const nlohmann::json& j, const std::string& base_path) {
  const std::string hint = "ISO 19906 inputs are plain numbers in SI units (docs/iso19906.md)";
  const JsonObject o(j, base_path, iso_input_keys(), "an ISO 19906 input file is one object of numbers, e.g. "
                                                     "{\"thickness\": 0.6}; see docs/iso19906.md");
  IsoInputs in;
  for (const auto& f : kFields) in.*f.member = o.number(f.key, in.*f.member, JsonRange::any(), f.unit, hint);
  if (!o.has("keel_porosity")) in.keel_porosity = in.rubble_porosity;  // one porosity unless both are given
  validate_iso_inputs(in, base_path);
  return in;
}

nlohmann::json iso_inputs_to_json(const IsoInputs& in) {
  nlohmann::json j = nlohmann::json::object();
  for (const auto& f : kFields) j[f.key] = in.*f.member;
  return j;
}

nlohmann::json iso_to_json(const IsoResult& r) {
  return nlohmann::json{
      {"H_B", r.H_B}, {"H_P", r.H_P}, {"H_R", r.H_R}, {"H_L", r.H_L},
      {"H_T", r.H_T}, {"F_H", r.F_H}, {"F_K", r.F_K}, {"F_total", r.F_total},
      {"xi", r.xi},   {"L_c", r.L_c}, {"l", r.l},     {"P", r.P},
  };
}

}  // namespace hs::analysis
