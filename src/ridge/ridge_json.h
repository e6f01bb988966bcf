// A ridge's JSON: the definition read from a scene (strict, with the shared reader src/json) and
// written back, the generation record and the report of a ridge file (docs/ridge.md). The data
// itself (ridge/ridge_data.h) knows no JSON.
#pragma once

#include "ridge/ridge_data.h"

#include <nlohmann/json.hpp>

#include <string>

namespace hs::rigid {

/// RidgeDef from the JSON object at json_path_prefix (e.g. "/ridge"). Strict: wrong types,
/// out-of-range values and unknown keys (with a did-you-mean hint) throw hs::InputError
/// naming the JSON path. A relative keel_profile_csv is resolved against base_dir.
RidgeDef ridge_def_from_json(const nlohmann::json& j, const std::string& json_path_prefix,
                             const std::string& base_dir = "");
/// The full definition as JSON (every key; ridge_def_from_json reads it back exactly).
nlohmann::json ridge_def_to_json(const RidgeDef& def);
/// What the ridge was made with (the file's `generation` attribute, docs/ridge.md): ice and
/// water density, friction, level ice and consolidated layer, the sheet (fixed boxes or the
/// run's floating sheet: per part top/underside z, particle diameter) and every plate's
/// x range, part and final lift.
nlohmann::json ridge_generation_json(const RidgeResult& r);
/// Summary: counts, porosity, keel depth / sail height target vs achieved, settle info.
nlohmann::json ridge_report(const RidgeResult& r);

}  // namespace hs::rigid
