// Planar wall: an infinite plane through `point` with unit normal `normal` pointing
// into the region where particles live, moving at constant `velocity`.
// Contact with a sphere of radius r at x uses the same contact law as particle pairs:
//   delta = r - (x - p).n,  contact normal = n (from the wall to the particle),
//   m_eff = m (the wall is immovable).
// The force on the wall (minus the sum of the forces it exerts) is tallied per step.
#pragma once

#include "common/types.h"

#include <string>

namespace hs::bonded {

struct PlaneWall {
  std::string name = "wall";
  Vec3 point = Vec3::Zero();
  Vec3 normal = Vec3::UnitZ();
  Vec3 velocity = Vec3::Zero();
  double friction = 0.3;   ///< Coulomb friction ice-wall
};

}  // namespace hs::bonded
