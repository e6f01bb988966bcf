// Parametric pier: closed, outward normals, analytic volume and radii, parameter checks.
#include "common/error.h"
#include "mesh/pier.h"

#include <gtest/gtest.h>

#include <cmath>

namespace hs::mesh {
namespace {

TEST(MeshPier, ClosedOutwardAndPartsNamed) {
  const PierParams p;
  const TriMesh m = make_pier(p);
  EXPECT_EQ(m.part_names, (std::vector<std::string>{"neck", "cone", "shaft"}));
  EXPECT_EQ(m.triangles.size(), 10u * 64u);
  EXPECT_EQ(m.vertices.size(), 5u * 64u + 2u);
  EXPECT_TRUE(is_closed(m));
  EXPECT_TRUE(is_consistently_oriented(m));
  EXPECT_GT(signed_volume(m), 0.0);
  // Every normal points away from the axis or, on the flat parts, straight up/down.
  for (std::uint32_t t = 0; t < m.triangles.size(); ++t) {
    const Vec3 n = triangle_normal(m, t);
    Vec3 centroid = Vec3::Zero();
    for (auto v : m.triangles[t]) centroid += m.vertices[v] / 3.0;
    const Vec3 radial(centroid.x(), centroid.y(), 0.0);
    if (std::abs(n.z()) > 1.0 - 1e-12) {
      const bool top = centroid.z() > p.cone_top_z + 0.5 * p.neck_height;
      EXPECT_EQ(n.z() > 0.0, top) << "triangle " << t;
    } else {
      EXPECT_GT(n.dot(radial), 0.0) << "triangle " << t;
    }
  }
  // Part by height: annulus (flat, z = cone_bottom_z, facing down) belongs to the cone.
  for (std::uint32_t t = 0; t < m.triangles.size(); ++t) {
    double zmin = 1e9, zmax = -1e9;
    for (auto v : m.triangles[t]) {
      zmin = std::min(zmin, m.vertices[v].z());
      zmax = std::max(zmax, m.vertices[v].z());
    }
    const std::string& part = m.part_names[m.triangle_part[t]];
    if (zmin >= p.cone_top_z) EXPECT_EQ(part, "neck");
    else if (zmax <= p.cone_bottom_z && zmin < p.cone_bottom_z) EXPECT_EQ(part, "shaft");
    else EXPECT_EQ(part, "cone");
  }
}

TEST(MeshPier, VolumeMatchesPolygonalFormulaExactlyAndCircularWithinOnePercent) {
  const PierParams p;
  const double v = signed_volume(make_pier(p));
  EXPECT_NEAR(v / pier_polygonal_volume(p), 1.0, 6e-14);  // measured 5.3e-15 (was 1e-12)
  EXPECT_NEAR(v / pier_volume(p), 1.0, 0.01);
  EXPECT_LT(v, pier_volume(p));  // inscribed polygons
  // The polygon converges to the circle: 1 - (N / 2 pi) sin(2 pi / N) ~ (2 pi / N)^2 / 6.
  PierParams fine = p;
  fine.segments = 512;
  EXPECT_NEAR(signed_volume(make_pier(fine)) / pier_volume(p), 1.0, 3e-5);
  // Analytic circular volume for the default parameters, computed by hand:
  const double t = std::tan(52.0 * kPi / 180.0);
  const double r1 = 7.0 - 2.0 / t, r2 = 7.0 + 4.0 / t;
  const double by_hand = kPi * r1 * r1 * 18.0 + kPi * 6.0 / 3.0 * (r1 * r1 + r2 * r2 + r1 * r2) +
                         kPi * 25.0 * 16.0;
  EXPECT_NEAR(pier_volume(p) / by_hand, 1.0, 1e-14);
}

TEST(MeshPier, RadiiAndWaterline) {
  const PierParams p;
  EXPECT_DOUBLE_EQ(pier_radius_at(p, 0.0), 7.0);
  EXPECT_NEAR(pier_radius_at(p, 1.0), 7.0 - 1.0 / std::tan(52.0 * kPi / 180.0), 1e-14);
  EXPECT_DOUBLE_EQ(pier_radius_at(p, 5.0), pier_cone_radius(p, 2.0));
  EXPECT_DOUBLE_EQ(pier_radius_at(p, -10.0), 5.0);
  EXPECT_DOUBLE_EQ(pier_radius_at(p, -4.0), pier_cone_radius(p, -4.0));
  EXPECT_DOUBLE_EQ(pier_radius_at(p, 6.5), pier_cone_radius(p, 2.0));  // the column, up to the deck
  EXPECT_DOUBLE_EQ(pier_radius_at(p, 19.9), pier_cone_radius(p, 2.0));
  EXPECT_EQ(pier_radius_at(p, 20.5), 0.0);
  EXPECT_EQ(pier_radius_at(p, -20.5), 0.0);

  // The mesh: corners lie on the circle of radius pier_radius_at; along the corner
  // line at phi = 0 the cone surface crosses z = 0 at x = 7 m.
  const TriMesh m = make_pier(p);
  for (const auto& v : m.vertices) {
    const double rxy = std::hypot(v.x(), v.y());
    if (rxy == 0.0) continue;  // cap centres
    const bool on_some_ring =
        std::abs(rxy - pier_cone_radius(p, p.cone_top_z)) < 1e-12 ||
        std::abs(rxy - pier_cone_radius(p, p.cone_bottom_z)) < 1e-12 || std::abs(rxy - 5.0) < 1e-12;
    EXPECT_TRUE(on_some_ring) << rxy;
  }
  Vec3 top = Vec3::Zero(), bottom = Vec3::Zero();
  for (const auto& v : m.vertices) {
    if (v.y() == 0.0 && v.x() > 0.0 && v.z() == p.cone_top_z) top = v;
    if (v.y() == 0.0 && v.x() > 6.0 && v.z() == p.cone_bottom_z) bottom = v;
  }
  const double s = (0.0 - bottom.z()) / (top.z() - bottom.z());
  EXPECT_NEAR(bottom.x() + s * (top.x() - bottom.x()), 7.0, 1e-12);
}

TEST(MeshPier, InvalidParametersNameTheField) {
  auto expect_field = [](PierParams p, const std::string& field, const std::string& words) {
    try {
      make_pier(p);
      ADD_FAILURE() << "no error for " << field;
    } catch (const InputError& e) {
      EXPECT_EQ(e.path(), field);
      EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
    }
  };
  PierParams p;
  p.shaft_diameter = 30.0;
  expect_field(p, "shaft_diameter", "shaft_diameter must be smaller than the cone base diameter");
  p = {};
  p.cone_angle_deg = 90.0;
  expect_field(p, "cone_angle_deg", "(0, 90)");
  p = {};
  p.cone_top_z = -5.0;
  expect_field(p, "cone_top_z", "above cone_bottom_z");
  p = {};
  p.cone_top_z = 20.0;
  expect_field(p, "cone_top_z", "apex");
  p = {};
  p.shaft_bottom_z = -3.0;
  expect_field(p, "shaft_bottom_z", "below cone_bottom_z");
  p = {};
  p.segments = 2;
  expect_field(p, "segments", "[3,");
  p = {};
  p.neck_height = 0.0;
  expect_field(p, "neck_height", "> 0");
  p = {};
  p.waterline_diameter = std::nan("");
  expect_field(p, "waterline_diameter", "finite");

  p = {};
  p.shaft_diameter = -1.0;
  try {
    validate_pier_params(p, "/structure/pier");
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_EQ(e.path(), "/structure/pier/shaft_diameter");
  }
}

}  // namespace
}  // namespace hs::mesh
