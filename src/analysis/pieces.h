// Pieces of ice at the end of a run: the connected components of the particles over intact
// bonds, with the size (particles) and horizontal extent of each.
#pragma once

#include "common/types.h"

#include <cstdint>
#include <vector>

namespace hs::analysis {

struct PieceParticle {
  GlobalId gid = 0;
  double x = 0.0, y = 0.0, r = 0.0;  ///< horizontal centre and radius, m
};
struct PieceBond {
  GlobalId a = 0, b = 0;  ///< global ids of the bonded particles
};

struct Pieces {
  std::vector<std::int64_t> size;  ///< particles per piece, descending
  std::vector<double> extent;      ///< m, max horizontal extent of each piece (same order)
};

/// The pieces of `particles` joined by `bonds` (bonds naming an absent particle are ignored).
/// The particles are taken in global-id order, so the result does not depend on the input
/// order; pieces of equal size keep the order of their smallest global id. A piece's extent
/// is the larger side of its x-y bounding box, spheres included.
Pieces find_pieces(std::vector<PieceParticle> particles, const std::vector<PieceBond>& bonds);

}  // namespace hs::analysis
