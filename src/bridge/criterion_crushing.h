// Conversion criterion: local crushing of the block's face under one particle (docs/bridge.md,
// "Block stress estimates"). A rigid block cannot crush, and a particle contact spring has no
// strength: without this criterion a particle pressed against a block by more than the ice can
// carry goes on sinking into it, where the same ice as particles would have crushed (its lattice
// bonds break in compression at bonds.compressive_strength_ratio x their tensile strength).
//   u_c = max over its particle contacts |F| / F_c,   F_c = sigma_cc x pi R_b^2
// (sigma_cc the lattice bond's compressive strength, R_b the bond radius: the force that crushes
// a bond of the lattice the block would become). |F| includes the contact's friction, at most
// sqrt(1 + mu^2) times its normal part. u_c = 0 when F_c is infinite (bonds that do not crush).
#pragma once

#include "bridge/conversion_criteria.h"
#include "common/error.h"

#include <cmath>
#include <string>

namespace hs::bridge {

inline double crushing_utilisation(const BlockLoads& b, const ConversionStrengths& s) {
  if (!(s.contact_crushing_force > 0.0))
    throw InputError("contact_crushing_force", "must be positive (N; infinite = no crushing criterion), got " +
                                                   std::to_string(s.contact_crushing_force));
  if (std::isinf(s.contact_crushing_force)) return 0.0;
  return b.particle_contact_force / s.contact_crushing_force;
}

}  // namespace hs::bridge
