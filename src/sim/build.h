// Building a scene's engine: the bonded ice sheet floating at equilibrium, the walls and the
// structure (its mesh built once). sim::build_simulation (simulation.h) adds the blocks and
// the schedule on top; tests may call these directly.
#pragma once

#include "analysis/iso19906.h"
#include "bonded/engine.h"
#include "mesh/tri_mesh.h"
#include "scene/scene.h"
#include "sim/blocks.h"
#include "sim/calibrated_ice.h"

#include <memory>
#include <string>
#include <vector>

namespace hs::sim {

/// Engine settings of the scene (contact and bond laws, water, gravity, limits, dt); the springs
/// and bond strengths from `ice` (calibrate_ice(s), computed here when not given).
bonded::EngineDef engine_def(const scene::Scene& s, const CalibratedIce& ice);
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
  double lattice_thickness = 0.0;       ///< m, lattice_mean_thickness of the sheet as built (ISO input)
  /// The ice as the lattice has it (springs, E, nu, flexural/tensile and bond strengths and where
  /// they came from): calibrate_ice(scene), what engine_def used; for ISO and the conversion.
  CalibratedIce calibrated;
  /// The scene's ridge file as read (and checked against the scene) for the sheet's lift; null
  /// without one. block_setup takes it, so a build reads the file once.
  std::shared_ptr<const rigid::RidgeResult> ridge;
};
// ---- structure ----
/// The structure's mesh in its own frame (make_pier or the loaded file). InputError at
/// /structure/mesh if the file cannot be read.
mesh::TriMesh structure_mesh(const scene::Scene& s);
/// Horizontal radius of the structure's widest section (pier: the cone base radius; mesh:
/// half the larger horizontal bounding-box side), m.
double structure_radius(const scene::Scene& s, const mesh::TriMesh& m);
/// ISO 19906 inputs for the scene's ice and pier without a run (`hybridsim iso SCENE`):
/// assemble_iso_inputs (sim/iso_inputs.h) with only the rubble height given, so the nominal
/// thickness of the consolidated layer if there is one, else of the level ice.
/// InputError at /structure when the scene has no parametric pier.
analysis::IsoInputs iso_inputs(const scene::Scene& s, double rubble_height);

// ---- memory guard ----
/// Rough resident memory of the engine for n particles, b bonds and w plane walls, bytes (the
/// figure `hybridsim check` prints as "estimated memory").
double engine_memory_bytes(double particles, double bonds, std::size_t walls);

/// What a scene will allocate, estimated from its definition before anything is built.
struct MemoryEstimate {
  double particles = 0;  ///< ice extent / D: length x width / (D^2 sqrt(3)/2) per layer x layers
  double bonds = 0;      ///< ~6 per particle (12 HCP neighbours, each bond shared)
  double bytes = 0;      ///< engine_memory_bytes of the above, plus the lattice built once, plus blocks
  // Rigid blocks (add_blocks; zero until the blocks are read):
  double blocks = 0;           ///< rigid bodies
  double joints = 0;           ///< freeze joints between blocks and to the ice
  double block_particles = 0;  ///< particles the blocks can become: sum of volumes / HCP cell volume
  double block_bytes = 0;      ///< the part of `bytes` the blocks add
};
MemoryEstimate memory_estimate(const scene::Scene& s);

/// Bytes one rigid block and one freeze joint hold in the Bullet world and the hybrid system
/// (body, box shape, broadphase proxy, contact manifolds; a 6-dof spring constraint). Measured:
/// `hybridsim check` of scenes/ridge_keel_8m_cone.json keeping all 2,970 blocks and 6,680 joints
/// of its ridge file (conversion "never") holds 23.7 MB more than keeping 3 blocks and no joints;
/// these figures give 25.8 MB (a run adds contact manifolds, ~1 kB per touching pair).
inline constexpr double kBytesPerBlock = 6000.0;
inline constexpr double kBytesPerJoint = 1500.0;

/// Adds the blocks of `b` to `est`: the rigid world, and, unless conversion is off, the particles
/// (and their ~6 bonds each) every block would become if converted (an upper bound: the pier may
/// reach every block in the conversion region). `walls` as for engine_memory_bytes.
void add_blocks(MemoryEstimate& est, const BlockSetup& b, double particle_diameter, std::size_t walls);

/// MemAvailable of /proc/meminfo, bytes; a negative number when it cannot be read.
double available_memory_bytes();

/// InputError when `ranks` copies of the estimate (every rank builds the whole scene before
/// keeping its share) exceed `available` bytes: at /ice, naming the fields that set the size
/// (/ice/length, /ice/width, /ice/thickness, /material/particle_diameter), or at /blocks when the
/// blocks need more than the ice (naming /blocks/ridge_file, /blocks/keep_x, /blocks/keep_y and
/// /blocks/conversion); the estimate, the available memory and --ignore-memory-limit. Nothing
/// happens when `available` < 0 (unknown).
void check_memory(const scene::Scene& s, const MemoryEstimate& est, double available, int ranks = 1);

// ---- initial overlap ----
/// Particles of the built sheet that start inside the structure or overlapping its surface.
struct StructureOverlap {
  std::size_t particles = 0;      ///< overlapping by more than kInitialOverlapTolerance x r, or inside
  std::size_t inside = 0;         ///< of which the centre is inside the (closed) mesh
  std::size_t deep = 0;           ///< of which the overlap reaches stability.max_overlap_ratio x r
  double max_overlap = 0.0;       ///< m, deepest surface overlap (inside: not measured)
  double max_overlap_ratio = 0.0; ///< the same / r
  Vec3 first = Vec3::Zero();      ///< world position of the deepest such particle (or one inside)
};
/// Surface overlaps up to this fraction of the radius count as touching (a sheet placed
/// exactly against the structure).
inline constexpr double kInitialOverlapTolerance = 1e-3;
/// Tests every particle against the structure's mesh at its position: the sphere-mesh contact
/// query (sphere_mesh_contact.h) for overlaps, a winding-number test for centres inside a
/// closed mesh (the contact query does not see a centre deeper than r). Zero without a structure.
StructureOverlap structure_overlap(const Built& b, const scene::Scene& s);
/// InputError at /structure/position when a particle's centre is inside the structure or its
/// overlap reaches stability.max_overlap_ratio x r (what the run would stop on as unstable):
/// their number, the deepest overlap, where, the sheet's extent and a position that clears it.
/// Smaller overlaps (> kInitialOverlapTolerance r) return a warning (else "").
std::string check_structure_overlap(const Built& b, const scene::Scene& s);

/// Builds the engine: bonded HCP ice floating at equilibrium, walls, the structure. With check_dt the time
/// step is checked against the critical step (InputError at "/time/dt" if too large). `ice`:
/// calibrate_ice(s), computed once for the run (Built::calibrated keeps it); computed here when
/// not given.
Built build_engine(const scene::Scene& s, const CalibratedIce& ice, bool check_dt = true);
Built build_engine(const scene::Scene& s, bool check_dt = true);

}  // namespace hs::sim
