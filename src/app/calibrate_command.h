// `hybridsim calibrate SCENE_OR_MATERIAL.json`: virtual laboratory tests on the scene's lattice
// (src/calib/lab_tests.h) against the ice the scene describes (docs/engine.md, "Calibrated ice").
#pragma once

#include "app/run.h"

#include <cstdio>
#include <ostream>

namespace hs::app {

/// Runs the tension, three-point bending and floating-strip tests on the scene's lattice and
/// prints a table (target, measured, difference) and then one JSON object: E, nu,
/// tensile_strength, flexural_strength, characteristic_length, each {"target", "measured"}
/// (target null where the scene gives none), plus the springs and strengths used. The file is a
/// scene, or a partial one: a "material" (and optionally "bonds", "water", "gravity") with
/// "ice": {"thickness"} (name, time and the sheet's extent are filled in). Progress goes to
/// `progress`. Returns 0; throws hs::InputError.
int calibrate_command(const RunOptions& opt, std::ostream& out, std::FILE* progress);

}  // namespace hs::app
