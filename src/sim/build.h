// Building a scene's engine: the bonded ice sheet floating at equilibrium, the walls and the
// structure (its mesh built once). sim::build_simulation (simulation.h) adds the blocks and
// the schedule on top; tests may call these directly.
#pragma once

#include "analysis/iso19906.h"
#include "bonded/engine.h"
#include "mesh/tri_mesh.h"
#include "scene/scene.h"

#include <memory>
#include <string>
#include <vector>

namespace hs::sim {

/// Engine settings of the scene (contact and bond laws, water, gravity, limits, dt).
bonded::EngineDef engine_def(const scene::Scene& s);

struct IceLayout {
  std::size_t layers = 0;               ///< level-ice layers
  std::size_t consolidated_layers = 0;  ///< 0 without a consolidated layer
  double bottom_z = 0.0;                ///< level ice bottom, m
  double top_z = 0.0;                   ///< level ice top, m
};
/// Layer counts and floating position of the ice sheet.
IceLayout ice_layout(const scene::Scene& s);

struct Built {
  std::unique_ptr<bonded::Engine> engine;
  std::size_t particles = 0;
  std::size_t bonds = 0;
  IceLayout layout;
  int structure = -1;                   ///< mesh wall index of the structure; -1 without one
  double structure_radius = 0.0;        ///< see structure_radius()
  std::vector<std::string> structure_parts;
  mesh::TriMesh structure_mesh;         ///< the structure's mesh as built (the engine keeps its own copy)
};
// ---- structure ----
/// The structure's mesh in its own frame (make_pier or the loaded file). InputError at
/// /structure/mesh if the file cannot be read.
mesh::TriMesh structure_mesh(const scene::Scene& s);
/// Horizontal radius of the structure's widest section (pier: the cone base radius; mesh:
/// half the larger horizontal bounding-box side), m.
double structure_radius(const scene::Scene& s, const mesh::TriMesh& m);
/// ISO 19906 inputs for the scene's ice and pier (docs/scene.md, "analysis"): thickness of
/// the consolidated layer if there is one, else of the level ice; E, nu, densities, g from the
/// scene; waterline diameter and cone angle from the pier; mu = structure friction.
/// InputError at /structure when the scene has no parametric pier.
analysis::IsoInputs iso_inputs(const scene::Scene& s, double rubble_height);

/// Builds the engine: bonded HCP ice floating at equilibrium, walls, the structure. With check_dt the time
/// step is checked against the critical step (InputError at "/time/dt" if too large).
Built build_engine(const scene::Scene& s, bool check_dt = true);

}  // namespace hs::sim
