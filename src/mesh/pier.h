// Parametric Confederation Bridge-like pier: a closed, outward-facing triangle mesh.
//
// Profile (axis = z through the origin, water line z = 0), top to bottom:
//   neck   vertical cylinder, radius r(cone_top_z), from cone_top_z + neck_height
//          down to cone_top_z: the pier's column above the ice shield, up to the deck
//          (default top z = +20 m, above any rubble pile); closed by a flat top cap
//          there (part "neck");
//   cone   r(z) = waterline_diameter/2 - z / tan(cone_angle), widening downwards from
//          cone_top_z to cone_bottom_z (an upward-breaking ice shield; the slope is
//          cone_angle from the horizontal), then a flat horizontal annulus at cone_bottom_z
//          from the cone base radius in to the shaft radius (part "cone");
//   shaft  vertical cylinder, radius shaft_diameter/2, from cone_bottom_z down to
//          shaft_bottom_z, closed by a flat bottom cap (part "shaft").
// Circles are regular polygons with `segments` corners ON the circle (circumradius r,
// first corner on +x), so radii measured through corners are exact.
#pragma once

#include "mesh/tri_mesh.h"

#include <string>

namespace hs::mesh {

struct PierParams {
  double waterline_diameter = 14.0;  ///< cone diameter at z = 0, m
  double cone_angle_deg = 52.0;      ///< cone slope from the horizontal, deg, in (0, 90)
  double cone_top_z = 2.0;           ///< where the cone meets the neck, m
  double cone_bottom_z = -4.0;       ///< cone base (widest section), m
  double neck_height = 18.0;         ///< vertical column above the cone top, m (to the deck, z = +20 m)
  double shaft_diameter = 10.0;      ///< column below the cone base, m
  double shaft_bottom_z = -20.0;     ///< m
  int segments = 64;                 ///< polygon corners per circle, >= 3
};

/// Default deck level, m above the water line (pier frame): the top of the neck when a scene
/// gives neither structure.pier.deck_z nor neck_height (scene/scene.cpp).
inline constexpr double kPierDefaultDeckZ = 20.0;

/// Part ids of make_pier (indices into TriMesh::part_names).
inline constexpr std::uint16_t kPierNeck = 0;
inline constexpr std::uint16_t kPierCone = 1;
inline constexpr std::uint16_t kPierShaft = 2;

/// Throws hs::InputError naming the offending field (prefixed by `path_prefix` + "/"
/// when given, e.g. "/structure/pier") with the allowed range.
void validate_pier_params(const PierParams& p, const std::string& path_prefix = "");

/// Validates, then builds the mesh (parts "neck", "cone", "shaft"; topology built).
TriMesh make_pier(const PierParams& p);

/// Cone radius (m) at height z: waterline_diameter/2 - z / tan(cone_angle).
double pier_cone_radius(const PierParams& p, double z);

/// Radius of the (circular) pier surface at height z: neck, cone or shaft radius;
/// at z = cone_bottom_z the cone base radius (the widest); 0 above the top or below
/// the bottom. The mesh's polygon corners lie on this circle.
double pier_radius_at(const PierParams& p, double z);

/// Volume of the circular pier (cylinder + frustum + cylinder), m^3.
double pier_volume(const PierParams& p);

/// Exact volume of the polygonal pier make_pier builds (regular N-gon prisms and
/// frustum: area of an N-gon of circumradius r is N/2 r^2 sin(2 pi / N)), m^3.
double pier_polygonal_volume(const PierParams& p);

}  // namespace hs::mesh
