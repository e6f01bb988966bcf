#include "sim/metrics.h"

#include "common/error.h"
#include "io/run_file_edit.h"
#include "io/run_file_read.h"
#include "json/reader.h"
#include "mesh/pier.h"
#include "sim/recorder.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <utility>

namespace hs::sim {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
using analysis::Metric;
using analysis::TimeWindow;

/// The structure's per-step load: F_h = |(F_x, F_y)|, F_z, at the times t_k; t_start before step 1.
struct LoadHistory {
  std::vector<double> t, fh, fz;
  double t_start = 0.0;
};

LoadHistory read_load(const io::RunFileReader& f, const std::string& path) {
  const std::string g = kLoadPerStepGroup;
  if (!f.has(g + "/time") || !f.has(g + "/force"))
    throw InputError(path, !f.has("/series/structure_position")
                               ? "the run has no structure: the metrics are of the load on a structure "
                                 "(docs/metrics.md)"
                               : "no per-step load (" + g + "): written by a hybridsim without it; run the scene "
                                 "again with this one to get the metrics");
  LoadHistory h;
  h.t = f.doubles(g + "/time");
  const std::vector<double> F = f.doubles(g + "/force");
  if (F.size() != 3 * h.t.size())
    throw InputError(path, g + "/force holds " + std::to_string(F.size() / 3) + " rows, " + g + "/time " +
                               std::to_string(h.t.size()) + ": not a run file hybridsim wrote");
  h.fh.resize(h.t.size());
  h.fz.resize(h.t.size());
  for (std::size_t k = 0; k < h.t.size(); ++k) {
    h.fh[k] = std::hypot(F[3 * k], F[3 * k + 1]);
    h.fz[k] = F[3 * k + 2];
  }
  // The time before step 1: the initial row of /series (t = 0 after a relaxation before the freeze).
  const std::vector<double> rows = f.has("/series/time") ? f.doubles("/series/time") : std::vector<double>{};
  h.t_start = !rows.empty() ? rows.front() : 0.0;
  return h;
}

/// The scene's penetration windows (docs/metrics.md, "Windows"): the steps in which the pier's
/// front at a feature's depth, x_f(t) = x_axis(t_0) + r_f + v_x (t - t_0), lies over the feature
/// (the level ice, the consolidated layer). r_f: the widest pier radius over the feature's
/// floating thickness (from h rho_i / rho_w below the water line to the rest above it), where the
/// sheet meets the cone first. None when the structure is not a parametric pier moving along +x.
struct SceneWindows {
  std::vector<TimeWindow> windows;
  std::vector<std::string> where;  ///< each window's x-range in words
  double front = kNaN, speed = kNaN;  ///< m at t_start (the level ice's front), m/s
};

double number_at(const nlohmann::json& j, const nlohmann::json::json_pointer& p, double fallback) {
  return j.contains(p) && j.at(p).is_number() ? j.at(p).get<double>() : fallback;
}

/// The widest radius of the pier over the floating thickness h of ice (m).
double front_radius(const nlohmann::json& j, double h) {
  using P = nlohmann::json::json_pointer;
  mesh::PierParams pp;
  for (auto [key, field] : {std::pair{"waterline_diameter", &pp.waterline_diameter}, {"cone_angle_deg", &pp.cone_angle_deg},
                            {"cone_top_z", &pp.cone_top_z}, {"cone_bottom_z", &pp.cone_bottom_z},
                            {"neck_height", &pp.neck_height}, {"shaft_diameter", &pp.shaft_diameter},
                            {"shaft_bottom_z", &pp.shaft_bottom_z}})
    *field = number_at(j, P(std::string("/structure/pier/") + key), *field);
  if (!j.contains(P("/structure/pier/neck_height")))  // the column up to the deck (scene.cpp, read_pier)
    pp.neck_height = number_at(j, P("/structure/pier/deck_z"), mesh::kPierDefaultDeckZ) - pp.cone_top_z;
  const double level = number_at(j, P("/water/level"), 0.0);
  const double draft = h * number_at(j, P("/material/density"), 920.0) / number_at(j, P("/water/density"), 1025.0);
  const double lo = level - draft, hi = lo + h;
  double r = std::max(mesh::pier_radius_at(pp, lo), mesh::pier_radius_at(pp, hi));
  if (pp.cone_bottom_z >= lo && pp.cone_bottom_z <= hi) r = std::max(r, mesh::pier_radius_at(pp, pp.cone_bottom_z));
  return r;
}

SceneWindows scene_windows(const io::RunFileReader& f, const LoadHistory& h) {
  SceneWindows out;
  const std::optional<std::string> text = f.string_attribute("/", "scene");
  if (!text) return out;
  const nlohmann::json j = nlohmann::json::parse(*text, nullptr, false);
  using P = nlohmann::json::json_pointer;
  if (j.is_discarded() || !j.contains("structure") || !j.contains("ice")) return out;
  const std::string type = j["structure"].value("type", j["structure"].contains("mesh") ? "mesh" : "pier");
  const double vx = number_at(j, P("/structure/velocity/0"), 0.4), vy = number_at(j, P("/structure/velocity/1"), 0.0);
  if (type != "pier" || !(vx > 0.0) || std::abs(vy) > 1e-9 * vx) return out;
  double axis_x = number_at(j, P("/structure/position/0"), 0.0);
  if (f.has("/series/structure_position")) axis_x = f.doubles("/series/structure_position").at(0);
  out.front = axis_x + front_radius(j, number_at(j, P("/ice/thickness"), 0.0));
  out.speed = vx;
  const double ice0 = number_at(j, P("/ice/origin/0"), 0.0), ice1 = ice0 + number_at(j, P("/ice/length"), 0.0);
  const bool cl = j["ice"].contains("consolidated_layer");
  const double cx = number_at(j, P("/ice/consolidated_layer/center_x"), 0.0);
  const double cw = number_at(j, P("/ice/consolidated_layer/width"), 0.0);
  const double level_end = cl ? std::max(ice0, cx - 0.5 * cw) : ice1;
  auto add = [&](const std::string& name, double x0, double x1, double front) {
    out.windows.push_back(analysis::penetration_window(name, x0, x1, front, out.speed, h.t_start));
    out.where.push_back("front " + json_fmt(front - axis_x) + " m ahead of the axis between x = " + json_fmt(x0) +
                        " and " + json_fmt(x1) + " m");
  };
  add("level_ice", ice0, level_end, out.front);
  if (cl)
    add("consolidated_layer", cx - 0.5 * cw, cx + 0.5 * cw,
        axis_x + front_radius(j, number_at(j, P("/ice/consolidated_layer/thickness"), 0.0)));
  return out;
}

/// The windows of the metrics: the run, the scene's, then the given ones (replacing by name);
/// level_ice, consolidated_layer and keel always appear (NaN when not defined).
void window_metrics(std::vector<Metric>& m, const LoadHistory& h, const SceneWindows& sw, const MetricsOptions& opt) {
  struct Named {
    std::string name, where;
    TimeWindow w;
  };
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<Named> list{{"run", "the whole run", {"run", -inf, inf}},
                          {"level_ice", "not defined by the scene", {"level_ice", 0.0, -1.0}},
                          {"consolidated_layer", "not defined by the scene", {"consolidated_layer", 0.0, -1.0}},
                          {"keel", "not defined by the scene: a study gives it", {"keel", 0.0, -1.0}}};
  auto put = [&](const Named& n) {
    for (auto& e : list)
      if (e.name == n.name) {
        e = n;
        return;
      }
    list.push_back(n);
  };
  for (std::size_t k = 0; k < sw.windows.size(); ++k) put({sw.windows[k].name, sw.where[k], sw.windows[k]});
  for (const MetricWindow& g : opt.windows) {
    if (!g.by_position) {
      put({g.name, "given", {g.name, g.from, g.to}});
    } else if (std::isfinite(sw.speed)) {
      put({g.name, "given: the level ice's front between x = " + json_fmt(g.from) + " and " + json_fmt(g.to) + " m",
           analysis::penetration_window(g.name, g.from, g.to, sw.front, sw.speed, h.t_start)});
    } else {
      put({g.name, "given by x, but the structure is not a pier moving along +x", {g.name, 0.0, -1.0}});
    }
  }
  for (const Named& n : list) {
    const std::string span = n.w.t1 < n.w.t0 ? "no steps" : std::isinf(n.w.t0) ? "every step"
                             : json_fmt(n.w.t0) + " s < t <= " + json_fmt(n.w.t1) + " s";
    const std::string why = " over the window '" + n.name + "' (" + span + "; " + n.where + "); NaN without steps";
    m.push_back({"load_h_mean_" + n.name, analysis::window_mean(h.t, h.fh, n.w.t0, n.w.t1), "N",
                 "mean horizontal load |(F_x, F_y)| on the structure per DEM step" + why});
    m.push_back({"load_v_mean_" + n.name, analysis::window_mean(h.t, h.fz, n.w.t0, n.w.t1), "N",
                 "mean vertical load F_z (up positive) on the structure per DEM step" + why});
  }
}

double last_value(const io::RunFileReader& f, const std::string& dataset) {
  if (!f.has(dataset)) return kNaN;
  const std::vector<double> v = f.doubles(dataset);
  return v.empty() ? kNaN : v.back();
}

/// The largest finite value of the dataset; NaN when it is missing or has none.
double max_value(const io::RunFileReader& f, const std::string& dataset) {
  double best = kNaN;
  if (!f.has(dataset)) return best;
  for (double v : f.doubles(dataset))
    if (std::isfinite(v) && !(v <= best)) best = v;
  return best;
}

void pile_metrics(std::vector<Metric>& m, const io::RunFileReader& f) {
  const std::string g = std::string(kPileClockGroup) + "/";
  const std::string clock = " (" + g + ", every " + json_fmt(kPileClock) + " s of simulated time)";
  m.push_back({"pile_height_mean_max", max_value(f, g + "height_mean"), "m",
               "peak of the ISO-consistent pile height (mean crest over the waterline width)" + clock +
                   "; NaN without a pier"});
  m.push_back({"pile_height_top_max", max_value(f, g + "height_top"), "m",
               "peak of the highest ice above the waterline over the structure's upstream half" + clock});
}

PileAtLoadPeak pile_at_peak(const io::RunFileReader& f, const LoadHistory& h, double width) {
  PileAtLoadPeak p{analysis::load_peak_window(h.t, h.fh, h.t_start, width), kNaN, kNaN, kNaN};
  const std::string g = std::string(kPileClockGroup) + "/";
  if (!f.has(g + "time")) return p;
  const std::vector<double> t = f.doubles(g + "time");
  const auto mean = [&](const char* name) {
    return f.has(g + name) ? analysis::finite_window_mean(t, f.doubles(g + name), p.window.t0, p.window.t1) : kNaN;
  };
  p.height_mean = mean("height_mean");
  p.slope_deg = mean("slope_deg");
  p.porosity = mean("porosity");
  return p;
}

void load_peak_metrics(std::vector<Metric>& m, const io::RunFileReader& f, const LoadHistory& h, double width) {
  const PileAtLoadPeak p = pile_at_peak(f, h, width);
  const std::string w = json_fmt(width);
  const std::string at = " over the window of the load peak (the " + w +
                         " s of the peak moving mean of the horizontal load, the whole run when it is shorter; "
                         "mean of the /pile_per_clock samples in it); NaN without a pile";
  m.push_back({"load_h_peak_window_start", p.window.t0, "s",
               "start of the window of the peak " + w + " s moving mean of the horizontal load (the run's start "
               "when it is shorter than " + w + " s)"});
  m.push_back({"load_h_peak_window_end", p.window.t1, "s", "end of that window"});
  m.push_back({"pile_height_mean_at_load_peak", p.height_mean, "m",
               "ISO-consistent pile height (mean crest over the waterline width)" + at});
  m.push_back({"pile_slope_deg_at_load_peak", p.slope_deg, "deg",
               "rubble slope angle (least-squares slope of the pile's crest against the distance ahead of the "
               "cone face)" + at});
  m.push_back({"pile_porosity_at_load_peak", p.porosity, "1",
               "pile porosity (1 - particle volume / envelope volume from the waterline to the crest, over the "
               "pile's cells)" + at});
}

void state_metrics(std::vector<Metric>& m, const io::RunFileReader& f) {
  pile_metrics(m, f);
  // The last row of /series is the last step's whatever the output interval: state at the end.
  m.push_back({"pile_height_mean_end", last_value(f, "/series/pile_height_mean"), "m",
               "ISO-consistent pile height (mean crest over the waterline width, /series/pile_height_mean) at the "
               "last step; NaN without a pier"});
  m.push_back({"pile_height_top_end", last_value(f, "/series/pile_height"), "m",
               "highest ice above the waterline over the structure's upstream half (/series/pile_height) at the "
               "last step"});
  const std::optional<double> L_c = f.double_attribute("/analysis/pieces", "characteristic_length");
  double broken = kNaN, median = kNaN, mean = kNaN;
  if (f.has("/analysis/pieces/size") && f.has("/analysis/pieces/extent")) {
    const std::vector<double> size = f.doubles("/analysis/pieces/size"), ext = f.doubles("/analysis/pieces/extent");
    std::vector<double> e;  // broken-off pieces: every piece of >= 2 particles but the largest
    for (std::size_t k = 1; k < size.size() && k < ext.size(); ++k)
      if (size[k] >= 2) e.push_back(ext[k]);
    broken = static_cast<double>(e.size());
    if (!e.empty() && L_c && *L_c > 0) {
      median = analysis::percentile(e, 0.5) / *L_c;
      double s = 0.0;
      for (double x : e) s += x;
      mean = s / static_cast<double>(e.size()) / *L_c;
    }
  }
  m.push_back({"pieces_broken", broken, "1",
               "pieces of >= 2 particles other than the largest at the end of the run (/analysis/pieces); NaN "
               "before the run's report"});
  m.push_back({"piece_extent_median_over_L_c", median, "1",
               "median horizontal extent of those pieces over the characteristic length L_c (docs/iso19906.md)"});
  m.push_back({"piece_extent_mean_over_L_c", mean, "1", "mean horizontal extent of those pieces over L_c"});
  m.push_back({"characteristic_length", L_c ? *L_c : kNaN, "m", "L_c of the run's ice (/analysis/pieces)"});
  const bool blocks = f.has("/series/blocks");
  m.push_back({"conversions", blocks ? last_value(f, "/series/blocks/conversions") : 0.0, "1",
               "blocks converted into particles over the run (0 without blocks)"});
  const std::optional<double> made = f.double_attribute("/analysis/hybrid", "particles_created");
  m.push_back({"particles_created", made ? *made : blocks ? kNaN : 0.0, "1",
               "particles made by conversions (/analysis/hybrid; 0 without blocks, NaN before the run's report)"});
}

}  // namespace

std::vector<MetricWindow> metric_windows_from_json(const nlohmann::json& j, const std::string& where) {
  if (!j.is_array()) throw InputError(where, "expected an array of windows [{\"name\": .., \"t0\": .., \"t1\": ..}]");
  std::vector<MetricWindow> out;
  for (std::size_t k = 0; k < j.size(); ++k) {
    const nlohmann::json& w = j[k];
    const std::string at = where + "/" + std::to_string(k);
    if (!w.is_object() || !w.contains("name") || !w["name"].is_string() || w["name"].get<std::string>().empty())
      throw InputError(at, "a window is {\"name\": \"keel\", \"t0\": 2, \"t1\": 5} (s) or {\"name\": \"keel\", "
                           "\"x0\": -4, \"x1\": 4} (m, the structure's waterline front)");
    MetricWindow m;
    m.name = w["name"].get<std::string>();
    m.by_position = w.contains("x0") || w.contains("x1");
    const char* a = m.by_position ? "x0" : "t0";
    const char* b = m.by_position ? "x1" : "t1";
    if (!w.contains(a) || !w.contains(b) || !w[a].is_number() || !w[b].is_number() || w.size() != 3)
      throw InputError(at, "window '" + m.name + "': give exactly name, " + a + " and " + b + " (numbers)");
    m.from = w[a].get<double>();
    m.to = w[b].get<double>();
    if (!(m.to > m.from)) throw InputError(at, "window '" + m.name + "': " + b + " must exceed " + a);
    out.push_back(m);
  }
  return out;
}

std::vector<Metric> compute_run_metrics(const std::string& path, const MetricsOptions& opt) {
  std::optional<io::RunFileReader> opened;
  try {
    opened.emplace(path);
  } catch (const std::exception& e) {
    throw InputError(path, std::string("cannot read the run file (") + e.what() + ")");
  }
  const io::RunFileReader& f = *opened;
  const LoadHistory h = read_load(f, path);
  std::vector<Metric> m;
  window_metrics(m, h, scene_windows(f, h), opt);
  const std::string w = json_fmt(opt.moving_window);
  m.push_back({"load_h_impulse", analysis::impulse(h.t, h.fh, h.t_start), "N s",
               "time integral of the horizontal load |(F_x, F_y)| over the run, per DEM step"});
  m.push_back({"load_h_p95", analysis::percentile(h.fh, 0.95), "N",
               "95th percentile of the horizontal load of the DEM steps"});
  m.push_back({"load_h_peak_moving_mean", analysis::max_moving_mean(h.t, h.fh, h.t_start, opt.moving_window), "N",
               "largest mean of the horizontal load over " + w + " s (a moving mean over the DEM steps); NaN "
               "for a run shorter than " + w + " s"});
  m.push_back({"load_h_peak_step", h.fh.empty() ? kNaN : *std::max_element(h.fh.begin(), h.fh.end()), "N",
               "largest horizontal load of a single DEM step"});
  m.push_back({"steps", static_cast<double>(h.t.size()), "1", "DEM steps in the per-step load"});
  state_metrics(m, f);
  load_peak_metrics(m, f, h, opt.moving_window);
  return m;
}

PileAtLoadPeak pile_at_load_peak(const std::string& path, double width) {
  std::optional<io::RunFileReader> opened;
  try {
    opened.emplace(path);
  } catch (const std::exception& e) {
    throw InputError(path, std::string("cannot read the run file (") + e.what() + ")");
  }
  return pile_at_peak(*opened, read_load(*opened, path), width);
}

std::vector<Metric> read_run_metrics(const std::string& path) {
  const io::RunFileReader f(path);
  std::vector<Metric> out;
  // In the order they were computed (the group attribute "order"), else in name order.
  std::vector<std::string> names = f.members(kMetricsGroup);
  if (const auto order = f.string_attribute(kMetricsGroup, "order")) {
    std::vector<std::string> listed;
    std::size_t a = 0;
    for (std::size_t b; (b = order->find(' ', a)) != std::string::npos || a < order->size(); a = b + 1) {
      if (b == std::string::npos) b = order->size();
      const std::string n = order->substr(a, b - a);
      if (std::find(names.begin(), names.end(), n) != names.end()) listed.push_back(n);
    }
    if (listed.size() == names.size()) names = listed;
  }
  for (const std::string& name : names) {
    const std::string d = std::string(kMetricsGroup) + "/" + name;
    const std::vector<double> v = f.doubles(d);
    out.push_back({name, v.empty() ? kNaN : v[0], f.string_attribute(d, "unit").value_or(""),
                   f.string_attribute(d, "description").value_or("")});
  }
  return out;
}

void write_run_metrics(const std::string& path, const std::vector<Metric>& metrics) {
  io::RunFileEditor f(path);
  f.add_group(kMetricsGroup);
  f.set_attribute(kMetricsGroup, "description",
                  "run metrics (docs/metrics.md): one scalar per metric, NaN where it has no data");
  std::string order;
  for (const Metric& m : metrics) order += (order.empty() ? "" : " ") + m.name;
  f.set_attribute(kMetricsGroup, "order", order);
  for (const Metric& m : metrics) f.add_scalar(std::string(kMetricsGroup) + "/" + m.name, m.value, m.unit, m.description);
  f.flush();
}

nlohmann::json metrics_to_json(const std::vector<Metric>& metrics) {
  nlohmann::json o = nlohmann::json::object();
  for (const Metric& m : metrics)
    o[m.name] = {{"value", std::isfinite(m.value) ? nlohmann::json(m.value) : nlohmann::json(nullptr)},
                 {"unit", m.unit},
                 {"description", m.description}};
  return o;
}

}  // namespace hs::sim
