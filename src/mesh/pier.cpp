#include "mesh/pier.h"

#include "common/error.h"

#include <cmath>
#include <sstream>

namespace hs::mesh {

namespace {

std::string num(double v) {
  std::ostringstream s;
  s.precision(6);
  s << v;
  return s.str();
}

double frustum_volume(double a1, double a2, double h) {
  return h / 3.0 * (a1 + a2 + std::sqrt(a1 * a2));
}

}  // namespace

double pier_cone_radius(const PierParams& p, double z) {
  return 0.5 * p.waterline_diameter - z / std::tan(p.cone_angle_deg * kPi / 180.0);
}

void validate_pier_params(const PierParams& p, const std::string& prefix) {
  auto fail = [&](const std::string& field, const std::string& msg) {
    throw InputError(prefix.empty() ? field : prefix + "/" + field, field + " " + msg);
  };
  auto finite = [&](const std::string& field, double v) {
    if (!std::isfinite(v)) fail(field, "must be a finite number (got " + num(v) + ")");
  };
  finite("waterline_diameter", p.waterline_diameter);
  finite("cone_angle_deg", p.cone_angle_deg);
  finite("cone_top_z", p.cone_top_z);
  finite("cone_bottom_z", p.cone_bottom_z);
  finite("neck_height", p.neck_height);
  finite("shaft_diameter", p.shaft_diameter);
  finite("shaft_bottom_z", p.shaft_bottom_z);
  if (!(p.waterline_diameter > 0.0)) {
    fail("waterline_diameter", "must be > 0 m (got " + num(p.waterline_diameter) + ")");
  }
  if (!(p.cone_angle_deg > 0.0 && p.cone_angle_deg < 90.0)) {
    fail("cone_angle_deg", "must be in (0, 90) degrees from the horizontal (got " +
                               num(p.cone_angle_deg) + ")");
  }
  if (!(p.cone_top_z > p.cone_bottom_z)) {
    fail("cone_top_z", "must be above cone_bottom_z (got " + num(p.cone_top_z) + " <= " +
                           num(p.cone_bottom_z) + ")");
  }
  if (!(pier_cone_radius(p, p.cone_top_z) > 0.0)) {
    fail("cone_top_z", "is above the cone apex: the cone radius there would be " +
                           num(pier_cone_radius(p, p.cone_top_z)) +
                           " m; lower cone_top_z, widen waterline_diameter or flatten "
                           "cone_angle_deg");
  }
  if (!(p.neck_height > 0.0)) {
    fail("neck_height", "must be > 0 m (got " + num(p.neck_height) + ")");
  }
  if (!(p.shaft_diameter > 0.0)) {
    fail("shaft_diameter", "must be > 0 m (got " + num(p.shaft_diameter) + ")");
  }
  const double base_d = 2.0 * pier_cone_radius(p, p.cone_bottom_z);
  if (!(p.shaft_diameter < base_d)) {
    fail("shaft_diameter", "must be smaller than the cone base diameter " + num(base_d) +
                               " m (at cone_bottom_z = " + num(p.cone_bottom_z) + " m; got " +
                               num(p.shaft_diameter) + " m)");
  }
  if (!(p.shaft_bottom_z < p.cone_bottom_z)) {
    fail("shaft_bottom_z", "must be below cone_bottom_z = " + num(p.cone_bottom_z) +
                               " m (got " + num(p.shaft_bottom_z) + ")");
  }
  if (p.segments < 3 || p.segments > 100000) {
    fail("segments", "must be in [3, 100000] (got " + std::to_string(p.segments) + ")");
  }
}

TriMesh make_pier(const PierParams& p) {
  validate_pier_params(p);
  const std::uint32_t n = std::uint32_t(p.segments);
  const double r_neck = pier_cone_radius(p, p.cone_top_z);
  const double r_base = pier_cone_radius(p, p.cone_bottom_z);
  const double r_shaft = 0.5 * p.shaft_diameter;
  const double z_top = p.cone_top_z + p.neck_height;

  TriMesh m;
  m.part_names = {"neck", "cone", "shaft"};
  // Rings, top to bottom: 0 neck top, 1 cone top, 2 cone base, 3 shaft top (annulus
  // inner edge), 4 shaft bottom; then the two cap centres.
  const double ring_r[5] = {r_neck, r_neck, r_base, r_shaft, r_shaft};
  const double ring_z[5] = {z_top, p.cone_top_z, p.cone_bottom_z, p.cone_bottom_z,
                            p.shaft_bottom_z};
  m.vertices.reserve(5 * n + 2);
  for (int ring = 0; ring < 5; ++ring) {
    for (std::uint32_t k = 0; k < n; ++k) {
      const double phi = 2.0 * kPi * double(k) / double(n);
      m.vertices.emplace_back(ring_r[ring] * std::cos(phi), ring_r[ring] * std::sin(phi),
                              ring_z[ring]);
    }
  }
  const std::uint32_t top_centre = 5 * n;
  const std::uint32_t bottom_centre = 5 * n + 1;
  m.vertices.emplace_back(0.0, 0.0, z_top);
  m.vertices.emplace_back(0.0, 0.0, p.shaft_bottom_z);

  auto v = [n](std::uint32_t ring, std::uint32_t k) { return ring * n + (k % n); };
  auto add = [&m](std::uint32_t a, std::uint32_t b, std::uint32_t c, std::uint16_t part) {
    m.triangles.push_back({a, b, c});
    m.triangle_part.push_back(part);
  };
  // Side band between an upper and a lower ring; counter-clockwise seen from outside.
  auto band = [&](std::uint32_t upper, std::uint32_t lower, std::uint16_t part) {
    for (std::uint32_t k = 0; k < n; ++k) {
      add(v(lower, k), v(lower, k + 1), v(upper, k + 1), part);
      add(v(lower, k), v(upper, k + 1), v(upper, k), part);
    }
  };
  for (std::uint32_t k = 0; k < n; ++k) add(top_centre, v(0, k), v(0, k + 1), kPierNeck);
  band(0, 1, kPierNeck);
  band(1, 2, kPierCone);
  // Annulus facing down (-z): inner ring 3 to outer ring 2.
  for (std::uint32_t k = 0; k < n; ++k) {
    add(v(3, k), v(3, k + 1), v(2, k + 1), kPierCone);
    add(v(3, k), v(2, k + 1), v(2, k), kPierCone);
  }
  band(3, 4, kPierShaft);
  for (std::uint32_t k = 0; k < n; ++k) add(bottom_centre, v(4, k + 1), v(4, k), kPierShaft);

  validate_mesh(m, "make_pier");
  build_topology(m);
  return m;
}

double pier_radius_at(const PierParams& p, double z) {
  const double z_top = p.cone_top_z + p.neck_height;
  if (z > z_top || z < p.shaft_bottom_z) return 0.0;
  if (z > p.cone_top_z) return pier_cone_radius(p, p.cone_top_z);
  if (z >= p.cone_bottom_z) return pier_cone_radius(p, z);
  return 0.5 * p.shaft_diameter;
}

namespace {

template <class Area>
double pier_volume_with(const PierParams& p, Area area) {
  const double a_neck = area(pier_cone_radius(p, p.cone_top_z));
  const double a_base = area(pier_cone_radius(p, p.cone_bottom_z));
  const double a_shaft = area(0.5 * p.shaft_diameter);
  return a_neck * p.neck_height +
         frustum_volume(a_neck, a_base, p.cone_top_z - p.cone_bottom_z) +
         a_shaft * (p.cone_bottom_z - p.shaft_bottom_z);
}

}  // namespace

double pier_volume(const PierParams& p) {
  return pier_volume_with(p, [](double r) { return kPi * r * r; });
}

double pier_polygonal_volume(const PierParams& p) {
  const double n = p.segments;
  return pier_volume_with(p, [n](double r) { return 0.5 * n * r * r * std::sin(2.0 * kPi / n); });
}

}  // namespace hs::mesh
