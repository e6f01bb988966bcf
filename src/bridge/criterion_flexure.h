// Conversion criterion: bending of the block as a free beam under all its loads, balanced by
// d'Alembert inertia (flexure_estimate, block_stress.h; docs/bridge.md, "Block stress estimates").
// u_b = the largest tensile fibre stress / flexural strength.
#pragma once

#include "bridge/conversion_criteria.h"

namespace hs::bridge {

inline double flexure_utilisation(const BlockLoads& b, const ConversionStrengths& s) {
  return flexure_estimate(b.box, b.loads, s.flexural_strength).utilisation;
}

}  // namespace hs::bridge
