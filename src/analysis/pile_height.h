// Rubble pile height probe: the highest point of ice over the upstream half of the
// cone, measured above the waterline (m). "Over the cone" means a particle whose
// horizontal distance from the pier axis is at most the cone's largest radius plus one
// particle diameter; "upstream" means on the side the ice comes from, i.e. the side the
// structure moves towards: (x - axis) . drift_dir > 0 with drift_dir the horizontal
// direction of the structure's velocity relative to the ice. Returns 0 when no ice is
// above the waterline there.
#pragma once

#include "common/types.h"

#include <cstddef>

namespace hs::analysis {

struct PileProbe {
  Vec3 axis_point = Vec3::Zero();      ///< a point on the vertical pier axis (world), m
  Vec3 upstream = Vec3::UnitX();       ///< horizontal unit vector towards the incoming ice
  double reach = 10.0;                 ///< horizontal radius of the probed region, m
  double water_level = 0.0;            ///< m
};

/// `x` positions, `r` radii of `n` particles.
inline double pile_height(const PileProbe& p, const Vec3* x, const double* r, std::size_t n) {
  double top = p.water_level;
  const Vec3 up = Vec3(p.upstream.x(), p.upstream.y(), 0.0).normalized();
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 d = x[i] - p.axis_point;
    const double dx = d.x(), dy = d.y();
    if (dx * up.x() + dy * up.y() <= 0.0) continue;
    if (dx * dx + dy * dy > p.reach * p.reach) continue;
    top = std::max(top, x[i].z() + r[i]);
  }
  return top - p.water_level;
}

}  // namespace hs::analysis
