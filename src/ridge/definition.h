// The definition's geometry and checks (docs/ridge.md): the target keel and sail envelopes, the
// ice's draft and freeboard, a measured keel profile from CSV, the floating plates' density and
// the validation of a RidgeDef. Plain functions of ridge/ridge_data.h (no Bullet, no JSON);
// used by the generator, by the JSON reader (ridge/ridge_json.h) and by the run's checks.
#pragma once

#include "ridge/ridge_data.h"

#include <string>
#include <vector>

namespace hs::rigid {

/// Target keel depth below the waterline at x (0 where there is no keel).
double keel_target_depth(const RidgeDef& def, double x);
/// Target sail height above the waterline at x (0 where there is no sail).
double sail_target_height(const RidgeDef& def, double x);
/// Draft (z of the underside = -draft) and freeboard of the ice at x (at rest; with a
/// floating sheet: its contact surfaces).
double ice_draft(const RidgeDef& def, double x);
double ice_freeboard(const RidgeDef& def, double x);

/// Half widths of the target keel and sail (the keel: the measured profile's reach when there
/// is one; 0: no sail), m.
double keel_half_width(const RidgeDef& d);
double sail_half_width(const RidgeDef& d);
/// Half width of the consolidated layer's contact surface (the run's particles with a floating
/// sheet), m.
double layer_half_width(const RidgeDef& d);

/// Reads a keel profile CSV: two columns position_m, depth_m (comma separated, an optional
/// header line, '#' comments and blank lines allowed), positions strictly increasing,
/// depths >= 0. Throws hs::InputError(path, "line N: ...") on any malformed line.
std::vector<ProfilePoint> load_profile_csv(const std::string& path);

/// Density that makes a plate of contact surfaces [underside, top] float with them there:
/// rho_w (-underside) / (top - underside). Throws hs::InputError unless top > 0 > underside.
double plate_density(double top, double underside, double water_density);

/// Ranges and cross-field rules of a definition; throws hs::InputError naming json_path + "/"
/// + the key (json_path: where the definition came from, e.g. "/ridge").
void validate_ridge_def(const RidgeDef& d, const std::string& json_path);

}  // namespace hs::rigid
