// The particle contact laws by name: which law a material uses (MaterialDef, EngineDef). The laws
// themselves live in src/bonded (contact_<law>.h, dispatched in contact_law.h); their identity
// lives here so that a scene can name a law without including the particle engine.
// Adding a law: docs/engine.md, "Adding a contact law".
#pragma once

#include <array>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace hs {

/// One entry per law, in the order of kContactModelNames.
enum class ContactModel { LinearSpringDashpot, HertzMindlin };

/// The scene's words for the laws (material.contact_model), indexed by ContactModel.
inline constexpr auto kContactModelNames = std::to_array<std::string_view>({"linear", "hertz"});

inline std::string contact_model_name(ContactModel m) {
  return std::string(kContactModelNames.at(static_cast<std::size_t>(m)));
}

inline std::vector<std::string> contact_model_names() {
  return {kContactModelNames.begin(), kContactModelNames.end()};
}

/// The law a scene word names; throws std::invalid_argument for a word not in kContactModelNames
/// (a scene reader checks the word first, with its JSON path).
inline ContactModel contact_model_from_name(std::string_view name) {
  for (std::size_t k = 0; k < kContactModelNames.size(); ++k)
    if (kContactModelNames[k] == name) return static_cast<ContactModel>(k);
  throw std::invalid_argument("unknown contact model \"" + std::string(name) + "\"");
}

}  // namespace hs
