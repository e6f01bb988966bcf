#include "app/calibrate_command.h"

#include "calib/lab_tests.h"
#include "common/error.h"
#include "common/ice_formulas.h"
#include "json/reader.h"
#include "scene/scene.h"
#include "sim/calibrated_ice.h"

#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <sstream>

namespace hs::app {

namespace {

scene::Scene load(const RunOptions& opt) {
  nlohmann::json j = scene::read_json_file(opt.scene_path);
  if (!j.is_object()) throw InputError("/", "the file must be a JSON object: a scene, or {\"material\": {...}, "
                                            "\"ice\": {\"thickness\": ...}}");
  // A partial scene (material file): what the lab tests do not use is filled in.
  if (!j.contains("name")) j["name"] = "calibrate";
  if (!j.contains("time")) j["time"] = {{"duration", 1.0}};
  if (!j.contains("ice"))
    throw InputError("/ice", "the lattice's thickness is needed: add \"ice\": {\"thickness\": 0.6} (m)");
  for (const char* k : {"length", "width"})
    if (j["ice"].is_object() && !j["ice"].contains(k)) j["ice"][k] = 10.0;
  for (const auto& o : opt.overrides) scene::apply_override(j, o);
  return scene::parse_scene(j, std::filesystem::path(opt.scene_path).parent_path().string());
}

std::string fmt(double v) {
  std::ostringstream s;
  s << std::setprecision(4) << v;
  return s.str();
}

}  // namespace

int calibrate_command(const RunOptions& opt, std::ostream& out, std::FILE* progress) {
  const scene::Scene s = load(opt);
  const sim::CalibratedIce ci = sim::calibrate_ice(s);
  for (const auto& w : ci.warnings) std::fprintf(progress, "warning: %s\n", w.c_str());
  const auto t0 = std::chrono::steady_clock::now();
  calib::LabOptions lo;
  lo.progress = [&](const std::string& test, double f) {
    const double el = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::fprintf(progress, "[calibrate] %-20s %3.0f %%  (%.0f s)\n", test.c_str(), 100.0 * f, el);
    std::fflush(progress);
  };
  std::fprintf(progress, "[calibrate] %s lattice: %d layers of D = %g m (h = %g m), k_n = %g N/m, k_s = %g N/m, "
                         "bond strength %g Pa (from %s)\n",
               ci.model.c_str(), ci.layers, s.material.particle_diameter, ci.thickness, ci.kn, ci.ks,
               ci.bond_tensile_strength, ci.strength_source.c_str());
  lo.max_strip_steps = opt.max_strip_steps;
  lo.linear_regime = !opt.calibrate_scene_strength;
  auto wanted = [&](const std::string& name) { return ("," + opt.calibrate_tests + ",").find("," + name + ",") != std::string::npos; };
  for (std::string rest = opt.calibrate_tests + ","; !rest.empty();) {
    const std::string name = rest.substr(0, rest.find(','));
    rest = rest.substr(rest.find(',') + 1);
    if (name != "tension" && name != "bending" && name != "strip")
      throw InputError("--tests", "unknown test \"" + name + "\"; give a comma-separated subset of tension,bending,strip");
  }
  calib::TensionResult t;
  calib::BendingResult b;
  calib::StripResult st;
  t.poisson_ratio = ci.poisson_ratio;
  if (wanted("tension")) t = calib::tension_test(s, lo);
  if (wanted("bending")) b = calib::bending_test(s, lo);
  if (wanted("strip")) st = calib::strip_test(s, t.poisson_ratio, lo);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  const double rho_w = s.water.density, g = s.gravity.norm();
  const double nu_t = s.material.poisson_ratio;
  const double Lc_target = characteristic_length(s.material.youngs_modulus, ci.thickness, rho_w, g, nu_t);
  const bool flex_target = ci.strength_source == "/material/flexural_strength";
  nlohmann::json j;
  // "measured" is null for a quantity whose test was not run (--tests).
  auto entry = [&](const char* key, double target, bool has_target, double measured, bool ran) {
    j[key] = {{"target", has_target ? nlohmann::json(target) : nlohmann::json(nullptr)},
              {"measured", ran ? nlohmann::json(measured) : nlohmann::json(nullptr)}};
  };
  const bool ran_t = wanted("tension"), ran_b = wanted("bending"), ran_s = wanted("strip");
  entry("E", s.material.youngs_modulus, true, t.youngs_modulus, ran_t);
  entry("nu", nu_t, true, t.poisson_ratio, ran_t);
  j["nu"]["reachable"] = !ci.poisson_clamped;
  j["nu"]["closest"] = ci.poisson_ratio;
  j["nu"]["range"] = {ci.poisson_min, ci.poisson_max};
  entry("tensile_strength", ci.target_tensile_strength, ci.target_tensile_strength > 0, t.tensile_strength, ran_t);
  entry("flexural_strength", s.material.flexural_strength, flex_target, b.flexural_strength, ran_b);
  entry("characteristic_length", Lc_target, true, st.characteristic_length, ran_s);
  j["model"] = ci.model;
  j["layers"] = ci.layers;
  j["thickness"] = ci.thickness;
  j["kn"] = ci.kn;
  j["ks"] = ci.ks;
  j["bond_tensile_strength"] = ci.bond_tensile_strength;
  j["bond_shear_strength"] = ci.bond_shear_strength;
  j["strength_source"] = ci.strength_source;
  j["predicted"] = {{"E", ci.youngs_modulus}, {"nu", ci.poisson_ratio}, {"flexural_strength", ci.flexural_strength},
                    {"tensile_strength", ci.tensile_strength}};
  j["tests"] = {{"tension", {{"particles", t.particles}, {"nu_z", t.poisson_ratio_z}}},
                {"bending", {{"particles", b.particles}, {"span", b.span}, {"width", b.width}, {"peak_force", b.peak_force},
                              {"peak_strength", b.peak_strength}, {"strength_scale", b.strength_scale}, {"first_break_time", b.first_break_time}}},
                {"strip", {{"particles", st.particles}, {"softening", st.softening}, {"beam_characteristic_length", st.strip_length},
                           {"fit_rms", st.fit_rms}}}};
  j["seconds"] = seconds;

  out << "calibrate: " << s.name << " (" << ci.model << ", " << ci.layers << " layers, h = " << fmt(ci.thickness)
      << " m, D = " << fmt(s.material.particle_diameter) << " m), " << fmt(seconds) << " s\n";
  out << "  quantity                  target        measured      difference\n";
  auto row = [&](const std::string& name, const nlohmann::json& e, const std::string& unit, bool absolute) {
    const bool ran = !e["measured"].is_null();
    const double m = ran ? e["measured"].get<double>() : 0.0;
    std::string tgt = "-", diff = "-";
    if (!e["target"].is_null()) {
      const double tv = e["target"].get<double>();
      tgt = fmt(tv);
      if (ran)
        diff = absolute ? (m - tv >= 0 ? "+" : "") + fmt(m - tv) : (m >= tv ? "+" : "") + fmt(100.0 * (m / tv - 1.0)) + " %";
    }
    out << "  " << std::left << std::setw(26) << (name + " (" + unit + ")") << std::setw(14) << tgt << std::setw(14)
        << (ran ? fmt(m) : std::string("not run")) << diff << "\n";
  };
  row("E", j["E"], "Pa", false);
  row("nu", j["nu"], "-", true);
  row("tensile strength", j["tensile_strength"], "Pa", false);
  row("flexural strength", j["flexural_strength"], "Pa", false);
  row("L_c", j["characteristic_length"], "m", false);
  if (ci.poisson_clamped)
    out << "  nu = " << fmt(nu_t) << " is not reachable with this lattice (range " << fmt(ci.poisson_min) << " ... "
        << fmt(ci.poisson_max) << "): closest " << fmt(ci.poisson_ratio) << "\n";
  if (st.softening > 1)
    out << "  (floating strip run with springs / " << fmt(st.softening) << ", L_c scaled back by its 1/4 power)\n";
  out << j.dump() << "\n";
  return 0;
}

}  // namespace hs::app
