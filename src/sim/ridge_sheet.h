// The run's particle sheet as the ridge generator sees it, and the check that a ridge file
// was made with the run's ice (docs/ridge.md, "Floating plates" and "Generation record").
//
// sheet_geometry is the one place that says where the run puts its sheet: build_engine
// fills its lattice from it, `hybridsim ridge <run scene>` settles the keel under plates of
// its contact surfaces, and a run refuses a ridge file whose recorded sheet differs.
#pragma once

#include "ridge/ridge_data.h"
#include "scene/scene.h"

#include <cstddef>
#include <nlohmann/json.hpp>
#include <string>

namespace hs::sim {

/// The sheet as build_engine lays it, floating at rest. One HCP lattice: level ice `layers`
/// layers of spacing c from lattice-box bottom `level_box_bottom` (draft h rho_i / rho_w of
/// h = layers c); with a consolidated layer the box is `total_layers` thick and hangs
/// `below` whole layers lower (its own draft, rounded to whole layers). Contact surfaces
/// (what a block touches): the outer layers' centres +- D/2.
struct SheetGeometry {
  double D = 0.0, c = 0.0;
  std::size_t layers = 0, total_layers = 0, below = 0;
  double level_box_bottom = 0.0;  ///< z, m
  double box_bottom = 0.0;        ///< z of the whole lattice box (consolidated layer's), m
  double level_top = 0.0, level_underside = 0.0;  ///< contact surfaces, level ice, m
  double layer_top = 0.0, layer_underside = 0.0;  ///< consolidated layer (= level ice without one), m
};
SheetGeometry sheet_geometry(const scene::Scene& s);

/// The ice a ridge must be generated with for this run: `def` takes the block density
/// (blocks.density or material.density), the ice-ice friction (blocks.friction or
/// material.friction) as the settle friction, water density, level-ice thickness, the
/// consolidated layer (thickness and width; none: width 0) and the floating sheet of
/// sheet_geometry. Call it after reading the ridge section.
void apply_run_scene(rigid::RidgeDef& def, const scene::Scene& s);

/// Whether the scene file itself sets the value at the JSON pointer (not a default).
bool scene_sets(const scene::Scene& s, const char* pointer);

/// Throws hs::InputError("/blocks/ridge_file", ...) unless the ridge file `path` was generated
/// with this scene's ice: every mismatching field named with the scene's and the file's value,
/// and the fix (`hybridsim ridge <scene>`).
void check_ridge_generation(const rigid::RidgeResult& r, const scene::Scene& s, const std::string& path);

/// Throws hs::InputError("/blocks/ridge_file", ...) unless the ridge file was generated from the
/// scene's own "ridge" section as it reads now (run_scene_ridge_def): every differing field of
/// the definition named with both values (the name aside), and the fix. Called by
/// check_ridge_generation when the scene has a "ridge" section.
void check_ridge_definition(const rigid::RidgeResult& r, const scene::Scene& s, const std::string& path);

/// The ridge definition a "ridge" value gives: the object, or the JSON file a string names
/// (relative to `base_dir`; errors inside it name the file). `ridge_base`: the directory the
/// definition's own relative paths (keel_profile_csv) are resolved against.
rigid::RidgeDef ridge_def_from_section(const nlohmann::json& v, const std::string& base_dir,
                                       std::string* ridge_base = nullptr);

/// A run scene's ridge: its "ridge" section with the scene's ice (apply_run_scene) and, if it
/// has none, the scene's name. A value the section sets itself must agree with the scene's
/// (InputError naming both). `where`: the file the section names ("" inline).
rigid::RidgeDef run_scene_ridge_def(const scene::Scene& s, std::string* ridge_base = nullptr,
                                    std::string* where = nullptr);

/// The sheet's lift at ridge-frame x: the lift of the plate over x, ramped linearly over
/// +-min(1 m, a quarter plate) across plate boundaries; 0 for a ridge without floating plates.
double sheet_lift(const rigid::RidgeResult& r, double x);

}  // namespace hs::sim
