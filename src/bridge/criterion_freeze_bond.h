// Conversion criterion: the freeze bonds holding the block (docs/bridge.md, "Block stress
// estimates"). u_f = the largest load / strength over its joints to other blocks
// (freeze_bond_estimate, block_stress.h) and its block-particle freeze bonds (their utilisation
// as BlockParticleBonds records it, tension or shear).
#pragma once

#include "bridge/conversion_criteria.h"

#include <algorithm>

namespace hs::bridge {

inline double freeze_bond_utilisation(const BlockLoads& b, const ConversionStrengths& s) {
  const double u_joints = freeze_bond_estimate(b.joints, s.freeze).utilisation;
  const double u_bonds = std::max(b.bond_u_tension, b.bond_u_shear);
  return u_bonds > u_joints ? u_bonds : u_joints;  // a block-particle bond governs only when larger
}

}  // namespace hs::bridge
