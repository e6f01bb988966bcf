// Ridge generator: see ridge.h and docs/ridge.md.
#include "rigid/ridge.h"

#include "common/error.h"
#include "common/ice_formulas.h"
#include "json/reader.h"
#include "rigid/box_water.h"
#include "rigid/rigid_world.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <sstream>
#include <unordered_map>

namespace hs::rigid {

namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;
constexpr double kTwoPi = 2.0 * 3.14159265358979323846;

// ---------------------------------------------------------------- random numbers
// mt19937_64 is specified bit for bit by the standard; the distributions are not, so they
// are written out here (same seed -> same ridge with any standard library).
class Rng {
 public:
  explicit Rng(std::uint64_t seed) : g_(seed) {}
  double uniform() { return static_cast<double>(g_() >> 11) * 0x1.0p-53; }  // [0, 1)
  double uniform(double a, double b) { return a + (b - a) * uniform(); }
  double normal() {  // Box-Muller, both values used
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    const double u1 = 1.0 - uniform();  // (0, 1]
    const double u2 = uniform();
    const double r = std::sqrt(-2.0 * std::log(u1));
    spare_ = r * std::sin(kTwoPi * u2);
    has_spare_ = true;
    return r * std::cos(kTwoPi * u2);
  }
  Quat rotation() {  // uniform on SO(3) (Shoemake)
    const double u1 = uniform(), u2 = uniform(), u3 = uniform();
    const double a = std::sqrt(1.0 - u1), b = std::sqrt(u1);
    return Quat(b * std::cos(kTwoPi * u3), a * std::sin(kTwoPi * u2), a * std::cos(kTwoPi * u2),
                b * std::sin(kTwoPi * u3));
  }

 private:
  std::mt19937_64 g_;
  bool has_spare_ = false;
  double spare_ = 0.0;
};

double sample_ln_r(Rng& rng, double m, double s) {
  for (;;) {
    const double z = rng.normal();
    if (std::abs(z) <= 4.0) return m + s * z;
  }
}

// ---------------------------------------------------------------- box geometry
/// Half extent of the box along the unit direction e.
double reach(const Vec3& h, const Mat3& R, const Vec3& e) {
  return h.x() * std::abs(R.col(0).dot(e)) + h.y() * std::abs(R.col(1).dot(e)) +
         h.z() * std::abs(R.col(2).dot(e));
}
/// Half extents of the box's axis-aligned bounding box.
Vec3 aabb_half(const Vec3& h, const Mat3& R) {
  return Vec3(reach(h, R, Vec3::UnitX()), reach(h, R, Vec3::UnitY()), reach(h, R, Vec3::UnitZ()));
}

/// SAT: minimum overlap depth over the 15 axes and that axis (from a to b); depth <= 0
/// means separated (the value is then the largest gap found, not a distance).
double sat(const Vec3& ha, const Vec3& xa, const Mat3& A, const Vec3& hb, const Vec3& xb,
           const Mat3& B, Vec3* axis) {
  const Vec3 d = xb - xa;
  double depth = std::numeric_limits<double>::infinity();
  Vec3 best = Vec3::UnitZ();
  auto test = [&](const Vec3& L) {
    const double o = reach(ha, A, L) + reach(hb, B, L) - std::abs(d.dot(L));
    if (o < depth) {
      depth = o;
      best = L;
    }
    return o > 0.0;
  };
  for (int i = 0; i < 3; ++i)
    if (!test(A.col(i))) return depth;
  for (int i = 0; i < 3; ++i)
    if (!test(B.col(i))) return depth;
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k) {
      Vec3 c = A.col(i).cross(B.col(k));
      const double n = c.norm();
      if (n < 1e-6) continue;
      if (!test(c / n)) return depth;
    }
  if (axis) *axis = best.dot(d) < 0.0 ? Vec3(-best) : best;
  return depth;
}

using Poly = std::vector<Vec3>;

/// Face polygons of a box, counter-clockwise about their outward normals.
std::array<Poly, 6> box_faces(const Vec3& h, const Vec3& x, const Mat3& R) {
  std::array<Poly, 6> faces;
  const Vec3 ax[3] = {R.col(0) * h.x(), R.col(1) * h.y(), R.col(2) * h.z()};
  for (int k = 0; k < 3; ++k) {
    const Vec3& n = ax[k];
    const Vec3& u = ax[(k + 1) % 3];
    const Vec3& w = ax[(k + 2) % 3];
    for (int sgn = 0; sgn < 2; ++sgn) {
      const Vec3 c = x + (sgn == 0 ? 1.0 : -1.0) * n;
      Poly q = {c + u + w, c - u + w, c - u - w, c + u - w};
      if (sgn == 1) std::swap(q[1], q[3]);
      faces[2 * k + sgn] = std::move(q);
    }
  }
  return faces;
}

/// Keeps the part of a convex polygon with n.p <= d.
Poly clip(const Poly& in, const Vec3& n, double d) {
  Poly out;
  const std::size_t m = in.size();
  for (std::size_t i = 0; i < m; ++i) {
    const Vec3& a = in[i];
    const Vec3& b = in[(i + 1) % m];
    const double da = n.dot(a) - d, db = n.dot(b) - d;
    if (da <= 0.0) out.push_back(a);
    if ((da < 0.0 && db > 0.0) || (da > 0.0 && db < 0.0)) out.push_back(a + (da / (da - db)) * (b - a));
  }
  return out;
}

/// Volume and centroid of the intersection of two boxes: the faces of each box clipped to
/// the other box bound the (convex) intersection; divergence theorem with signed tetrahedra.
double box_intersection(const Vec3& ha, const Vec3& xa, const Mat3& A, const Vec3& hb,
                        const Vec3& xb, const Mat3& B, Vec3* centroid) {
  std::vector<Poly> polys;
  auto add = [&](const Vec3& h1, const Vec3& x1, const Mat3& R1, const Vec3& h2, const Vec3& x2,
                 const Mat3& R2) {
    for (Poly& f : box_faces(h1, x1, R1)) {
      Poly p = std::move(f);
      for (int k = 0; k < 3 && p.size() >= 3; ++k) {
        const Vec3 n = R2.col(k);
        p = clip(p, n, n.dot(x2) + h2[k]);
        if (p.size() >= 3) p = clip(p, -n, -n.dot(x2) + h2[k]);
      }
      if (p.size() >= 3) polys.push_back(std::move(p));
    }
  };
  add(ha, xa, A, hb, xb, B);
  add(hb, xb, B, ha, xa, A);
  Vec3 p0 = Vec3::Zero();
  std::size_t np = 0;
  for (const Poly& p : polys)
    for (const Vec3& v : p) p0 += v, ++np;
  if (np == 0) return 0.0;
  p0 /= static_cast<double>(np);
  double vol = 0.0;
  Vec3 mom = Vec3::Zero();
  for (const Poly& p : polys)
    for (std::size_t i = 1; i + 1 < p.size(); ++i) {
      const Vec3 a = p[0] - p0, b = p[i] - p0, c = p[i + 1] - p0;
      const double vt = a.dot(b.cross(c)) / 6.0;
      vol += vt;
      mom += vt * (p0 + 0.25 * (a + b + c));
    }
  if (centroid) *centroid = vol > 0.0 ? Vec3(mom / vol) : p0;
  return std::max(0.0, vol);
}

// ---------------------------------------------------------------- spatial hash
class HashGrid {
 public:
  explicit HashGrid(double cell) : cell_(cell) {}
  void insert(std::int32_t id, const Vec3& lo, const Vec3& hi) {
    for_cells(lo, hi, [&](std::uint64_t k) { map_[k].push_back(id); });
  }
  /// Ids whose boxes were inserted over cells touching [lo, hi], each once, ascending.
  void query(const Vec3& lo, const Vec3& hi, std::vector<std::int32_t>& out) {
    out.clear();
    for_cells(lo, hi, [&](std::uint64_t k) {
      auto it = map_.find(k);
      if (it == map_.end()) return;
      for (std::int32_t id : it->second) {
        if (static_cast<std::size_t>(id) >= stamp_.size()) stamp_.resize(id + 1, 0);
        if (stamp_[id] == epoch_) continue;
        stamp_[id] = epoch_;
        out.push_back(id);
      }
    });
    ++epoch_;
    std::sort(out.begin(), out.end());
  }
  const std::vector<std::int32_t>* cell_of(const Vec3& p) const {
    auto it = map_.find(key(idx(p.x()), idx(p.y()), idx(p.z())));
    return it == map_.end() ? nullptr : &it->second;
  }

 private:
  std::int64_t idx(double v) const { return static_cast<std::int64_t>(std::floor(v / cell_)); }
  static std::uint64_t key(std::int64_t i, std::int64_t j, std::int64_t k) {
    const std::uint64_t o = 1u << 20, m = (1u << 21) - 1;
    return ((static_cast<std::uint64_t>(i + o) & m) << 42) |
           ((static_cast<std::uint64_t>(j + o) & m) << 21) | (static_cast<std::uint64_t>(k + o) & m);
  }
  template <class F>
  void for_cells(const Vec3& lo, const Vec3& hi, F&& f) {
    const std::int64_t i0 = idx(lo.x()), i1 = idx(hi.x()), j0 = idx(lo.y()), j1 = idx(hi.y()),
                       k0 = idx(lo.z()), k1 = idx(hi.z());
    for (std::int64_t i = i0; i <= i1; ++i)
      for (std::int64_t j = j0; j <= j1; ++j)
        for (std::int64_t k = k0; k <= k1; ++k) f(key(i, j, k));
  }
  double cell_;
  std::unordered_map<std::uint64_t, std::vector<std::int32_t>> map_;
  std::vector<std::uint32_t> stamp_;
  std::uint32_t epoch_ = 1;
};

// ---------------------------------------------------------------- profile helpers
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

struct Placed {
  Vec3 h, x;
  Quat q;
  Mat3 R;
  Vec3 aabb;
  int part;
};

double percentile95(std::vector<double>& v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const std::size_t k = static_cast<std::size_t>(std::ceil(0.95 * static_cast<double>(v.size()))) - 1;
  return v[std::min(k, v.size() - 1)];
}

}  // namespace

// ---------------------------------------------------------------- public pieces
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

std::vector<double> sample_log_aspect(const AspectLognormal& a, std::size_t n, std::uint64_t seed) {
  Rng rng(seed);
  double m, s;
  a.log_params(m, s);
  std::vector<double> out(n);
  for (double& v : out) v = sample_ln_r(rng, m, s);
  return out;
}

/// Half width of the consolidated layer's contact surface (the run's particles with a floating sheet).
static double layer_half_width(const RidgeDef& d) {
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

double box_penetration(const Vec3& ha, const Vec3& xa, const Quat& qa, const Vec3& hb,
                       const Vec3& xb, const Quat& qb) {
  const double s = sat(ha, xa, qa.toRotationMatrix(), hb, xb, qb.toRotationMatrix(), nullptr);
  return s > 0.0 ? s : 0.0;
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

// ---------------------------------------------------------------- validation
namespace {

void validate(const RidgeDef& d, const std::string& P) {
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

}  // namespace

// ---------------------------------------------------------------- generator
// generate_ridge runs the phases below in order (docs/ridge.md): the ice sheet, placement
// (greedy deposition into the target envelope), the rigid world, compaction and settling,
// freeze joints, and the report (achieved profile and porosity). The random stream is drawn
// in placement only, in a fixed order, so a seed gives the same ridge bit for bit.
namespace {

/// State shared by the phases: the definition, the random stream, the progress callback.
struct RidgeRun {
  const RidgeDef& d;
  const RidgeProgressFn& progress;
  Rng rng;
  double lnm = 0.0, lns = 0.0;  ///< log-normal parameters of the aspect ratio
  double kx = 0.0, sx = 0.0;    ///< keel and sail half widths, m
  double ice_half = 0.0;        ///< half width of the ice sheet, m
  double wcl = 0.0;             ///< width of the consolidated layer within it, m

  RidgeRun(const RidgeDef& def, const RidgeProgressFn& p) : d(def), progress(p), rng(def.seed) {
    d.aspect.log_params(lnm, lns);
  }
  void report(const char* phase, double t, double ke, std::size_t n, double disp = -1.0) const {
    if (!progress) return;
    RidgeProgress q;
    q.phase = phase;
    q.max_displacement = disp;
    q.time = t;
    q.max_time = d.settle.max_time;
    q.kinetic_energy_per_block = ke;
    q.blocks = n;
    progress(q);
  }
};

/// Gap left between neighbouring plates and between a plate and the end walls, m: plates
/// that heave independently must not rub (friction) on each other.
constexpr double kPlateGap = 1e-3;

/// Ice sheet: level ice left/right, consolidated layer in the middle. Fixed boxes of the
/// solid slab, or (sheet.floating) plates of the run's sheet geometry, each part cut into
/// strips about plate_width wide.
void add_ice_sheet(RidgeRun& run, std::vector<IceBox>& ice) {
  const RidgeDef& d = run.d;
  run.kx = keel_half_width(d);
  run.sx = sail_half_width(d);
  run.ice_half = std::max(run.kx, run.sx) + d.level_ice_margin;
  run.wcl = std::min(2.0 * layer_half_width(d), 2.0 * run.ice_half);
  if (d.sheet.floating) {
    auto plates = [&](double x0, double x1, int part) {
      if (x1 - x0 <= 0.0) return;
      const double top = part == 1 ? d.sheet.layer_top : d.sheet.level_top;
      const double under = part == 1 ? d.sheet.layer_underside : d.sheet.level_underside;
      const int n = d.sheet.plate_width > 0.0
                        ? std::max(1, static_cast<int>(std::lround((x1 - x0) / d.sheet.plate_width)))
                        : 1;
      const double w = (x1 - x0) / n;
      for (int i = 0; i < n; ++i) {
        IceBox b;
        b.half_extents = Vec3(0.5 * (w - kPlateGap), 0.5 * (d.length - 2.0 * kPlateGap), 0.5 * (top - under));
        b.position = Vec3(x0 + (i + 0.5) * w, 0.5 * d.length, 0.5 * (top + under));
        b.part = part;
        ice.push_back(b);
      }
    };
    plates(-run.ice_half, -0.5 * run.wcl, 0);
    plates(-0.5 * run.wcl, 0.5 * run.wcl, 1);
    plates(0.5 * run.wcl, run.ice_half, 0);
    return;
  }
  auto ice_box = [&](double x0, double x1, double t, int part) {
    if (x1 - x0 <= 0.0) return;
    const double draft = flotation_draft(t, d.ice_density, d.water_density);
    IceBox b;
    b.half_extents = Vec3(0.5 * (x1 - x0), 0.5 * d.length, 0.5 * t);
    b.position = Vec3(0.5 * (x0 + x1), 0.5 * d.length, 0.5 * t - draft);
    b.part = part;
    ice.push_back(b);
  };
  ice_box(-run.ice_half, -0.5 * run.wcl, d.level_ice_thickness, 0);
  ice_box(-0.5 * run.wcl, 0.5 * run.wcl, d.consolidated_layer_thickness, 1);
  ice_box(0.5 * run.wcl, run.ice_half, d.level_ice_thickness, 0);
}

/// Target envelope (keel or sail) on a fine x grid: its thickness integrated over x gives the
/// volume and the distribution of block x positions.
struct Envelope {
  std::vector<double> xs, cdf;
  double volume = 0.0;  ///< m^3

  Envelope() = default;
  Envelope(const RidgeDef& d, bool keel, double hw) {
    const double dxs = 0.02;
    double lo = -hw, hi = hw;
    if (keel && !d.keel_profile.empty()) lo = d.keel_profile.front().position, hi = d.keel_profile.back().position;
    const int n = std::max(2, static_cast<int>(std::ceil((hi - lo) / dxs)));
    xs.resize(n + 1);
    cdf.assign(n + 1, 0.0);
    for (int i = 0; i <= n; ++i) xs[i] = lo + (hi - lo) * i / n;
    auto thick = [&](double x) {
      return keel ? std::max(0.0, keel_target_depth(d, x) - ice_draft(d, x))
                  : std::max(0.0, sail_target_height(d, x) - ice_freeboard(d, x));
    };
    for (int i = 1; i <= n; ++i)
      cdf[i] = cdf[i - 1] + 0.5 * (thick(xs[i - 1]) + thick(xs[i])) * (xs[i] - xs[i - 1]);
    volume = cdf.back() * d.length;
  }
  /// An x drawn with density proportional to the envelope thickness.
  double sample_x(Rng& rng) const {
    const double u = rng.uniform() * cdf.back();
    auto it = std::upper_bound(cdf.begin(), cdf.end(), u);
    const std::size_t i = std::clamp<std::size_t>(it - cdf.begin(), 1, cdf.size() - 1);
    const double c0 = cdf[i - 1], c1 = cdf[i];
    const double t = c1 > c0 ? (u - c0) / (c1 - c0) : 0.5;
    return xs[i - 1] + t * (xs[i] - xs[i - 1]);
  }
};

// ---- placement: non-overlapping piles hanging under / standing on the ice, packed by
// greedy deposition (docs/ridge.md, Method 3): every block tries placement_candidates
// poses, each translated along z from the ice to the first free position (exact: the
// z range where two boxes overlap is an interval, found with the 15 SAT axes), and keeps
// the one that ends least deep relative to the local target depth. Holes are filled
// before the pile grows, so the column starts denser (porosity ~0.6 instead of ~0.8)
// and shaped like the target, and the rise is short.
class Placement {
 public:
  Placement(RidgeRun& run, const Envelope& keel, const Envelope& sail)
      : run_(run), d_(run.d), keel_(keel), sail_(sail), gap_(run.d.joints.gap), h_blk_(run.d.block_thickness),
        zreach_(3.0 * std::max(run.d.keel_depth, run.d.sail_height) + 20.0 * run.d.block_thickness) {}

  /// Adds blocks to the keel (or sail) until their volume reaches volume_target; returns it.
  double fill(bool keel, double volume_target) {
    double vol = 0.0;
    while (vol < volume_target) {
      const double L = h_blk_ * std::exp(sample_ln_r(run_.rng, run_.lnm, run_.lns));
      const double B = L * run_.rng.uniform(d_.width_fraction_min, d_.width_fraction_max);
      Placed best;
      double best_score = std::numeric_limits<double>::infinity();
      for (int c = 0; c < d_.placement_candidates; ++c) {
        double score = 0.0;
        const Placed p = candidate(keel, L, B, score);
        if (score < best_score) best_score = score, best = p;
      }
      const std::int32_t id = static_cast<std::int32_t>(placed.size());
      placed.push_back(best);
      grid_.insert(id, best.x - best.aabb - Vec3::Constant(gap_), best.x + best.aabb + Vec3::Constant(gap_));
      vol += 8.0 * best.h.prod();
      if (placed.size() % 2000 == 0) run_.report("place", 0.0, 0.0, placed.size());
    }
    return vol;
  }

  std::vector<Placed> placed;

 private:
  /// One candidate pose of an L x B block, dropped from the ice to its first free position;
  /// score: how far it reaches into the envelope, as a fraction of the local thickness (the
  /// emptiest place wins; > 1: it sticks out of the envelope).
  Placed candidate(bool keel, double L, double B, double& score) {
    Rng& rng = run_.rng;
    Placed p;
    p.h = Vec3(0.5 * L, 0.5 * B, 0.5 * h_blk_);
    p.part = keel ? 0 : 1;
    const double x = (keel ? keel_ : sail_).sample_x(rng);
    if (d_.max_tilt_deg >= 90.0) {
      p.q = rng.rotation();
    } else {  // random yaw, then a tilt of U(0, max) about a random horizontal axis
      const double yaw = kTwoPi * rng.uniform(), az = kTwoPi * rng.uniform();
      const double tilt = d_.max_tilt_deg * kDeg * rng.uniform();
      p.q = Quat(Eigen::AngleAxisd(tilt, Vec3(std::cos(az), std::sin(az), 0.0))) *
            Quat(Eigen::AngleAxisd(yaw, Vec3::UnitZ()));
    }
    double y = rng.uniform();
    p.R = p.q.toRotationMatrix();
    p.aabb = aabb_half(p.h, p.R);
    const double ylo = p.aabb.y() + gap_, yhi = d_.length - p.aabb.y() - gap_;
    y = ylo < yhi ? ylo + y * (yhi - ylo) : 0.5 * d_.length;
    // Start just clear of the ice over the block's x range.
    const double xl = x - p.aabb.x(), xr = x + p.aabb.x();
    const bool over_cl = xl < 0.5 * run_.wcl && xr > -0.5 * run_.wcl;
    const double t_ice = over_cl ? d_.consolidated_layer_thickness : d_.level_ice_thickness;
    const double ice_z = keel ? -flotation_draft(t_ice, d_.ice_density, d_.water_density) - gap_ - p.aabb.z()
                              : flotation_freeboard(t_ice, d_.ice_density, d_.water_density) + gap_ + p.aabb.z();
    p.x = Vec3(x, y, ice_z);
    p.x.z() += free_shift(p, keel);
    const double reach_z = keel ? -(p.x.z() - p.aabb.z()) : p.x.z() + p.aabb.z();
    const double target = keel ? keel_target_depth(d_, x) : sail_target_height(d_, x);
    score = target > 0.0 ? reach_z / target : std::numeric_limits<double>::infinity();
    return p;
  }

  /// Highest (keel: t <= 0, moving down) / lowest (sail: t >= 0, moving up) shift t of p
  /// along z with no overlap (boxes inflated by gap/2 each).
  double free_shift(const Placed& p, bool keel) {
    const double gap = gap_;
    const Vec3 hp = p.h + Vec3::Constant(0.5 * gap);
    Vec3 lo = p.x - p.aabb - Vec3::Constant(gap), hi = p.x + p.aabb + Vec3::Constant(gap);
    if (keel) lo.z() -= zreach_;
    else hi.z() += zreach_;
    grid_.query(lo, hi, cand_);
    ivals_.clear();
    for (std::int32_t id : cand_) {
      const Placed& o = placed[id];
      const Vec3 dd = o.x - p.x;
      if (std::abs(dd.x()) > p.aabb.x() + o.aabb.x() + gap || std::abs(dd.y()) > p.aabb.y() + o.aabb.y() + gap)
        continue;
      const Vec3 ho = o.h + Vec3::Constant(0.5 * gap);
      // Overlap on axis L at shift t: |dd.L - t L_z| < r_L; intersect over the axes.
      double tlo = -std::numeric_limits<double>::infinity(), thi = std::numeric_limits<double>::infinity();
      auto axis = [&](const Vec3& L) {
        const double r = reach(hp, p.R, L) + reach(ho, o.R, L), c = dd.dot(L), a = L.z();
        if (std::abs(a) < 1e-12) {
          if (std::abs(c) >= r) tlo = thi = 0.0;  // separated for every t
          return;
        }
        double t0 = (c - r) / a, t1 = (c + r) / a;
        if (t0 > t1) std::swap(t0, t1);
        tlo = std::max(tlo, t0);
        thi = std::min(thi, t1);
      };
      for (int i = 0; i < 3 && tlo < thi; ++i) axis(p.R.col(i));
      for (int i = 0; i < 3 && tlo < thi; ++i) axis(o.R.col(i));
      for (int i = 0; i < 3 && tlo < thi; ++i)
        for (int k = 0; k < 3 && tlo < thi; ++k) {
          const Vec3 c = p.R.col(i).cross(o.R.col(k));
          const double nc = c.norm();
          if (nc >= 1e-6) axis(c / nc);
        }
      if (tlo < thi) ivals_.emplace_back(tlo, thi);
    }
    double t = 0.0;
    for (bool moved = true; moved;) {
      moved = false;
      for (const auto& [a, b] : ivals_)
        if (a < t && t < b) {
          t = keel ? a : b;
          moved = true;
        }
    }
    return t;
  }

  RidgeRun& run_;
  const RidgeDef& d_;
  const Envelope& keel_;
  const Envelope& sail_;
  const double gap_, h_blk_;
  const double zreach_;  ///< search depth, m
  HashGrid grid_{2.0};
  std::vector<std::int32_t> cand_;
  std::vector<std::pair<double, double>> ivals_;
};

/// The rigid world of the settling: end walls fixed, the ice fixed or floating plates (heave
/// only), blocks released at rest. Returns the blocks' ids in `placed` order; the ice boxes'
/// ids go to `ice_ids`.
std::vector<BlockId> build_settle_world(RigidWorld& world, const RidgeRun& run, const std::vector<IceBox>& ice,
                                        const std::vector<Placed>& placed, std::vector<BlockId>& ice_ids) {
  const RidgeDef& d = run.d;
  double zmin = 0.0, zmax = 0.0;
  for (const Placed& p : placed) {
    zmin = std::min(zmin, p.x.z() - p.aabb.z());
    zmax = std::max(zmax, p.x.z() + p.aabb.z());
  }
  for (const IceBox& b : ice) {
    BlockDef bd;
    bd.half_extents = b.half_extents;
    bd.position = b.position;
    if (d.sheet.floating) {
      bd.density = plate_density(b.position.z() + b.half_extents.z(), b.position.z() - b.half_extents.z(),
                                 d.water_density);
      bd.linear_factor = Vec3::UnitZ();
      bd.angular_factor = Vec3::Zero();
    } else {
      bd.fixed = true;
    }
    ice_ids.push_back(world.add_block(bd));
  }
  if (d.sheet.floating && d.sheet.plates_joined) {
    // Fixed joints between neighbours (the settle world's joints never break: its strength is
    // infinite), anchored at the middle of their common edge.
    for (std::size_t k = 0; k + 1 < ice.size(); ++k) {
      FreezeJointDef j;
      j.a = ice_ids[k];
      j.b = ice_ids[k + 1];
      j.anchor = Vec3(0.5 * (ice[k].position.x() + ice[k].half_extents.x() + ice[k + 1].position.x() -
                             ice[k + 1].half_extents.x()),
                      ice[k].position.y(), std::min(ice[k].position.z(), ice[k + 1].position.z()));
      j.normal = Vec3::UnitX();
      j.area = 1.0;
      world.add_freeze_joint(j);
    }
  }
  if (d.end_walls) {
    for (int s = 0; s < 2; ++s) {
      BlockDef bd;
      bd.half_extents = Vec3(run.ice_half + 5.0, 1.0, 0.5 * (zmax - zmin) + 5.0);
      bd.position = Vec3(0.0, s == 0 ? -1.0 : d.length + 1.0, 0.5 * (zmax + zmin));
      bd.fixed = true;
      world.add_block(bd);
    }
  }
  std::vector<BlockId> ids;
  ids.reserve(placed.size());
  for (const Placed& p : placed) {
    BlockDef bd;
    bd.half_extents = p.h;
    bd.position = p.x;
    bd.orientation = p.q;
    bd.density = d.ice_density;
    ids.push_back(world.add_block(bd));
  }
  return ids;
}

RigidWorldDef settle_world_def(const RidgeDef& d) {
  RigidWorldDef wd;
  wd.dt = d.settle.dt;
  wd.solver_iterations = d.settle.solver_iterations;
  wd.water = true;
  wd.water_level = 0.0;
  wd.water_density = d.water_density;
  wd.linear_drag = d.settle.linear_drag;
  wd.quadratic_drag_cd = d.settle.quadratic_drag_cd;
  wd.friction = d.settle.friction;
  wd.restitution = 0.0;
  wd.fixed_friction_directions = d.settle.fixed_friction_directions;
  wd.allow_sleep = d.settle.allow_sleep;
  wd.sleep_linear_velocity = 0.02;
  wd.sleep_angular_velocity = 0.02;
  wd.freeze_bond_strength = std::numeric_limits<double>::infinity();  // the plates' joints hold
  return wd;
}

// ---- settle, in two phases (docs/ridge.md, Method 4). Compaction: the keel blocks'
// friction lowered to compaction_friction so the rising blocks slide into the voids of
// the pile (a numerical stand-in for the reworking a real keel gets while the ridge is
// pushed together; it is not the friction of the final state); sail blocks keep theirs.
// Settle: the physical friction back, more solver iterations, and a velocity-
// proportional damping (rate settle.damping, implicit) against the residual creep and
// solver jitter of a deep pile. Each phase ends when the mean kinetic energy per block
// stays below the threshold for 1 s (after min_time in that phase).
class Settling {
 public:
  Settling(const RidgeRun& run, RigidWorld& world, const std::vector<BlockId>& ids, const std::vector<Placed>& placed)
      : run_(run), d_(run.d), world_(world), ids_(ids), placed_(placed), n_(placed.size()),
        check_every_(std::max(1, static_cast<int>(std::lround(0.25 / run.d.settle.dt)))),
        ring_(static_cast<int>(std::ceil(1.0 / (check_every_ * run.d.settle.dt) - 1e-9)) + 1), snaps_(ring_) {}

  /// Runs compaction and settling; fills the settle figures of `st`. Returns the last mean
  /// kinetic energy per block, J.
  double run(RidgeStats& st) {
    const double vcap = d_.settle.speed_cap_factor * d_.block_thickness / d_.settle.dt;
    double below = 0.0, ke = 0.0;
    bool settled = false, compacting = d_.settle.compaction_time > 0.0;
    std::uint64_t steps = 0;
    if (compacting) {
      set_keel_friction(d_.settle.compaction_friction);
      world_.set_solver_iterations(d_.settle.compaction_solver_iterations);
    }
    double phase_start = 0.0;
    if (n_ > 0) snapshot();
    while (n_ > 0) {
      world_.substep();
      ++steps;
      cap_and_damp(vcap, compacting ? 1.0 : 1.0 / (1.0 + d_.settle.damping * d_.settle.dt));
      if (steps % check_every_ != 0) continue;
      const double t = world_.time();
      ke = world_.kinetic_energy() / static_cast<double>(n_);
      snapshot();
      const double moved = last_second_max_displacement();
      run_.report(compacting ? "compact" : "settle", t, ke, n_, moved);
      bool phase_done = false;
      // The displacement test is the settle phase's (compaction ends at its time anyway).
      const bool still = compacting || !(d_.settle.max_displacement > 0.0) ||
                         (t - phase_start >= 1.0 && moved < d_.settle.max_displacement);
      if (t - phase_start >= d_.settle.min_time && ke < d_.settle.kinetic_energy_per_block && still) {
        below += check_every_ * d_.settle.dt;
        phase_done = below >= 1.0 - 1e-9;
      } else {
        below = 0.0;
      }
      if (compacting && (phase_done || t >= d_.settle.compaction_time)) {
        compacting = false;
        st.compaction_time = t;
        set_keel_friction(d_.settle.friction);
        world_.set_solver_iterations(d_.settle.solver_iterations);
        phase_start = t;
        below = 0.0;
        continue;
      }
      if (phase_done) {
        settled = true;
        break;
      }
      if (t >= d_.settle.max_time) break;
    }
    final_displacement(st);
    st.settled = settled || n_ == 0;
    st.settle_time = world_.time();
    st.settle_steps = steps;
    st.final_kinetic_energy_per_block = ke;
    return ke;
  }

 private:
  /// Only keel blocks: keel-keel and keel-ice contacts lose their friction (the combined
  /// coefficient is a product), sail blocks keep theirs on the ice and on each other.
  void set_keel_friction(double mu) {
    for (std::size_t i = 0; i < n_; ++i)
      if (placed_[i].part == 0) world_.set_friction(ids_[i], mu);
  }
  /// Speed cap (translation and rim speed of the rotation) and the settling damping.
  void cap_and_damp(double vcap, double damp) {
    for (std::size_t i = 0; i < n_; ++i) {
      Vec3 v = world_.velocity(ids_[i]);
      Vec3 w = world_.angular_velocity(ids_[i]);
      const double sv = v.norm(), sw = w.norm() * placed_[i].h.maxCoeff();
      if (sv > vcap) v *= vcap / sv;
      if (sw > vcap) w *= vcap / sw;
      if (sv > vcap || sw > vcap || damp != 1.0) world_.set_velocity(ids_[i], v * damp, w * damp);
    }
  }
  /// Positions at the last checks (a ring over >= 1 s): the displacement over the final
  /// second is reported next to the kinetic energy, as a direct measure of rest.
  void snapshot() {
    std::vector<Vec3>& v = snaps_[nsnap_++ % ring_];
    v.resize(n_);
    for (std::size_t i = 0; i < n_; ++i) v[i] = world_.position(ids_[i]);
  }
  /// The oldest snapshot in the ring (<= 1 s ago) and the newest; needs nsnap_ >= 2.
  const std::vector<Vec3>& oldest_snapshot() const {
    return snaps_[nsnap_ >= static_cast<std::uint64_t>(ring_) ? nsnap_ % ring_ : 0];
  }
  const std::vector<Vec3>& newest_snapshot() const { return snaps_[(nsnap_ - 1) % ring_]; }
  /// Largest block displacement since the oldest snapshot in the ring, m.
  double last_second_max_displacement() const {
    if (nsnap_ < 2) return std::numeric_limits<double>::infinity();
    const std::vector<Vec3>& old = oldest_snapshot();
    const std::vector<Vec3>& now = newest_snapshot();
    double m = 0.0;
    for (std::size_t i = 0; i < n_; ++i) m = std::max(m, (now[i] - old[i]).norm());
    return m;
  }
  void final_displacement(RidgeStats& st) const {
    if (nsnap_ < 2) return;  // displacement since the oldest snapshot in the ring (<= 1 s ago)
    const std::vector<Vec3>& old = oldest_snapshot();
    const std::vector<Vec3>& now = newest_snapshot();
    double sum = 0.0;
    for (std::size_t i = 0; i < n_; ++i) {
      const double dd = (now[i] - old[i]).norm();
      sum += dd;
      st.final_max_displacement = std::max(st.final_max_displacement, dd);
    }
    st.final_mean_displacement = sum / static_cast<double>(n_);
  }

  const RidgeRun& run_;
  const RidgeDef& d_;
  RigidWorld& world_;
  const std::vector<BlockId>& ids_;
  const std::vector<Placed>& placed_;
  const std::size_t n_;
  const int check_every_;
  const int ring_;
  std::vector<std::vector<Vec3>> snaps_;
  std::uint64_t nsnap_ = 0;
};

/// Where the final kinetic energy sits. A Bullet body asleep has its velocities set to
/// exactly zero (and counts 0 in ke); an awake body never has exactly zero velocity.
void final_energy_stats(const RigidWorld& world, const std::vector<BlockId>& ids, const std::vector<Placed>& placed,
                        RidgeStats& st) {
  const std::size_t n = placed.size();
  if (n == 0) return;
  std::vector<double> eb(n);
  double esail = 0.0, etot = 0.0;
  std::size_t asleep = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 v = world.velocity(ids[i]), w = world.angular_velocity(ids[i]);
    if (v.isZero(0.0) && w.isZero(0.0)) ++asleep;
    const Vec3 wl = world.orientation(ids[i]).toRotationMatrix().transpose() * w;
    const Vec3& h = placed[i].h;
    const double m = world.mass(ids[i]);
    const Vec3 inertia = m / 3.0 * Vec3(h.y() * h.y() + h.z() * h.z(), h.x() * h.x() + h.z() * h.z(),
                                        h.x() * h.x() + h.y() * h.y());
    eb[i] = 0.5 * m * v.squaredNorm() + 0.5 * wl.dot(inertia.cwiseProduct(wl));
    etot += eb[i];
    if (placed[i].part != 0) esail += eb[i];
  }
  st.final_asleep_blocks = asleep;
  st.final_kinetic_energy_per_awake_block = asleep < n ? etot / static_cast<double>(n - asleep) : 0.0;
  st.final_kinetic_energy_sail_fraction = etot > 0.0 ? esail / etot : 0.0;
  std::nth_element(eb.begin(), eb.begin() + n / 2, eb.end());
  st.final_kinetic_energy_median = eb[n / 2];
}

/// The settled blocks into the result (and back into `placed`, for the joints and the report).
void collect_blocks(const RigidWorld& world, const std::vector<BlockId>& ids, std::vector<Placed>& placed,
                    RidgeResult& res) {
  const std::size_t n = placed.size();
  res.blocks.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    RidgeBlock& b = res.blocks[i];
    b.half_extents = placed[i].h;
    b.position = world.position(ids[i]);
    b.orientation = world.orientation(ids[i]);
    if (b.orientation.w() < 0.0) b.orientation.coeffs() *= -1.0;  // canonical sign
    b.part = placed[i].part;
    placed[i].x = b.position;
    placed[i].q = b.orientation;
    placed[i].R = b.orientation.toRotationMatrix();
    placed[i].aabb = aabb_half(placed[i].h, placed[i].R);
    if (b.part == 0) ++res.stats.keel_blocks;
    else ++res.stats.sail_blocks;
  }
}

/// The plates' final poses (heave only) and lifts; the vertical force balance of the whole.
void collect_plates(const RigidWorld& world, const std::vector<BlockId>& ice_ids, RidgeResult& res) {
  const RidgeDef& d = res.def;
  const double g = 9.81;
  auto net_buoyancy = [&](const Vec3& h, const Vec3& x, const Quat& q, double density) {
    const SubmergedBox sb = submerged_box(h, x, q, 0.0);
    return g * (d.water_density * sb.volume - density * 8.0 * h.prod());
  };
  res.stats.block_net_buoyancy = 0.0;
  for (const RidgeBlock& b : res.blocks)
    res.stats.block_net_buoyancy += net_buoyancy(b.half_extents, b.position, b.orientation, d.ice_density);
  res.stats.plate_net_buoyancy = 0.0;
  if (!d.sheet.floating) return;
  for (std::size_t k = 0; k < res.ice.size(); ++k) {
    IceBox& b = res.ice[k];
    const double rest = b.position.z();
    const double rho = plate_density(rest + b.half_extents.z(), rest - b.half_extents.z(), d.water_density);
    b.position = world.position(ice_ids[k]);
    b.lift = b.position.z() - rest;
    res.stats.plate_net_buoyancy += net_buoyancy(b.half_extents, b.position, Quat::Identity(), rho);
  }
}

// ---- freeze joints and final overlap: every pair of boxes (block-block, block-ice) closer
// than the gap gets a joint of the area of their gap-inflated intersection over its depth.
void find_joints(const RidgeDef& d, const std::vector<Placed>& placed, const HashGrid& fgrid_in, RidgeResult& res) {
  HashGrid& fgrid = const_cast<HashGrid&>(fgrid_in);  // query() only stamps its scratch
  const double gap = d.joints.gap;
  const Vec3 hg = Vec3::Constant(0.5 * gap);
  auto try_joint = [&](std::int32_t a, std::int32_t b, const Vec3& ha, const Vec3& xa, const Mat3& A,
                       const Vec3& hb, const Vec3& xb, const Mat3& B) {
    const double pen = sat(ha, xa, A, hb, xb, B, nullptr);
    if (pen > 0.0) res.stats.max_final_overlap = std::max(res.stats.max_final_overlap, pen);
    Vec3 axis = Vec3::UnitZ();
    const double s = sat(ha + hg, xa, A, hb + hg, xb, B, &axis);
    if (s <= 0.0) return;
    Vec3 c = Vec3::Zero();
    const double vol = box_intersection(ha + hg, xa, A, hb + hg, xb, B, &c);
    const double area = vol / s;
    if (!(area >= d.joints.min_area) || area <= 0.0) return;
    RidgeJoint j;
    j.a = a;
    j.b = b;
    j.anchor = c;
    j.normal = axis;
    j.area = area;
    res.joints.push_back(j);
  };
  std::vector<std::int32_t> cand;
  for (std::size_t i = 0; i < placed.size(); ++i) {
    const Placed& p = placed[i];
    fgrid.query(p.x - p.aabb - Vec3::Constant(gap), p.x + p.aabb + Vec3::Constant(gap), cand);
    for (std::int32_t j : cand) {
      if (j <= static_cast<std::int32_t>(i)) continue;
      const Placed& o = placed[j];
      if (((p.x - o.x).cwiseAbs() - p.aabb - o.aabb).maxCoeff() > gap) continue;
      try_joint(static_cast<std::int32_t>(i), j, p.h, p.x, p.R, o.h, o.x, o.R);
    }
    for (std::size_t k = 0; k < res.ice.size(); ++k) {
      const IceBox& ib = res.ice[k];
      if (((p.x - ib.position).cwiseAbs() - p.aabb - ib.half_extents).maxCoeff() > gap) continue;
      const std::size_t before = res.joints.size();
      // The ice is b: normal from the block to the ice.
      try_joint(static_cast<std::int32_t>(i), -1 - static_cast<std::int32_t>(k), p.h, p.x, p.R,
                ib.half_extents, ib.position, Mat3::Identity());
      if (!d.joints.to_ice && res.joints.size() > before) res.joints.pop_back();
      else if (res.joints.size() > before) ++res.stats.ice_joints;
    }
  }
  res.stats.joints = res.joints.size();
}

/// The x range and bins of the report: bin b covers [(b0 + b) pb, (b0 + b + 1) pb).
struct ProfileBins {
  double xlo = 0.0, xhi = 0.0, pb = 0.0;
  std::int64_t b0 = 0;
  std::size_t nb = 0;
};

// ---- achieved profile: 95th percentile of block bottoms (keel) / tops (sail) per bin.
ProfileBins measure_profile(const RidgeRun& run, const std::vector<Placed>& placed, RidgeResult& res) {
  const RidgeDef& d = run.d;
  ProfileBins pbins;
  double xlo = 0.0, xhi = 0.0;
  for (const Placed& p : placed) xlo = std::min(xlo, p.x.x()), xhi = std::max(xhi, p.x.x());
  xlo = std::min(xlo, -std::max(run.kx, run.sx));
  xhi = std::max(xhi, std::max(run.kx, run.sx));
  if (!d.keel_profile.empty()) {
    xlo = std::min(xlo, d.keel_profile.front().position);
    xhi = std::max(xhi, d.keel_profile.back().position);
  }
  const double pb = d.profile_bin;
  const std::int64_t b0 = static_cast<std::int64_t>(std::floor(xlo / pb)),
                     b1 = static_cast<std::int64_t>(std::floor(xhi / pb));
  const std::size_t nb = static_cast<std::size_t>(b1 - b0 + 1);
  std::vector<std::vector<double>> kbot(nb), stop(nb);
  for (const Placed& p : placed) {
    const std::size_t bi = static_cast<std::size_t>(static_cast<std::int64_t>(std::floor(p.x.x() / pb)) - b0);
    if (p.part == 0) kbot[bi].push_back(-(p.x.z() - p.aabb.z()));
    else stop[bi].push_back(p.x.z() + p.aabb.z());
  }
  RidgeProfile& pr = res.profile;
  double se = 0.0;
  std::size_t ne = 0;
  for (std::size_t i = 0; i < nb; ++i) {
    const double xc = (static_cast<double>(b0 + static_cast<std::int64_t>(i)) + 0.5) * pb;
    pr.x.push_back(xc);
    pr.keel_target.push_back(keel_target_depth(d, xc));
    pr.keel_depth.push_back(percentile95(kbot[i]));
    pr.sail_target.push_back(sail_target_height(d, xc));
    pr.sail_height.push_back(percentile95(stop[i]));
    if (pr.keel_target.back() > 0.0 || pr.keel_depth.back() > 0.0) {
      const double e = pr.keel_depth.back() - pr.keel_target.back();
      se += e * e;
      ++ne;
    }
    res.stats.keel_depth_target = std::max(res.stats.keel_depth_target, pr.keel_target.back());
    res.stats.keel_depth_achieved = std::max(res.stats.keel_depth_achieved, pr.keel_depth.back());
    res.stats.sail_height_target = std::max(res.stats.sail_height_target, pr.sail_target.back());
    res.stats.sail_height_achieved = std::max(res.stats.sail_height_achieved, pr.sail_height.back());
  }
  res.stats.keel_profile_rms_error = ne ? std::sqrt(se / static_cast<double>(ne)) : 0.0;
  pbins.xlo = xlo;
  pbins.xhi = xhi;
  pbins.pb = pb;
  pbins.b0 = b0;
  pbins.nb = nb;
  return pbins;
}

// ---- porosity: point count inside the achieved keel envelope.
void measure_porosity(const RidgeDef& d, const std::vector<Placed>& placed, const HashGrid& fgrid,
                      const ProfileBins& bins, RidgeResult& res) {
  const double g = d.porosity_grid, pb = bins.pb;
  const RidgeProfile& pr = res.profile;
  std::uint64_t pts_all = 0, in_all = 0, pts_core = 0, in_core = 0;
  const std::int64_t nx = static_cast<std::int64_t>(std::floor((bins.xhi - bins.xlo) / g));
  const std::int64_t ny = static_cast<std::int64_t>(std::floor(d.length / g));
  for (std::int64_t ix = 0; ix < nx; ++ix) {
    const double x = bins.xlo + (static_cast<double>(ix) + 0.5) * g;
    const std::size_t bi = static_cast<std::size_t>(static_cast<std::int64_t>(std::floor(x / pb)) - bins.b0);
    if (bi >= bins.nb) continue;
    const double zb = -pr.keel_depth[bi], zt = -ice_draft(d, x);
    if (!(zb < zt)) continue;
    // Core: under the consolidated layer, upper 80 % of the local keel thickness (away
    // from the rough bottom, where the 95th-percentile envelope is mostly water).
    const bool core_x = std::abs(x) < 0.5 * d.consolidated_layer_width;
    const double zcore = zt + 0.8 * (zb - zt);
    for (std::int64_t iy = 0; iy < ny; ++iy) {
      const double y = (static_cast<double>(iy) + 0.5) * g;
      for (double z = zt - 0.5 * g; z > zb; z -= g) {
        const Vec3 q(x, y, z);
        bool inside = false;
        if (const auto* c = fgrid.cell_of(q))
          for (std::int32_t id : *c) {
            const Placed& p = placed[id];
            if (p.part != 0) continue;
            const Vec3 l = p.R.transpose() * (q - p.x);
            if (std::abs(l.x()) <= p.h.x() && std::abs(l.y()) <= p.h.y() && std::abs(l.z()) <= p.h.z()) {
              inside = true;
              break;
            }
          }
        ++pts_all;
        in_all += inside;
        if (core_x && z > zcore) ++pts_core, in_core += inside;
      }
    }
  }
  res.stats.keel_porosity = pts_all ? 1.0 - static_cast<double>(in_all) / static_cast<double>(pts_all) : 0.0;
  res.stats.core_porosity = pts_core ? 1.0 - static_cast<double>(in_core) / static_cast<double>(pts_core) : 0.0;
}

}  // namespace

RidgeEstimate ridge_estimate(const RidgeDef& d) {
  RidgeEstimate e;
  // The envelopes' cross-sections by the trapezoid rule on 4000 intervals (a bounded cost for
  // any ridge size; generate_ridge integrates on a 2 cm grid).
  auto section = [&](bool keel, double hw) {
    double lo = -hw, hi = hw;
    if (keel && !d.keel_profile.empty()) lo = d.keel_profile.front().position, hi = d.keel_profile.back().position;
    if (!(hi > lo)) return 0.0;
    auto thick = [&](double x) {
      return keel ? std::max(0.0, keel_target_depth(d, x) - ice_draft(d, x))
                  : std::max(0.0, sail_target_height(d, x) - ice_freeboard(d, x));
    };
    const int n = 4000;
    double a = 0.0;
    for (int i = 0; i < n; ++i) {
      const double x0 = lo + (hi - lo) * i / n, x1 = lo + (hi - lo) * (i + 1) / n;
      a += 0.5 * (thick(x0) + thick(x1)) * (x1 - x0);
    }
    return a;
  };
  e.keel_volume = section(true, keel_half_width(d)) * d.length;
  e.sail_volume = d.sail_height > 0.0 ? section(false, sail_half_width(d)) * d.length : 0.0;
  // Blocks are L x B x h with L = h r, ln r ~ N(m, s), B = L U(wmin, wmax): E[L B h] = h^3 E[r^2] E[U].
  double m = 0.0, sd = 0.0;
  d.aspect.log_params(m, sd);
  const double h = d.block_thickness;
  e.mean_block_volume =
      h * h * h * std::exp(2.0 * m + 2.0 * sd * sd) * 0.5 * (d.width_fraction_min + d.width_fraction_max);
  e.blocks = e.mean_block_volume > 0 ? (1.0 - d.fill_porosity) * (e.keel_volume + e.sail_volume) / e.mean_block_volume
                                     : 0.0;
  e.bytes = e.blocks * kRidgeBytesPerBlock;
  return e;
}

RidgeResult generate_ridge(const RidgeDef& def, const RidgeProgressFn& progress) {
  validate(def, "ridge");
  const auto wall0 = std::chrono::steady_clock::now();
  RidgeResult res;
  res.def = def;
  const RidgeDef& d = def;
  RidgeRun run(d, progress);
  add_ice_sheet(run, res.ice);

  // Placement, into the target envelopes.
  const Envelope keel(d, true, run.kx);
  const Envelope sail = d.sail_height > 0.0 ? Envelope(d, false, run.sx) : Envelope();
  res.stats.keel_target_volume = keel.volume;
  Placement placement(run, keel, sail);
  res.stats.keel_block_volume = placement.fill(true, (1.0 - d.fill_porosity) * keel.volume);
  res.stats.sail_block_volume = sail.volume > 0.0 ? placement.fill(false, (1.0 - d.fill_porosity) * sail.volume) : 0.0;
  std::vector<Placed> placed = std::move(placement.placed);
  const std::size_t n = placed.size();
  run.report("place", 0.0, 0.0, n);

  // Compaction and settling in the rigid world.
  RigidWorld world(settle_world_def(d));
  std::vector<BlockId> ice_ids;
  const std::vector<BlockId> ids = build_settle_world(world, run, res.ice, placed, ice_ids);
  const double ke = Settling(run, world, ids, placed).run(res.stats);
  final_energy_stats(world, ids, placed, res.stats);
  collect_blocks(world, ids, placed, res);
  collect_plates(world, ice_ids, res);

  // Joints, then the report.
  run.report("joints", res.stats.settle_time, ke, n);
  HashGrid fgrid(2.0);
  for (std::size_t i = 0; i < n; ++i)
    fgrid.insert(static_cast<std::int32_t>(i), placed[i].x - placed[i].aabb - Vec3::Constant(d.joints.gap),
                 placed[i].x + placed[i].aabb + Vec3::Constant(d.joints.gap));
  find_joints(d, placed, fgrid, res);
  run.report("measure", res.stats.settle_time, ke, n);
  const ProfileBins bins = measure_profile(run, placed, res);
  measure_porosity(d, placed, fgrid, bins, res);
  res.stats.wall_time =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  return res;
}

RidgeResult resettle_ridge(const RidgeResult& in, const RidgeResettleDef& rd, RidgeResettleStats* stats_out,
                           const RidgeProgressFn& progress) {
  const auto wall0 = std::chrono::steady_clock::now();
  const RidgeDef& d = in.def;
  const std::size_t n = in.blocks.size();
  if (!rd.keep.empty() && rd.keep.size() != n)
    throw InputError("resettle/keep", "must have one flag per block of the ridge (" + std::to_string(n) + ")");
  if (rd.phases.empty()) throw InputError("resettle/phases", "needs at least one phase");
  for (const auto& ph : rd.phases)
    if (!(ph.dt > 0.0) || !(ph.time >= 0.0) || ph.solver_iterations < 1 || !(ph.damping >= 0.0))
      throw InputError("resettle/phases", "each phase needs dt > 0, time >= 0, solver_iterations >= 1, damping >= 0");
  RidgeResettleStats st;
  auto kept = [&](std::size_t i) { return rd.keep.empty() || rd.keep[i] != 0; };
  auto moves = [&](std::size_t i) {
    const Vec3& x = in.blocks[i].position;
    return (x.array() >= rd.region_lo.array()).all() && (x.array() <= rd.region_hi.array()).all();
  };
  std::vector<RidgeBlock> blocks = in.blocks;  // current poses
  std::vector<IceBox> plates = rd.plates;      // current poses (rest poses in rd.plates)
  std::vector<Vec3> last_second;               // moving blocks' positions one second before the end
  for (std::size_t i = 0; i < n; ++i) {
    if (!kept(i)) ++st.dropped_blocks;
    else if (moves(i)) ++st.moving_blocks;
    else ++st.held_blocks;
  }
  double ke = 0.0, t_total = 0.0, t_end = 0.0;
  for (const auto& ph : rd.phases) t_end += ph.time;
  const double vcap_h = d.settle.speed_cap_factor * d.block_thickness;  // / dt: the generator's cap
  for (const auto& ph : rd.phases) {
    RidgeDef pd = d;
    pd.settle.dt = ph.dt;
    pd.settle.solver_iterations = ph.solver_iterations;
    pd.settle.allow_sleep = false;  // (Bullet's islands would join the held blocks' neighbours)
    RigidWorldDef wd = settle_world_def(pd);
    // Every penetration removed by position (split impulse) as in the run's world (bridge): at a
    // small step the erp push of a shallow overlap (Bullet's below 4 cm) is a kick (0.2 x 4 cm at
    // 1/240 s: 1.9 m/s), and a block pile that rested at 1/30 s has such overlaps everywhere.
    wd.split_impulse_depth = 0.0;
    RigidWorld world(wd);
    for (const IceBox& b : rd.fixed_boxes) {
      BlockDef bd;
      bd.half_extents = b.half_extents;
      bd.position = b.position;
      bd.fixed = true;
      world.add_block(bd);
    }
    std::vector<BlockId> plate_ids;
    for (std::size_t k = 0; k < plates.size(); ++k) {
      const IceBox& rest = rd.plates[k];
      BlockDef bd;
      bd.half_extents = rest.half_extents;
      bd.position = plates[k].position;
      bd.density = plate_density(rest.position.z() + rest.half_extents.z(), rest.position.z() - rest.half_extents.z(),
                                 d.water_density);
      bd.linear_factor = Vec3::UnitZ();
      bd.angular_factor = Vec3::Zero();
      plate_ids.push_back(world.add_block(bd));
    }
    for (std::size_t k = 0; k + 1 < plates.size(); ++k) {  // joined: the settle world's joints never break
      FreezeJointDef j;
      j.a = plate_ids[k];
      j.b = plate_ids[k + 1];
      j.anchor = 0.5 * (plates[k].position + plates[k + 1].position);
      j.normal = (plates[k + 1].position - plates[k].position).normalized();
      j.area = 1.0;
      world.add_freeze_joint(j);
    }
    if (!rd.obstacle_triangles.empty()) {
      KinematicMeshDef m;
      m.vertices = rd.obstacle_vertices;
      m.triangles = rd.obstacle_triangles;
      m.position = rd.obstacle_position;
      world.add_kinematic_mesh(m);
    }
    std::vector<BlockId> ids(n);
    std::vector<std::size_t> moving;
    for (std::size_t i = 0; i < n; ++i) {
      if (!kept(i)) continue;
      BlockDef bd;
      bd.half_extents = blocks[i].half_extents;
      bd.position = blocks[i].position;
      bd.orientation = blocks[i].orientation;
      bd.density = d.ice_density;
      bd.fixed = !moves(i);
      ids[i] = world.add_block(bd);
      if (!bd.fixed) moving.push_back(i);
    }
    const auto steps = static_cast<std::uint64_t>(std::llround(ph.time / ph.dt));
    const double damp = 1.0 / (1.0 + ph.damping * ph.dt), vcap = vcap_h / ph.dt;
    const std::uint64_t report_every = std::max<std::uint64_t>(1, static_cast<std::uint64_t>(std::lround(0.25 / ph.dt)));
    for (std::uint64_t s = 0; s < steps; ++s) {
      world.substep();
      t_total += ph.dt;
      for (const std::size_t i : moving) {
        Vec3 v = world.velocity(ids[i]), w = world.angular_velocity(ids[i]);
        const double sv = v.norm(), sw = w.norm() * blocks[i].half_extents.maxCoeff();
        if (sv > vcap) v *= vcap / sv;
        if (sw > vcap) w *= vcap / sw;
        world.set_velocity(ids[i], v * damp, w * damp);
      }
      if (last_second.empty() && t_total >= t_end - 1.0 - 1e-9) {
        last_second.assign(n, Vec3::Zero());
        for (const std::size_t i : moving) last_second[i] = world.position(ids[i]);
      }
      if ((s + 1) % report_every == 0 || s + 1 == steps) {
        ke = world.kinetic_energy() / static_cast<double>(std::max<std::size_t>(1, moving.size()));
        if (progress) {
          RidgeProgress q;
          q.phase = "resettle";
          q.time = t_total;
          q.max_time = t_end;
          q.kinetic_energy_per_block = ke;
          q.blocks = moving.size();
          progress(q);
        }
      }
    }
    for (const std::size_t i : moving) {
      blocks[i].position = world.position(ids[i]);
      blocks[i].orientation = world.orientation(ids[i]);
      if (blocks[i].orientation.w() < 0.0) blocks[i].orientation.coeffs() *= -1.0;  // canonical sign
    }
    for (std::size_t k = 0; k < plates.size(); ++k) plates[k].position = world.position(plate_ids[k]);
  }
  st.final_kinetic_energy_per_block = ke;
  // The result: blocks renumbered without the left-out ones, joints carried with their first block.
  RidgeResult res = in;
  res.blocks.clear();
  std::vector<std::int32_t> index(n, -1);
  for (std::size_t i = 0; i < n; ++i) {
    if (!kept(i)) continue;
    index[i] = static_cast<std::int32_t>(res.blocks.size());
    res.blocks.push_back(blocks[i]);
    st.max_displacement = std::max(st.max_displacement, (blocks[i].position - in.blocks[i].position).norm());
    if (!last_second.empty() && moves(i))
      st.last_second_max_displacement =
          std::max(st.last_second_max_displacement, (blocks[i].position - last_second[i]).norm());
  }
  res.joints.clear();
  for (const RidgeJoint& j : in.joints) {
    const auto a = static_cast<std::size_t>(j.a);
    if (index[a] < 0 || (j.b >= 0 && index[static_cast<std::size_t>(j.b)] < 0)) {
      ++st.dropped_joints;
      continue;
    }
    RidgeJoint o = j;
    o.a = index[a];
    if (j.b >= 0) o.b = index[static_cast<std::size_t>(j.b)];
    const Quat dq = blocks[a].orientation * in.blocks[a].orientation.conjugate();
    o.anchor = blocks[a].position + dq * (j.anchor - in.blocks[a].position);
    o.normal = dq * j.normal;
    if (j.b < 0) {  // to the ice: the result's ice is the plates; the plate nearest the anchor in x
      if (plates.empty()) {
        ++st.dropped_joints;
        continue;
      }
      std::size_t best = 0;
      double dist = std::numeric_limits<double>::infinity();
      for (std::size_t k = 0; k < plates.size(); ++k) {
        const double dx = std::max(0.0, std::abs(o.anchor.x() - plates[k].position.x()) - plates[k].half_extents.x());
        if (dx < dist) dist = dx, best = k;
      }
      o.b = -1 - static_cast<std::int32_t>(best);
    }
    res.joints.push_back(o);
  }
  res.ice.clear();
  for (std::size_t k = 0; k < plates.size(); ++k) {
    IceBox b = rd.plates[k];
    b.lift = plates[k].position.z() - rd.plates[k].position.z();
    b.position = plates[k].position;
    res.ice.push_back(b);
  }
  if (!plates.empty()) {
    res.def.sheet.floating = true;
    res.def.sheet.plates_joined = true;
    st.plate_lift = res.ice.front().lift;
  }
  res.stats.keel_blocks = res.stats.sail_blocks = 0;
  for (const RidgeBlock& b : res.blocks) (b.part == 0 ? res.stats.keel_blocks : res.stats.sail_blocks)++;
  res.stats.joints = res.joints.size();
  res.stats.ice_joints = static_cast<std::size_t>(
      std::count_if(res.joints.begin(), res.joints.end(), [](const RidgeJoint& j) { return j.b < 0; }));
  st.wall_time = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  if (stats_out) *stats_out = st;
  return res;
}


// ---------------------------------------------------------------- JSON
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
  validate(d, P);
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

double plate_density(double top, double underside, double water_density) {
  if (!(top > 0.0 && underside < 0.0))
    throw InputError("", "a floating plate needs its top above and its underside below the waterline (top " +
                             json_fmt(top) + " m, underside " + json_fmt(underside) + " m)");
  return water_density * (-underside) / (top - underside);
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
