// Rubble pile height probe: the highest point of ice over the upstream half of the
// cone, measured above the waterline (m). "Over the cone" means a particle whose
// horizontal distance from the pier axis is at most the cone's largest radius plus one
// particle diameter; "upstream" means on the side the ice comes from, i.e. the side the
// structure moves towards: (x - axis) . drift_dir > 0 with drift_dir the horizontal
// direction of the structure's velocity relative to the ice. Returns 0 when no ice is
// above the waterline there.
#pragma once

#include "common/types.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

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

// ISO-consistent pile height: ISO 19906 takes a pile of one height h_r across the whole
// waterline width w of the cone. The DEM pile is highest at the cone's upstream face and lower
// at its sides, so its single highest particle overstates h_r. The band probe measures the
// pile's crest across the width and averages it:
//   frame: u = (x - axis) . upstream (horizontal, towards the incoming ice),
//          v = (x - axis) . (z x upstream) (horizontal, across);
//   band:  0 < u <= reach (the upstream half: the cone face and the pile in front of it),
//          |v| <= half_width (the waterline radius w/2);
//   bins:  the band's width is cut into `bins` equal strips across v; a particle belongs to
//          the strip of its centre;
//   crest: per strip, the highest ice above the waterline, max(z + r) - water_level over the
//          strip's particles, 0 when none is above the water;
//   mean:  the plain average of the crests over all strips (empty strips count 0).
// The crests are a max per strip, so ranks combine theirs with an element-wise max.
struct PileBand {
  Vec3 axis_point = Vec3::Zero();  ///< a point on the vertical pier axis (world), m
  Vec3 upstream = Vec3::UnitX();   ///< horizontal unit vector towards the incoming ice
  double half_width = 7.0;         ///< w/2, m
  double reach = 10.0;             ///< u extent from the axis, m (cone radius + distance ahead)
  double water_level = 0.0;        ///< m
  std::size_t bins = 1;            ///< strips across the width, >= 1
};

/// Per-strip crest heights (size p.bins, m above the water level, >= 0) of `n` particles.
inline std::vector<double> pile_crests(const PileBand& p, const Vec3* x, const double* r, std::size_t n) {
  const std::size_t bins = std::max<std::size_t>(p.bins, 1);
  std::vector<double> crest(bins, 0.0);
  const Vec3 up = Vec3(p.upstream.x(), p.upstream.y(), 0.0).normalized();
  const double ax = up.x(), ay = up.y();  // across = (-ay, ax)
  const double strip = 2.0 * p.half_width / static_cast<double>(bins);
  for (std::size_t i = 0; i < n; ++i) {
    const double dx = x[i].x() - p.axis_point.x(), dy = x[i].y() - p.axis_point.y();
    const double u = dx * ax + dy * ay, v = -dx * ay + dy * ax;
    if (u <= 0.0 || u > p.reach || std::abs(v) > p.half_width) continue;
    const auto k = std::min(bins - 1, static_cast<std::size_t>(std::floor((v + p.half_width) / strip)));
    crest[k] = std::max(crest[k], x[i].z() + r[i] - p.water_level);
  }
  return crest;
}

/// Mean of the crests (m).
inline double mean_crest(const std::vector<double>& crest) {
  double sum = 0.0;
  for (const double c : crest) sum += c;
  return crest.empty() ? 0.0 : sum / static_cast<double>(crest.size());
}

}  // namespace hs::analysis
