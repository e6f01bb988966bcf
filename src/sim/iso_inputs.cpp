// The ISO 19906 inputs of a run with their sources; rules in iso_inputs.h.
#include "sim/iso_inputs.h"

#include "common/error.h"
#include "common/hcp_geometry.h"
#include "common/ice_formulas.h"
#include "json/reader.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <set>
#include <stdexcept>

namespace hs::sim {

const char* to_string(IsoSource s) {
  switch (s) {
    case IsoSource::Scene: return "scene";
    case IsoSource::Measured: return "measured";
    case IsoSource::Default: return "default";
    case IsoSource::RidgeFile: return "ridge_file";
    case IsoSource::Calibrated: return "calibrated";
  }
  return "?";
}

const IsoInputRecord& IsoAssembly::record(const std::string& key) const {
  for (const auto& r : records)
    if (r.key == key) return r;
  throw std::out_of_range("no ISO input record '" + key + "'");
}

namespace {

/// Whether the effective scene JSON has a value at `pointer` ("/analysis/keel_depth").
bool given(const scene::Scene& s, const char* pointer) {
  return s.json.is_object() && s.json.contains(nlohmann::json::json_pointer(pointer));
}

IsoSource scene_or_default(const scene::Scene& s, const char* pointer) {
  return given(s, pointer) ? IsoSource::Scene : IsoSource::Default;
}

/// Pier radius on the piece of the profile that contains `mid` (neck, cone or shaft), at z:
/// the pieces' own formulas, so that the ends of a piece take its values and not the
/// neighbour's at a step (cone base -> shaft).
double radius_on_piece(const mesh::PierParams& p, double z, double mid) {
  const double neck_top = p.cone_top_z + p.neck_height;
  if (mid > neck_top || mid < p.shaft_bottom_z) return 0.0;
  if (mid > p.cone_top_z) return mesh::pier_cone_radius(p, p.cone_top_z);
  if (mid > p.cone_bottom_z) return mesh::pier_cone_radius(p, z);
  return 0.5 * p.shaft_diameter;
}

}  // namespace

double lattice_mean_thickness(const bonded::ParticleStore& p, const scene::Scene& s) {
  const std::size_t n = p.owned();
  if (n == 0 || !s.has_ice) return 0.0;
  const double D = s.material.particle_diameter;
  const double c = hcp_layer_spacing(D);
  const bool band = s.ice.has_consolidated_layer;
  const auto& cl = s.ice.consolidated_layer;
  const auto inside = [&](std::size_t i) { return !band || std::abs(p.x[i].x() - cl.center_x) <= 0.5 * cl.width; };
  double z_min = 0.0;
  std::size_t count = 0;
  for (std::size_t i = 0; i < n; ++i)
    if (inside(i)) z_min = count++ ? std::min(z_min, p.x[i].z()) : p.x[i].z();
  if (count == 0) return 0.0;
  std::set<long long> layers;  // layer index above the lowest: centre heights are c apart
  double volume = 0.0;
  for (std::size_t i = 0; i < n; ++i)
    if (inside(i)) {
      layers.insert(std::llround((p.x[i].z() - z_min) / c));
      volume += p.buoyant_volume[i];
    }
  return static_cast<double>(layers.size()) * (volume / static_cast<double>(count)) / (D * D * std::sqrt(3.0) / 2.0);
}

double keel_width_on_pier(const mesh::PierParams& p, double z_top, double h_k, double mu_phi, double gamma_e,
                          double cohesion) {
  if (!(h_k > 0.0)) return 0.0;
  const double z_bot = z_top - h_k;
  std::vector<double> cuts{z_bot, z_top};
  for (const double b : {p.shaft_bottom_z, p.cone_bottom_z, p.cone_top_z, p.cone_top_z + p.neck_height})
    if (b > z_bot && b < z_top) cuts.push_back(b);
  std::sort(cuts.begin(), cuts.end());
  const auto pressure = [&](double z) { return mu_phi * mu_phi * gamma_e * (z_top - z) + 2.0 * cohesion * mu_phi; };
  // Simpson's rule on each piece: exact for the quadratic (linear width x linear pressure).
  double wp = 0.0, w = 0.0;
  for (std::size_t k = 0; k + 1 < cuts.size(); ++k) {
    const double a = cuts[k], b = cuts[k + 1], m = 0.5 * (a + b);
    if (!(b > a)) continue;
    const double ra = radius_on_piece(p, a, m), rm = radius_on_piece(p, m, m), rb = radius_on_piece(p, b, m);
    wp += (b - a) / 6.0 * (2 * ra * pressure(a) + 4.0 * 2 * rm * pressure(m) + 2 * rb * pressure(b));
    w += (b - a) / 6.0 * (2 * ra + 4.0 * 2 * rm + 2 * rb);
  }
  const double load = mu_phi * mu_phi * gamma_e * h_k * h_k / 2.0 + 2.0 * cohesion * mu_phi * h_k;
  return load > 0.0 ? wp / load : w / h_k;
}

namespace {

/// The ISO inputs being assembled, each with where its value came from.
struct InputSetter {
  analysis::IsoInputs values;
  struct Pending {
    IsoSource source;
    std::string note, origin;
  };
  std::vector<std::pair<std::string, Pending>> sources;
  void set(const char* key, double analysis::IsoInputs::*field, double value, IsoSource source, std::string note = "",
           std::string origin = "") {
    values.*field = value;
    if (origin.empty()) origin = to_string(source);
    sources.push_back({key, {source, std::move(note), std::move(origin)}});
  }
};

std::string fmt_g(double v, int digits) {
  char b[32];
  std::snprintf(b, sizeof b, "%.*g", digits, v);
  return b;
}

/// "measured at t = 28.1 to 29.1 s (load peak)" ("(the whole run)" for a run shorter than the
/// moving mean) and the window in words for a note.
std::string peak_origin(const PileAtLoadPeak& p) {
  return "measured at t = " + fmt_g(p.window.t0, 4) + " to " + fmt_g(p.window.t1, 4) + " s (" +
         (p.window.whole_run ? "the whole run" : "load peak") + ")";
}
std::string peak_note(const PileAtLoadPeak& p, const char* series) {
  return std::string("mean of /pile_per_clock/") + series + " over t = " + json_fmt(p.window.t0) + " to " +
         json_fmt(p.window.t1) + " s, " +
         (p.window.whole_run ? "the whole run (shorter than the 1 s moving mean of the horizontal load)"
                             : "the window of the peak 1 s moving mean of the horizontal load");
}

/// Thickness, waterline diameter, flexural strength, stiffness: the ice ISO breaks.
void set_ice_inputs(InputSetter& in, const scene::Scene& s, const IsoMeasured& m) {
  const auto& pier = s.structure.pier;
  const auto& mat = s.material;
  const auto& an = s.analysis;
  // Thickness: the ice ISO breaks (the consolidated layer if there is one).
  const bool layer = s.has_ice && s.ice.has_consolidated_layer;
  const double nominal = layer ? s.ice.consolidated_layer.thickness : s.ice.thickness;
  const char* nominal_path = layer ? "/ice/consolidated_layer/thickness" : "/ice/thickness";
  if (m.thickness)
    in.set("thickness", &analysis::IsoInputs::thickness, *m.thickness, IsoSource::Measured,
        std::string("mean thickness of the built lattice") + (layer ? " in the consolidated layer" : "") +
            " (ice volume per unit area); nominal " + nominal_path + " = " + json_fmt(nominal) + " m");
  else
    in.set("thickness", &analysis::IsoInputs::thickness, nominal, IsoSource::Scene, std::string("nominal ") + nominal_path);

  in.set("waterline_diameter", &analysis::IsoInputs::waterline_diameter, pier.waterline_diameter,
      scene_or_default(s, "/structure/pier/waterline_diameter"), "/structure/pier/waterline_diameter");

  // Strength and stiffness: the calibrated lattice's when there is one; an explicit
  // analysis.flexural_strength still overrides it (as every analysis.* value).
  if (given(s, "/analysis/flexural_strength"))
    in.set("flexural_strength", &analysis::IsoInputs::flexural_strength, an.flexural_strength, IsoSource::Scene,
        "/analysis/flexural_strength");
  else if (m.calibrated)
    in.set("flexural_strength", &analysis::IsoInputs::flexural_strength, m.calibrated->flexural_strength, IsoSource::Calibrated,
        "flexural strength of the calibrated lattice (three-point bending, /material/flexural_strength the target)");
  else if (given(s, "/material/flexural_strength") && s.json["material"]["flexural_strength"].is_number())
    in.set("flexural_strength", &analysis::IsoInputs::flexural_strength, s.json["material"]["flexural_strength"].get<double>(),
        IsoSource::Scene, "/material/flexural_strength");
  else
    in.set("flexural_strength", &analysis::IsoInputs::flexural_strength, an.flexural_strength,
        scene_or_default(s, "/analysis/flexural_strength"), "/analysis/flexural_strength");
  if (m.calibrated) {
    in.set("youngs_modulus", &analysis::IsoInputs::youngs_modulus, m.calibrated->youngs_modulus, IsoSource::Calibrated,
        "Young's modulus of the calibrated lattice");
    in.set("poisson_ratio", &analysis::IsoInputs::poisson_ratio, m.calibrated->poisson_ratio, IsoSource::Calibrated,
        "Poisson's ratio of the calibrated lattice");
  } else {
    in.set("youngs_modulus", &analysis::IsoInputs::youngs_modulus, mat.youngs_modulus,
        scene_or_default(s, "/material/youngs_modulus"), "/material/youngs_modulus");
    in.set("poisson_ratio", &analysis::IsoInputs::poisson_ratio, mat.poisson_ratio, scene_or_default(s, "/material/poisson_ratio"),
        "/material/poisson_ratio");
  }
}

/// The cone, friction, densities and gravity.
void set_material_inputs(InputSetter& in, const scene::Scene& s) {
  const auto& pier = s.structure.pier;
  const auto& mat = s.material;
  const auto& an = s.analysis;
  in.set("cone_angle_deg", &analysis::IsoInputs::cone_angle_deg, pier.cone_angle_deg,
      scene_or_default(s, "/structure/pier/cone_angle_deg"), "/structure/pier/cone_angle_deg");
  in.set("friction_ice_structure", &analysis::IsoInputs::friction_ice_structure, s.structure.friction,
      scene_or_default(s, "/structure/friction"), "/structure/friction");
  if (given(s, "/analysis/friction_ice_ice"))
    in.set("friction_ice_ice", &analysis::IsoInputs::friction_ice_ice, an.friction_ice_ice, IsoSource::Scene,
        "/analysis/friction_ice_ice");
  else
    in.set("friction_ice_ice", &analysis::IsoInputs::friction_ice_ice, an.friction_ice_ice,
        scene_or_default(s, "/material/friction"), "/material/friction");
  in.set("ice_density", &analysis::IsoInputs::ice_density, mat.density, scene_or_default(s, "/material/density"),
      "/material/density");
  in.set("water_density", &analysis::IsoInputs::water_density, s.water.density, scene_or_default(s, "/water/density"),
      "/water/density");
  in.set("gravity", &analysis::IsoInputs::gravity, s.gravity.norm(), scene_or_default(s, "/gravity"), "|/gravity|");
}

/// The pile's height, slope and porosity, and the keel's porosity.
void set_pile_inputs(InputSetter& in, const scene::Scene& s, const IsoMeasured& m) {
  using I = analysis::IsoInputs;
  const auto& an = s.analysis;
  const std::optional<PileAtLoadPeak>& p = m.at_peak;
  const std::string run_max =
      m.rubble_height ? "; the run's maximum " + json_fmt(*m.rubble_height) + " m" : std::string();
  if (given(s, "/analysis/rubble_height"))
    in.set("rubble_height", &I::rubble_height, an.rubble_height, IsoSource::Scene, "/analysis/rubble_height");
  else if (p && std::isfinite(p->height_mean))
    in.set("rubble_height", &I::rubble_height, p->height_mean, IsoSource::Measured,
        "ISO-consistent pile height (crest averaged over the waterline width): " + peak_note(*p, "height_mean") +
            run_max, peak_origin(*p));
  else if (m.rubble_height)
    in.set("rubble_height", &I::rubble_height, *m.rubble_height, IsoSource::Measured,
        "peak over the run of /series/pile_height_mean (crest of the pile averaged over the waterline width)",
        "measured: the run's maximum");
  else
    in.set("rubble_height", &I::rubble_height, an.rubble_height, IsoSource::Default, "/analysis/rubble_height");
  const double alpha = in.values.cone_angle_deg;
  if (an.rubble_slope_deg > 0)
    in.set("rubble_slope_deg", &I::rubble_slope_deg, an.rubble_slope_deg, IsoSource::Scene, "/analysis/rubble_slope_deg");
  else if (p && p->slope_deg > 0 && p->slope_deg < alpha)
    in.set("rubble_slope_deg", &I::rubble_slope_deg, p->slope_deg, IsoSource::Measured,
        "the pile's slope (least-squares fit of its crest against the distance ahead of the cone face): " +
            peak_note(*p, "slope_deg"), peak_origin(*p));
  else
    in.set("rubble_slope_deg", &I::rubble_slope_deg, 0.8 * alpha, IsoSource::Default,
        "0.8 x cone_angle_deg; " + (p && std::isfinite(p->slope_deg)
                                         ? "the measured slope, " + json_fmt(p->slope_deg) + " deg, is outside (0, " +
                                               json_fmt(alpha) + ") deg"
                                         : std::string("no pile slope measured")),
        "assumed 0.8 x cone angle");
  if (given(s, "/analysis/rubble_porosity"))
    in.set("rubble_porosity", &I::rubble_porosity, an.rubble_porosity, IsoSource::Scene, "/analysis/rubble_porosity");
  else if (p && p->porosity >= 0.0 && p->porosity < 1.0)
    in.set("rubble_porosity", &I::rubble_porosity, p->porosity, IsoSource::Measured,
        "the pile's porosity (1 - particle volume / envelope volume above the waterline): " +
            peak_note(*p, "porosity"), peak_origin(*p));
  else if (m.ridge)
    in.set("rubble_porosity", &I::rubble_porosity, m.ridge->porosity, IsoSource::RidgeFile,
        "keel porosity of " + m.ridge->path + " (no pile porosity measured)");
  else
    in.set("rubble_porosity", &I::rubble_porosity, an.rubble_porosity, IsoSource::Default, "/analysis/rubble_porosity");
  if (given(s, "/analysis/rubble_porosity"))
    in.set("keel_porosity", &I::keel_porosity, an.rubble_porosity, IsoSource::Scene,
        "/analysis/rubble_porosity (one porosity for the pile and the keel)");
  else if (m.ridge)
    in.set("keel_porosity", &I::keel_porosity, m.ridge->porosity, IsoSource::RidgeFile, "keel porosity of " + m.ridge->path);
  else
    in.set("keel_porosity", &I::keel_porosity, an.rubble_porosity, IsoSource::Default, "/analysis/rubble_porosity");
}

void set_rubble_inputs(InputSetter& in, const scene::Scene& s, const IsoMeasured& m) {
  const auto& an = s.analysis;
  set_pile_inputs(in, s, m);
  in.set("rubble_cohesion", &analysis::IsoInputs::rubble_cohesion, an.rubble_cohesion,
      scene_or_default(s, "/analysis/rubble_cohesion"), "/analysis/rubble_cohesion");
  in.set("rubble_friction_angle_deg", &analysis::IsoInputs::rubble_friction_angle_deg, an.rubble_friction_angle_deg,
      scene_or_default(s, "/analysis/rubble_friction_angle_deg"), "/analysis/rubble_friction_angle_deg");
}

void set_keel_inputs(InputSetter& in, const scene::Scene& s, const IsoMeasured& m) {
  const auto& pier = s.structure.pier;
  const auto& an = s.analysis;
  // The keel: depth below the consolidated layer, and where on the pier it acts.
  const double level = s.water.enabled ? s.water.level : 0.0;
  double keel_top_depth = in.values.thickness * in.values.ice_density / in.values.water_density;  // the ISO sheet's underside
  if (given(s, "/analysis/keel_depth")) {
    in.set("keel_depth", &analysis::IsoInputs::keel_depth, an.keel_depth, IsoSource::Scene,
        "/analysis/keel_depth (ISO: below the consolidated layer)");
  } else if (m.ridge) {
    keel_top_depth = m.ridge->layer_bottom_depth;
    const bool frozen = m.keel_depth_limit && *m.keel_depth_limit < m.ridge->keel_depth;
    const double depth = frozen ? *m.keel_depth_limit : m.ridge->keel_depth;
    in.set("keel_depth", &analysis::IsoInputs::keel_depth, std::max(0.0, depth - m.ridge->layer_bottom_depth),
        IsoSource::RidgeFile,
        "keel depth " + json_fmt(m.ridge->keel_depth) + " m below the waterline" +
            (frozen ? " frozen at " + json_fmt(depth) + " m (the cone base)" : std::string()) +
            " minus the consolidated layer's underside at " + json_fmt(m.ridge->layer_bottom_depth) + " m, " +
            m.ridge->path,
        frozen ? "ridge_file, frozen at " + fmt_g(depth, 3) + " m below the waterline (the cone base)" : "ridge_file");
  } else {
    in.set("keel_depth", &analysis::IsoInputs::keel_depth, 0.0, IsoSource::Default, "no keel");
  }
  if (in.values.keel_depth > 0.0) {
    const double phi = in.values.rubble_friction_angle_deg * std::numbers::pi / 180.0;
    const double mu_phi = std::tan(std::numbers::pi / 4.0 + phi / 2.0);
    const double gamma_e = (1.0 - in.values.keel_porosity) * (in.values.water_density - in.values.ice_density) * in.values.gravity;
    const double z_top = level - keel_top_depth - s.structure.position.z();  // pier frame
    in.set("keel_width", &analysis::IsoInputs::keel_width,
        keel_width_on_pier(pier, z_top, in.values.keel_depth, mu_phi, gamma_e, in.values.rubble_cohesion),
        scene_or_default(s, "/structure/pier"),
        "pier diameter weighted by the plug-failure pressure over the keel, z = " + json_fmt(z_top) + " to " +
            json_fmt(z_top - in.values.keel_depth) + " m in the pier's frame (cone base " +
            json_fmt(2.0 * mesh::pier_cone_radius(pier, pier.cone_bottom_z)) + " m at z = " +
            json_fmt(pier.cone_bottom_z) + " m, shaft " + json_fmt(pier.shaft_diameter) + " m)",
        "the pier's profile over the keel's depth");
  } else {
    in.set("keel_width", &analysis::IsoInputs::keel_width, in.values.waterline_diameter, scene_or_default(s, "/structure/pier"),
        "no keel: the waterline diameter");
  }
}

}  // namespace

double cone_base_depth(const scene::Scene& s) {
  const double level = s.water.enabled ? s.water.level : 0.0;
  return level - (s.structure.position.z() + s.structure.pier.cone_bottom_z);
}

IsoAssembly assemble_iso_inputs(const scene::Scene& s, const IsoMeasured& m) {
  if (!s.has_structure)
    throw InputError("/structure", "the ISO 19906 estimate needs a cone: add \"structure\": {\"type\": \"pier\"}");
  if (s.structure.type != "pier")
    throw InputError("/structure/type", "the ISO 19906 estimate needs the parametric pier (waterline diameter and "
                                        "cone angle); a mesh structure does not give them");
  InputSetter setter;
  set_ice_inputs(setter, s, m);
  set_material_inputs(setter, s);
  set_rubble_inputs(setter, s, m);
  set_keel_inputs(setter, s, m);
  IsoAssembly out;
  out.in = setter.values;
  const analysis::IsoInputs& in = out.in;
  const auto& src = setter.sources;
  // One record per input, in the inputs' own order, with their units.
  const nlohmann::json values = analysis::iso_inputs_to_json(in);
  for (const auto& key : analysis::iso_input_keys()) {
    const auto it = std::find_if(src.begin(), src.end(), [&](const auto& p) { return p.first == key; });
    if (it == src.end()) throw std::logic_error("assemble_iso_inputs: no source for ISO input " + key);
    IsoInputRecord r;
    r.key = key;
    r.value = values[key].get<double>();
    r.unit = analysis::iso_input_unit(key);
    r.source = it->second.source;
    r.note = it->second.note;
    r.origin = it->second.origin;
    out.records.push_back(std::move(r));
  }
  return out;
}

}  // namespace hs::sim
