// Conversion criteria (docs/bridge.md, "Block stress estimates" and "Adding a conversion
// criterion"): each criterion is a pure function of one block's loads that returns its
// utilisation u (load / capacity; 1 = the capacity is reached). A block in the conversion region
// converts when max over the criteria of u x safety_factor >= 1 (converts(), block_stress.h).
// Gathering the loads (under MPI, from every rank onto the deciding rank) is the hybrid system's
// business (HybridSystem::apply_policy); nothing here knows about ranks, Bullet or particles.
//
// Adding a criterion: one header criterion_<name>.h with its utilisation function, and one line
// in conversion_criteria() (conversion_criteria.cpp).
#pragma once

#include "bridge/block_stress.h"

#include <cmath>
#include <cstddef>
#include <span>
#include <vector>

namespace hs::bridge {

/// What the criteria see of one block at a rigid step.
struct BlockLoads {
  BlockBox box;                           ///< its shape and pose
  std::vector<FreezeJointSample> joints;  ///< its freeze joints to other blocks (RigidWorld)
  /// Every contact and bond force on it, in this order: rigid contacts (blocks, structure),
  /// particle contacts, block-particle freeze bonds. No gravity or buoyancy (PointLoad).
  std::vector<PointLoad> loads;
  double bond_u_tension = 0.0;  ///< largest stress / strength of its block-particle freeze bonds, tension
  double bond_u_shear = 0.0;    ///< ... shear
  /// N: the largest force (magnitude) that one particle contact puts on it (crushing criterion).
  double particle_contact_force = 0.0;
};

/// The capacities the criteria compare the loads with.
struct ConversionStrengths {
  FreezeBondStrength freeze;         ///< of the joints between blocks
  double flexural_strength = 0.5e6;  ///< sigma_f, Pa
  /// N: the force of one particle contact at which the block's face crushes: the force that
  /// crushes a lattice bond of the particles it would become (compressive strength x bond area).
  /// Infinite (the default, and when the lattice's bonds do not break in compression): no
  /// crushing criterion.
  double contact_crushing_force = INFINITY;
};

/// u >= 0 of one block; throws hs::InputError for impossible input (block_stress.h).
using ConversionCriterion = double (*)(const BlockLoads&, const ConversionStrengths&);

struct NamedCriterion {
  const char* name;  ///< for reports ("freeze_bond", "flexure")
  ConversionCriterion utilisation;
};

/// The criteria in order: a tie goes to the earlier one.
std::span<const NamedCriterion> conversion_criteria();
/// Positions of the built-in criteria in conversion_criteria() (HybridReport's counters).
inline constexpr std::size_t kFreezeBondCriterion = 0, kFlexureCriterion = 1, kCrushingCriterion = 2;

struct ConversionDecision {
  double utilisation = 0.0;  ///< max over the criteria
  int governing = -1;        ///< index of the criterion giving it; -1 when every u is 0
};

/// Every criterion on one block; the largest u governs (ties: the earlier criterion).
ConversionDecision evaluate_criteria(const BlockLoads& block, const ConversionStrengths& strengths);

}  // namespace hs::bridge
