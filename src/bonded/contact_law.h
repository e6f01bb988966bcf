// The one dispatch point of the particle contact laws (docs/engine.md, "Adding a contact law").
//
// A law is a struct in its own file (contact_<law>.h) with
//   static constexpr ContactModel kModel;                  its identity (src/common/contact_model.h)
//   template <class Def> static Law from_def(const Def&);  its parameters from the EngineDef
//   Law with_friction(double mu) const;                    the same law with another Coulomb coefficient
//   ContactResult force(delta, r_star, n, vn, vt, m_eff, dt, xi&) const;   force on j (contact_linear.h)
//   double energy(delta, r_star, xi) const;                elastic energy stored in the contact, J
//   ContactStiffness time_step_stiffness(double r_min) const;   springs for the time-step check
//   double reference_stiffness(double E, double D) const;  one stiffness that sizes other steps
// and one line in ContactLaws below. with_contact_law(def, f) calls f(law) with the law that
// def.contact_model names; f is a generic lambda, so every law gets its own compiled copy of
// the loop it wraps (no virtual call per contact).
#pragma once

#include "common/contact_model.h"
#include "contact_hertz.h"
#include "contact_linear.h"

#include <cstddef>

namespace hs::bonded {

using hs::ContactModel;  // bonded::ContactModel, as before it moved to src/common

template <class... Laws>
struct ContactLawList {};

/// The registered laws: one entry per law.
using ContactLaws = ContactLawList<LinearLaw, HertzLaw>;

namespace detail {
// Always inlined: the dispatch must cost the call sites nothing.
template <class Def, class F, class Law, class... Rest>
[[gnu::always_inline]] inline decltype(auto) dispatch_contact_law(const Def& def, F& f, ContactLawList<Law, Rest...>) {
  if constexpr (sizeof...(Rest) == 0) {
    return f(Law::from_def(def));  // the last one: every model has a law (static_assert below)
  } else {
    if (def.contact_model == Law::kModel) return f(Law::from_def(def));
    return dispatch_contact_law(def, f, ContactLawList<Rest...>{});
  }
}

template <class... Laws>
constexpr bool registers_every_model(ContactLawList<Laws...>) {
  // Each ContactModel exactly once, in the enum's order.
  std::size_t k = 0;
  return sizeof...(Laws) == kContactModelNames.size() && ((static_cast<std::size_t>(Laws::kModel) == k++) && ...);
}
}  // namespace detail

static_assert(detail::registers_every_model(ContactLaws{}),
              "ContactLaws must list one law per ContactModel, in the enum's order (src/common/contact_model.h)");

/// f(law) for the law that def.contact_model names (def: an EngineDef).
template <class Def, class F>
[[gnu::always_inline]] inline decltype(auto) with_contact_law(const Def& def, F&& f) {
  return detail::dispatch_contact_law(def, f, ContactLaws{});
}

}  // namespace hs::bonded
