// Scenes: the JSON file a user writes, read into plain definition structs.
//
// Flow:  text --parse_json_text--> json --apply_override (--set)--> json
//            --parse_scene (validates everything, once)--> Scene
// A Scene is definitions only; sim::build_simulation (src/sim) builds the engine, the structure
// and the blocks from it.
// Every problem is an hs::InputError whose path is the JSON pointer of the offending value
// ("/ice/thickness") and whose message gives the bad value, what is allowed and the fix.
// Unknown keys are errors with a did-you-mean suggestion. The reading is the shared JSON
// reader's (src/json/reader.h); parse_scene has one function per section. Fields, units
// and defaults: docs/scene.md; JSON Schema for editors: docs/scene.schema.json.
#pragma once

#include "common/contact_model.h"
#include "common/types.h"
#include "json/reader.h"
#include "mesh/pier.h"

#include <nlohmann/json.hpp>

#include <array>
#include <string>
#include <vector>

namespace hs::scene {

struct TimeDef {
  double duration = 0.0;           ///< simulated time, s (required)
  double dt = 0.0;                 ///< s; 0 = paper Eq. 2 with dt_alpha
  double dt_alpha = 0.1;           ///< alpha in dt = alpha D sqrt(rho/E)
  double output_interval = 0.01;   ///< s between /series rows
  double snapshot_interval = 0.0;  ///< s between particle snapshots; 0 = none
  /// Simulated seconds between checkpoints (<output>.ckpt.h5, docs/output.md); 0 = none (a run
  /// stopped by SIGINT/SIGTERM writes one anyway).
  double checkpoint_interval = 0.0;
};

/// Most DEM steps a run may take (time.duration / dt). Beyond it even a thousand-particle sheet
/// runs for months on one core, and the step count no longer fits the schedule's counters
/// exactly: such a dt (1e-300) is a typing error, refused at /time/dt.
inline constexpr double kMaxSteps = 1e10;

/// InputError at /time/dt, naming /time/duration, when duration / dt exceeds kMaxSteps.
/// `dt_origin` says where dt came from ("" for time.dt itself, or e.g. " (Eq. 2: ...)").
void check_step_count(const TimeDef& t, double dt, const std::string& dt_origin = "");

/// How the lattice's springs and bond strengths follow from the material (sim/calibrated_ice.h).
enum class StiffnessModel { Calibrated, PaperEq1 };

struct MaterialDef {
  StiffnessModel stiffness_model = StiffnessModel::Calibrated;  ///< "calibrated" (default) | "paper_eq1"
  double density = 920.0;          ///< kg/m^3
  double youngs_modulus = 1e9;     ///< Pa
  double poisson_ratio = 0.3;
  double particle_diameter = 0.5;  ///< D, m
  double restitution = 0.3;        ///< contacts
  double friction = 0.3;           ///< particle-particle Coulomb coefficient
  ContactModel contact_model = ContactModel::LinearSpringDashpot;  ///< the law (common/contact_model.h)
  double stiffness = 0.0;          ///< k_n = k_t, N/m; 0 = paper Eq. 1, pi E D / 12 (paper_eq1 only)
  double flexural_strength = 0.5e6;  ///< Pa, target of "calibrated" (3-point bending, as ISO uses it)
  double tensile_strength = 0.0;   ///< Pa, target reported by `hybridsim calibrate`; 0 = none
  /// The stiffness actually used (Eq. 1 when `stiffness` is 0).
  double effective_stiffness() const;
};

struct BondsDef {
  double tensile_strength = 0.6e6;         ///< Pa
  double shear_strength = 0.6e6;           ///< Pa
  double damping_ratio = 0.1;
  double radius_ratio = 1.0;               ///< bond radius / particle radius
  double freeze_tensile_strength = 2e4;    ///< Pa (freeze bonds between blocks)
  double freeze_shear_strength = 2e4;      ///< Pa
  double freeze_strength_fraction = 0.0;   ///< > 0: freeze strengths = this x the lattice bond's
  /// Lattice bonds also break when their largest compressive stress passes this multiple of their
  /// tensile strength (ParallelBondParams::sigma_cc); infinite (absent): never in compression.
  double compressive_strength_ratio = INFINITY;
  /// A bond broken with its particles deeper than crushed_set_depth x r: "set" (the contact
  /// pushes back only beyond that depth, bonded::EngineDef::crushed_set) or "elastic".
  std::string crushed_contact = "set";
  double crushed_set_depth = 0.25;  ///< h / smaller radius (bonded::EngineDef::crushed_set_depth)
  /// Relative standard deviation of each lattice bond's strengths, drawn per bond from a lognormal
  /// of mean 1 under Scene::seed (bonded/bond_strength_spread.h); 0 = every bond alike.
  double strength_spread = 0.0;
  bool strength_given = false;             ///< tensile_strength or shear_strength was in the scene
};

struct WaterDef {
  bool enabled = true;
  double level = 0.0;              ///< z of the surface, m
  double density = 1025.0;         ///< kg/m^3
  /// Drag on rigid blocks and particles alike (docs/engine.md, "Water drag"): the face law of
  /// src/rigid/box_water.h on each block's wetted faces and on each particle's exposed cell faces.
  double linear_drag_per_area = 1000.0;  ///< c_lin, Pa s/m (N s/m per m^2 of wetted surface)
  double drag_coefficient = 1.0;         ///< C_d, quadratic drag on leading faces
  Vec3 current = Vec3::Zero();     ///< m/s
};

struct ConsolidatedLayerDef {
  double thickness = 0.0;          ///< m (> ice thickness)
  double width = 0.0;              ///< m, extent along x of the band (the band runs along y)
  double center_x = 0.0;           ///< m, x of the band's centre line
};

struct IceDef {
  std::string type = "level_ice";
  double thickness = 0.0;          ///< m (required)
  double length = 0.0;             ///< m along x (required)
  double width = 0.0;              ///< m along y (required)
  std::array<double, 2> origin{0.0, 0.0};  ///< (x, y) of the -x,-y corner, m
  bool has_consolidated_layer = false;
  ConsolidatedLayerDef consolidated_layer;
};

struct WallDef {
  std::string name;
  Vec3 point = Vec3::Zero();       ///< m
  Vec3 normal = Vec3::UnitZ();     ///< unit (normalised at load), into the particle side
  Vec3 velocity = Vec3::Zero();    ///< m/s
  double friction = 0.1;           ///< ice-wall Coulomb coefficient
};

/// The structure (pier) pushed through the ice: a parametric pier or a mesh file, moving at
/// constant velocity. Loads on it are tallied per mesh part.
struct StructureDef {
  std::string name = "pier";
  std::string type = "pier";           ///< "pier" (parametric, mesh::make_pier) or "mesh" (STL/OBJ file)
  mesh::PierParams pier;               ///< type "pier"
  std::string mesh;                    ///< type "mesh": the path as written in the scene
  std::string mesh_path;               ///< ... resolved against the scene file's directory
  Vec3 position = Vec3::Zero();        ///< world position of the mesh origin (pier: axis at its waterline), m
  Vec3 velocity{0.4, 0.0, 0.0};        ///< m/s; the structure moves into the ice
  double friction = 0.1;               ///< ice-structure Coulomb coefficient
};

/// Inputs of the ISO 19906 estimate that the scene's ice and structure do not give.
struct AnalysisDef {
  double flexural_strength = 0.5e6;        ///< sigma_f, Pa
  double rubble_porosity = 0.3;            ///< -
  double rubble_slope_deg = 0.0;           ///< deg; 0 = 0.8 x the cone angle
  double rubble_friction_angle_deg = 30.0; ///< deg
  double rubble_cohesion = 3e3;            ///< Pa
  double friction_ice_ice = -1.0;          ///< -; < 0 = material.friction
  double keel_depth = 0.0;                 ///< m
  double rubble_height = 0.0;              ///< m; used by `hybridsim iso` (a run uses its pile height)
};

struct StabilityDef {
  double max_speed = 100.0;        ///< m/s
  double max_overlap_ratio = 0.5;  ///< overlap / radius
};

/// How a run under mpirun spreads over the ranks (ignored by a serial run); docs/parallel.md.
struct ParallelSceneDef {
  std::array<int, 3> grid{0, 0, 0};      ///< boxes along x, y, z; all 0 = chosen from the rank count
  std::uint64_t balance_interval = 500;  ///< steps between load-balance checks; 0 = never
  std::string cost = "work";             ///< "work" (deterministic) or "time" (measured)
};

/// One block given in the scene itself (tests, small scenes).
struct BlockItemDef {
  Vec3 half_extents{0.5, 0.5, 0.5};  ///< m
  Vec3 position = Vec3::Zero();      ///< centre, m
  Quat orientation = Quat::Identity();
  Vec3 velocity = Vec3::Zero();      ///< m/s
  Vec3 angular_velocity = Vec3::Zero();  ///< rad/s, world
  bool fixed = false;                ///< immovable (e.g. ice cover beside the particle sheet); never converts
};

/// Where blocks may turn into particles: a region that moves with the structure
/// (docs/bridge.md, "Conversion region").
struct ConversionRegionDef {
  std::string shape = "cylinder";    ///< "cylinder" (vertical axis) or "box"
  Vec3 offset = Vec3::Zero();        ///< centre relative to the structure's mesh origin, m
  double radius = 0.0;               ///< cylinder radius, m; 0 = structure radius + 5 m
  double z_min = -1e30, z_max = 1e30;  ///< cylinder z range relative to the offset, m
  Vec3 half_extents = Vec3::Zero();  ///< box, m
};

/// Rigid ice blocks (Bullet): a ridge file from `hybridsim ridge` and/or a list, and how
/// they turn into bonded particles near the structure (docs/bridge.md).
struct BlocksDef {
  std::string ridge_file;            ///< as written in the scene
  std::string ridge_file_path;       ///< resolved against the scene's directory
  Vec3 offset = Vec3::Zero();        ///< added to the ridge file's positions, m
  std::array<double, 2> keep_x{-1e30, 1e30}, keep_y{-1e30, 1e30};  ///< ridge blocks kept (centre), m
  bool keep_sail = true;             ///< keep the ridge file's sail blocks
  /// Ridge blocks without a joint to another kept block or the ice: "drop" (left out) or "keep"
  /// (docs/bridge.md, "Relaxation": they creep in a keel steeper than the friction angle).
  std::string loose_blocks = "drop";
  std::vector<BlockItemDef> list;
  double density = 0.0;              ///< kg/m^3; 0 = material.density
  double friction = -1.0;            ///< ice-ice; < 0 = material.friction
  int solver_iterations = 20;
  /// m/s: a solve of the rigid world stops once no row changes its velocity by more than this in
  /// an iteration (RigidWorldDef::solver_tolerance; docs/rigid.md, "Solver iterations and their
  /// early exit"); 0 = every solve takes solver_iterations.
  double solver_tolerance = 1e-4;
  /// Two friction directions per contact point, kept for its lifetime (RigidWorldDef); false:
  /// Bullet's one direction along the sliding velocity, under which resting blocks in a deep
  /// pile creep at cm/s (docs/ridge.md, "Fixed friction directions").
  bool fixed_friction_directions = true;
  /// Friction rows that see external torques (RigidWorldDef::friction_sees_torque).
  bool friction_sees_torque = false;
  double rigid_dt = 0.0;             ///< s; 0 = the largest step the stability rule allows
  std::string conversion = "hybrid"; ///< "hybrid", "all_at_start" or "never"
  /// Where all_at_start's blocks' sites come from (bridge::IceMaterial::world_lattice): "block",
  /// each its own face-aligned lattice, or "world", one lattice fixed in the world shared by every
  /// block. Hybrid-mode conversions always use the block's own lattice.
  std::string lattice = "block";
  ConversionRegionDef region;
  double safety_factor = 1.0;        ///< converts when utilisation x safety_factor >= 1
  double flexural_strength = 0.5e6;  ///< Pa; read with analysis.flexural_strength as its default
  double stress_time_constant = 0.05;  ///< s, low-pass filter on the utilisation; 0 = none
  /// The relaxation before the freeze (docs/bridge.md, "Relaxation"; bridge::RelaxDef): on by
  /// default with a ridge file (off for a list alone: its blocks' initial state is the scene's),
  /// `"relax": false` turns it off, `true` or an object on.
  struct Relax {
    bool enabled = true;
    double max_time = 30.0;  ///< s
    double speed = 0.002;    ///< m/s
    double hold = 1.0;       ///< s
    double damping = 0.0;    ///< 1/s, a set-up device (not physics)
    double jointed_time = 0.0;  ///< s of the jointed stage after it (bridge::RelaxDef); 0 = none
    double lattice_time = 0.0;  ///< s, all_at_start: lattices relax after the rigid blocks (bridge::RelaxDef)
    double lattice_damping = -1.0;  ///< 1/s, the lattice stage's damping; < 0: damping (bridge::RelaxDef)
    bool hold_freeze_bonds = false;  ///< the lattice stage keeps its freeze bonds, unbreakable (bridge::RelaxDef)
  } relax;
  /// Not a scene key: false lets the run take a ridge file made with other ice or under fixed
  /// boxes (sim::check_ridge_generation passes). Set by `hybridsim bench hybrid` only, which times
  /// steps on the standalone paper-size ridge and does not ask for its rest.
  bool check_ridge_generation = true;
  /// Far sleep of the rigid world (docs/rigid.md, "Far sleep"); off unless blocks.far_sleep is given.
  bool far_sleep = false;
  double far_sleep_wake_distance = 2.0, far_sleep_speed = 0.01, far_sleep_still_time = 0.5;
  bool far_sleep_start_asleep = false;
  int far_sleep_wake_hops = 4;
  bool far_sleep_loads_wake_neighbours = false;
  bool far_sleep_loads_held = false, far_sleep_region_awake = true, far_sleep_zone_wakes_neighbours = true;
};

struct Scene {
  std::string name;
  std::string description;
  std::string output;              ///< output file; default "<name>.h5"
  /// The ensemble member: every random draw of the run (bonds.strength_spread) is a hash of this
  /// seed and what is drawn for, so two runs with one seed are identical and two seeds are two
  /// realisations. Absent = 0. A scene with no random option draws nothing and ignores it.
  std::uint64_t seed = 0;
  TimeDef time;
  MaterialDef material;
  BondsDef bonds;
  WaterDef water;
  Vec3 gravity{0.0, 0.0, -9.81};
  bool has_ice = false;
  IceDef ice;
  std::vector<WallDef> walls;
  bool has_structure = false;
  StructureDef structure;
  AnalysisDef analysis;
  StabilityDef stability;
  ParallelSceneDef parallel;
  bool has_blocks = false;
  BlocksDef blocks;

  nlohmann::json json;             ///< the effective scene (after --set overrides)
  std::string base_dir;            ///< the scene file's directory: relative paths are resolved against it
  std::vector<std::string> warnings;  ///< "path: message", for the user; not errors
};

// ---- reading ----
/// Text and files to JSON: the shared reader's (src/json/reader.h), here for scene users.
using hs::parse_json_text;
using hs::read_json_file;
/// Sets one field from "path.to.field=value" (the value is parsed as JSON, else taken as a
/// string). Array elements by index: "walls.0.velocity=[-0.5,0,0]". Missing objects along
/// the path are created. Throws InputError naming the path if it does not exist in the
/// scene schema, or if the assignment is malformed.
void apply_override(nlohmann::json& scene, const std::string& assignment);
/// Validates and converts. Throws InputError naming the JSON pointer of the first problem.
/// Relative file names in the scene (/structure/mesh) are resolved against `base_dir`
/// (the scene file's directory; "" = the current directory).
Scene parse_scene(const nlohmann::json& j, const std::string& base_dir = "");
/// read_json_file + every override in order + parse_scene.
Scene load_scene_file(const std::string& path, const std::vector<std::string>& overrides = {});

/// The keys allowed in the object at `pointer` ("" root, "/ice", "/walls/0", ...); empty
/// if `pointer` is not an object in the schema. Used for unknown-key checks and --set.
const std::vector<std::string>& allowed_keys(const std::string& pointer);

}  // namespace hs::scene
