#include "bridge/conversion_criteria.h"

#include "bridge/criterion_crushing.h"
#include "bridge/criterion_flexure.h"
#include "bridge/criterion_freeze_bond.h"

#include <array>

namespace hs::bridge {

std::span<const NamedCriterion> conversion_criteria() {
  // One line per criterion; the order is kFreezeBondCriterion, kFlexureCriterion,
  // kCrushingCriterion, then any others.
  static const std::array list{
      NamedCriterion{"freeze_bond", &freeze_bond_utilisation},
      NamedCriterion{"flexure", &flexure_utilisation},
      NamedCriterion{"crushing", &crushing_utilisation},
  };
  return list;
}

ConversionDecision evaluate_criteria(const BlockLoads& block, const ConversionStrengths& strengths) {
  ConversionDecision d;
  const auto criteria = conversion_criteria();
  for (std::size_t c = 0; c < criteria.size(); ++c) {
    const double u = criteria[c].utilisation(block, strengths);
    if (u > d.utilisation) {
      d.utilisation = u;
      d.governing = static_cast<int>(c);
    }
  }
  return d;
}

}  // namespace hs::bridge
