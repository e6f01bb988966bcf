// Ridge generator (paper "Generation of Ice Ridges", DESIGN.md "Ridge"): level ice with a
// consolidated layer (fixed boxes at the waterline), a keel of cuboid blocks released under
// the ice that rise by buoyancy and settle, a sail of blocks dropped onto the ice, and
// freeze joints between the touching blocks once everything is at rest. See docs/ridge.md.
//
// Frame: x across the ridge (interaction direction), y along the ridge (0..length), z up,
// still water surface at z = 0. The ridge axis is x = 0. Units: SI (m, kg, s, J, Pa).
//
// Target envelope (keel; the sail is the same construction above the ice):
//   draft of the ice  d_i(x) = t (rho_i / rho_w), t = consolidated_layer_thickness for
//                     |x| < consolidated_layer_width/2, else level_ice_thickness;
//   keel depth        D(x) = min(keel_depth, d_li + (W/2 - |x|) tan(theta))  for |x| < W/2
//                     (W = keel_width, theta = shoulder_slope_deg, d_li = level-ice draft):
//                     a trapezoid, or a triangle when W = 2 (keel_depth - d_li) / tan(theta)
//                     (the default when keel_width is not given);
//                     or, with a measured profile, D(x) = linear interpolation of the CSV
//                     (0 outside it);
//   envelope          the water between z = -D(x) and the ice underside z = -d_i(x).
// Blocks: thickness h = block_thickness, length L = r h with ln r ~ N(mu, sigma)
// (aspect "of": "log"; with "of": "ratio" r itself has mean mu and sd sigma), width
// B = L u, u ~ U(width_fraction_min, width_fraction_max); ln r is truncated at mu +- 4 sigma.
#pragma once

#include "common/types.h"

#include <nlohmann/json.hpp>

#include <array>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace hs::rigid {

/// Aspect ratio r = L/h of the rubble blocks.
struct AspectLognormal {
  double mu = 1.06;    ///< "log": mean of ln r; "ratio": mean of r
  double sigma = 0.5;  ///< "log": sd of ln r;   "ratio": sd of r
  bool of_log = true;  ///< JSON "of": "log" (true) or "ratio" (false)
  /// Parameters (m, s) of ln r ~ N(m, s) for either reading:
  /// "ratio": s^2 = ln(1 + sigma^2/mu^2), m = ln(mu) - s^2/2.
  void log_params(double& m, double& s) const;
};

/// One point of a measured keel profile: keel depth below the waterline at position x.
struct ProfilePoint {
  double position = 0.0;  ///< x, m
  double depth = 0.0;     ///< m below the waterline, >= 0
};

/// Settling (rigid-body stage) settings.
struct RidgeSettleDef {
  /// Rigid step, s. Stability rule (docs/ridge.md): v_max dt <= 0.25 h_min with the speed
  /// cap below, and the linear water drag explicit-stable: c_lin dt / (rho_i h_min) < 1.
  double dt = 1.0 / 30.0;
  int solver_iterations = 20;
  /// Settled when the mean kinetic energy per block stays below this for 1 s, J.
  double kinetic_energy_per_block = 0.01;
  /// And (settle phase, when > 0) every block moved less than this over that last second, m:
  /// the mean energy passes while single blocks still slide through the pile at cm/s, and
  /// those keep sliding in the run (docs/ridge.md, Method 4, "Settle"). 0 = energy only.
  double max_displacement = 0.0;
  double min_time = 2.0;   ///< s, never stop before this
  double max_time = 150.0; ///< s, stop here even if not settled (stats.settled = false)
  double friction = 0.5;   ///< ice-ice Coulomb coefficient while settling
  double linear_drag = 1000.0;      ///< water drag c_lin, Pa s/m (RigidWorldDef)
  double quadratic_drag_cd = 1.0;   ///< water drag C_d
  /// Speed cap while settling (generation only, not physics): |v| <= speed_cap_factor h_min/dt.
  double speed_cap_factor = 0.25;
  bool allow_sleep = true;          ///< Bullet deactivation of resting islands
  /// Compaction phase (generation device, docs/ridge.md): friction while the blocks rise
  /// and pack; ends when the KE criterion is met or at compaction_time (0: no such phase).
  double compaction_friction = 0.0;
  double compaction_time = 30.0;    ///< s, simulated
  /// Solver iterations while compacting (the settle phase uses solver_iterations: a deep
  /// pile at rest needs ~30 to bring the residual jitter under the KE threshold).
  int compaction_solver_iterations = 10;
  /// Settle phase (after compaction): velocity damping rate, 1/s (v /= 1 + damping dt per
  /// step). Numerical: it stops the creep of the pile, it is not water drag.
  double damping = 5.0;
  /// RigidWorldDef::fixed_friction_directions (both phases): two friction directions per
  /// contact point, fixed for its lifetime and warm-started, instead of Bullet's one
  /// direction along the sliding velocity; stops the frictional creep of resting blocks.
  bool fixed_friction_directions = true;
};

/// Freeze-joint detection after settling.
struct RidgeJointDef {
  double gap = 0.02;        ///< m, blocks closer than this are "touching"
  double min_area = 0.01;   ///< m^2, smaller contact patches get no joint
  bool to_ice = true;       ///< also freeze blocks to the level ice / consolidated layer
};

/// The ice a ridge settles under (docs/ridge.md, "Floating plates").
/// floating = false (standalone ridge scenes): fixed boxes of the solid slab, t thick at the
/// flotation draft t rho_i / rho_w. floating = true (a run scene's ridge): plates with the
/// geometry of the run's particle sheet at rest (contact surfaces: top and bottom layer
/// centres +- D/2, from sim::sheet_geometry), free to heave only, each weighing what makes
/// it float exactly there; the keel pushes them up and the sail loads them until the whole
/// is in vertical equilibrium.
struct RidgeSheet {
  bool floating = false;
  double level_top = 0.0, level_underside = 0.0;  ///< z at rest, level ice, m
  double layer_top = 0.0, layer_underside = 0.0;  ///< z at rest, consolidated layer, m
  /// x extent of the consolidated layer's particles, m: the band's width plus one particle
  /// diameter (the spheres whose centres lie in the band reach D/2 beyond it).
  double layer_width = 0.0;
  double particle_diameter = 0.0;                 ///< D of the run's sheet (record only), m
  double consolidated_layer_center_x = 0.0;       ///< the run scene's centre (record only), m
  /// m, x width of the plate strips each part is cut into; 0 (default): one plate per part
  /// (level ice | consolidated layer | level ice). Narrow strips have no bending stiffness
  /// between them: a sail sinks its own strips (docs/ridge.md, "Floating plates").
  double plate_width = 0.0;
  /// Neighbouring plates joined rigidly (unbreakable fixed joints at their common edges): the
  /// sheet heaves as one body, as the run's bonded lattice is one piece. false: each plate
  /// heaves on its own (no bending stiffness: a sail pushes its plate under, docs/ridge.md).
  bool plates_joined = true;
};

struct RidgeDef {
  std::string name;  ///< free text (scene name)
  RidgeSheet sheet;  ///< the ice it settles under (not in the ridge JSON but plate_width)
  // Ice sheet.
  double level_ice_thickness = 0.6;            ///< m
  double consolidated_layer_thickness = 0.9;   ///< m
  double consolidated_layer_width = 20.0;      ///< m, centred on x = 0
  double level_ice_margin = 10.0;              ///< m of level ice beyond the keel/sail on each side
  double ice_density = 910.0;                  ///< kg/m^3
  double water_density = 1025.0;               ///< kg/m^3
  // Keel.
  double keel_depth = 7.9;                     ///< m below the waterline
  double keel_width = -1.0;                    ///< m at the ice underside; < 0: triangle from the slope
  double shoulder_slope_deg = 6.0;             ///< shoulder slope, deg
  std::string keel_profile_csv;                ///< measured profile (replaces the trapezoid) or ""
  std::vector<ProfilePoint> keel_profile;      ///< its points (loaded by ridge_def_from_json)
  // Sail.
  double sail_height = 7.9 / 4.4;              ///< m above the waterline; 0: no sail
  double sail_width = -1.0;                    ///< m at the ice top; < 0: triangle from the slope
  double sail_slope_deg = 6.0;                 ///< deg
  // Along the ridge.
  double length = 200.0;                       ///< m (y extent)
  bool end_walls = true;                       ///< fixed walls at y = 0 and y = length while settling
  // Blocks.
  double block_thickness = 0.6;                ///< m (default: level ice thickness)
  AspectLognormal aspect;
  double width_fraction_min = 0.5;             ///< block width / length ~ U(min, max)
  double width_fraction_max = 1.0;
  /// Initial block orientation: >= 90 uniformly random; otherwise random yaw and a tilt
  /// of U(0, max_tilt_deg) about a random horizontal axis (flatter, denser rubble).
  double max_tilt_deg = 90.0;
  /// Porosity assumed when counting how many blocks fill the target envelope:
  /// block volume = (1 - fill_porosity) x envelope volume (keel and sail separately).
  /// Default: the whole-keel porosity the generator reaches (~0.4, docs/ridge.md), so the
  /// keel comes out at its target depth.
  double fill_porosity = 0.4;
  /// Poses tried per block in the greedy deposition (the least deep one relative to the
  /// target profile is kept); 1 is plain ballistic deposition (loose, porosity ~0.8).
  int placement_candidates = 8;
  std::uint64_t seed = 1;
  RidgeSettleDef settle;
  RidgeJointDef joints;
  double profile_bin = 1.0;                    ///< m, x bin of the achieved profile
  double porosity_grid = 0.25;                 ///< m, point spacing of the porosity count
};

/// A settled block.
struct RidgeBlock {
  Vec3 half_extents = Vec3::Zero();
  Vec3 position = Vec3::Zero();
  Quat orientation = Quat::Identity();
  std::int32_t part = 0;  ///< 0 keel, 1 sail
};

/// A box of the ice sheet: fixed, or a floating plate (RidgeSheet) at its final pose.
struct IceBox {
  Vec3 half_extents = Vec3::Zero();
  Vec3 position = Vec3::Zero();  ///< final (a plate: after settling), m
  std::int32_t part = 0;  ///< 0 level ice, 1 consolidated layer
  double lift = 0.0;      ///< plate: final z - rest z (up > 0), m; fixed box: 0
};

/// Freeze joint between blocks[a] and blocks[b] (b < 0: ice box -1 - b).
struct RidgeJoint {
  std::int32_t a = 0, b = 0;
  Vec3 anchor = Vec3::Zero();          ///< centroid of the contact region, world
  Vec3 normal = Vec3::UnitZ();         ///< unit, from a to b
  double area = 0.0;                   ///< m^2, contact patch estimate
};

/// Target vs achieved profile, per x bin (centres).
struct RidgeProfile {
  std::vector<double> x;              ///< bin centres, m
  std::vector<double> keel_target;    ///< D(x), m below the waterline (0: no keel)
  std::vector<double> keel_depth;     ///< 95th percentile of block bottoms, m below the waterline (0: none)
  std::vector<double> sail_target;    ///< m above the waterline (0: no sail)
  std::vector<double> sail_height;    ///< 95th percentile of block tops, m (0: none)
};

struct RidgeStats {
  std::size_t keel_blocks = 0, sail_blocks = 0, joints = 0, ice_joints = 0;
  double keel_block_volume = 0.0, sail_block_volume = 0.0;  ///< m^3
  double keel_target_volume = 0.0;    ///< target envelope volume, m^3
  /// 1 - (block volume inside) / (envelope volume), counted on a point grid inside the
  /// achieved keel envelope (ice underside down to the achieved profile).
  double keel_porosity = 0.0;
  /// Same, only under the consolidated layer (|x| < consolidated_layer_width / 2).
  double core_porosity = 0.0;
  double keel_depth_target = 0.0, keel_depth_achieved = 0.0;  ///< max over bins, m
  double sail_height_target = 0.0, sail_height_achieved = 0.0;
  double keel_profile_rms_error = 0.0;  ///< m, over bins where the target or achieved keel > 0
  double settle_time = 0.0;             ///< simulated s
  double compaction_time = 0.0;         ///< simulated s at which the compaction phase ended
  std::uint64_t settle_steps = 0;
  bool settled = false;                 ///< KE criterion met before max_time
  double final_kinetic_energy_per_block = 0.0;  ///< J
  /// Breakdown of the final kinetic energy: blocks asleep (Bullet deactivation: velocity
  /// exactly 0), mean over the awake blocks, J, median block, J, and the sail's share.
  std::size_t final_asleep_blocks = 0;
  double final_kinetic_energy_per_awake_block = 0.0;
  double final_kinetic_energy_median = 0.0;
  double final_kinetic_energy_sail_fraction = 0.0;
  /// Block displacement over the last second of settling, mean and max, m.
  double final_mean_displacement = 0.0, final_max_displacement = 0.0;
  double max_final_overlap = 0.0;       ///< m, largest pairwise SAT penetration after settling
  /// Vertical balance at the end (g = 9.81): sum over blocks of buoyancy - weight, and over the
  /// floating plates (0 for fixed ice), N. At rest the two cancel.
  double block_net_buoyancy = 0.0, plate_net_buoyancy = 0.0;
  double wall_time = 0.0;               ///< s (not reproducible; excluded from comparisons)
};

struct RidgeResult {
  RidgeDef def;
  std::vector<RidgeBlock> blocks;
  std::vector<RidgeJoint> joints;
  std::vector<IceBox> ice;
  RidgeProfile profile;
  RidgeStats stats;
  /// The generation record as read from a file (ridge_generation_json at save); empty for a
  /// result fresh from generate_ridge.
  nlohmann::json generation;
};

struct RidgeProgress {
  const char* phase = "";  ///< "place", "settle", "joints", "measure"
  double time = 0.0;       ///< simulated s (settle)
  double max_time = 0.0;
  double kinetic_energy_per_block = 0.0;
  std::size_t blocks = 0;
  /// Largest block displacement over the last second, m (settle phases; < 0: not measured).
  double max_displacement = -1.0;
};
using RidgeProgressFn = std::function<void(const RidgeProgress&)>;

/// Builds the ridge. Same def (seed included) -> identical result bit for bit (wall_time
/// aside). Throws hs::InputError for an impossible definition.
RidgeResult generate_ridge(const RidgeDef& def, const RidgeProgressFn& progress = {});

/// Settling an existing ridge again under another ice cover (docs/rigid.md, "The bench's ridge at
/// rest"): a ridge generated under fixed boxes is not at rest where a run floats a particle
/// sheet instead (the sheet must carry the keel's buoyancy that the boxes held), nor around a
/// structure placed into it. The blocks whose centre lies in [region_lo, region_hi] move; every
/// other block is held where it is (a fixed body, as far sleep holds it in the run).
struct RidgeResettleDef {
  std::vector<IceBox> fixed_boxes;  ///< the cover that stays (fixed bodies)
  /// Plates at their rest pose (position, half extents: contact surfaces at rest), floating with
  /// plate_density, heave only, joined rigidly to each other in order (the run's lattice is one
  /// piece); their final pose and lift go to the result's `ice`.
  std::vector<IceBox> plates;
  /// A structure held where it stands (velocity ignored), e.g. the pier; no triangles: none.
  std::vector<Vec3> obstacle_vertices;
  std::vector<std::array<std::uint32_t, 3>> obstacle_triangles;
  Vec3 obstacle_position = Vec3::Zero();
  std::vector<char> keep;  ///< per block of the input; false: left out (inside the structure); empty: all
  Vec3 region_lo = Vec3::Zero(), region_hi = Vec3::Zero();
  struct Phase {
    double dt = 1.0 / 30.0, time = 10.0;  ///< s
    int solver_iterations = 20;
    double damping = 5.0;  ///< 1/s, v /= 1 + damping dt per step (as the generator's settle phase)
  };
  std::vector<Phase> phases{Phase{}, Phase{1.0 / 240.0, 2.0, 20, 5.0}};
};
/// What resettle_ridge did (returned beside the result; not written to the ridge file).
struct RidgeResettleStats {
  std::size_t moving_blocks = 0, held_blocks = 0, dropped_blocks = 0, dropped_joints = 0;
  double plate_lift = 0.0;                 ///< m, the first plate's (joined plates heave together)
  double final_kinetic_energy_per_block = 0.0;  ///< J, moving blocks, end of the last phase
  double max_displacement = 0.0;           ///< m, largest block move from the input's pose
  double last_second_max_displacement = 0.0;  ///< m, over the last second of the last phase
  double wall_time = 0.0;                  ///< s
};
/// The input with the moving blocks at their settled poses, the left-out blocks removed (joints
/// renumbered, those of left-out blocks dropped), every joint's anchor carried with its first
/// block, `ice` the plates (final pose, lift; the fixed boxes are not kept) and def.sheet.floating
/// set, so that a run lifts its sheet by their lift (sim::sheet_lift). A joint to the ice is taken
/// to the plate nearest its anchor in x (the ice index only names a part of the sheet: a run makes
/// block-particle bonds against the joint's patch wherever particles are), and dropped when there
/// are no plates. Deterministic.
RidgeResult resettle_ridge(const RidgeResult& in, const RidgeResettleDef& rd, RidgeResettleStats* stats = nullptr,
                           const RidgeProgressFn& progress = {});

// ---- pieces, public for tests and tools ----

/// Target keel depth below the waterline at x (0 where there is no keel).
double keel_target_depth(const RidgeDef& def, double x);
/// Target sail height above the waterline at x (0 where there is no sail).
double sail_target_height(const RidgeDef& def, double x);
/// Draft (z of the underside = -draft) and freeboard of the ice at x (at rest; with a
/// floating sheet: its contact surfaces).
double ice_draft(const RidgeDef& def, double x);
double ice_freeboard(const RidgeDef& def, double x);

/// n samples of ln(L/h) from the generator's sampler (seeded, truncated at +-4 sigma).
std::vector<double> sample_log_aspect(const AspectLognormal& a, std::size_t n, std::uint64_t seed);

/// Reads a keel profile CSV: two columns position_m, depth_m (comma separated, an optional
/// header line, '#' comments and blank lines allowed), positions strictly increasing,
/// depths >= 0. Throws hs::InputError(path, "line N: ...") on any malformed line.
std::vector<ProfilePoint> load_profile_csv(const std::string& path);

/// Penetration depth of two oriented boxes (separating axis test; 0 when separated).
double box_penetration(const Vec3& ha, const Vec3& xa, const Quat& qa, const Vec3& hb,
                       const Vec3& xb, const Quat& qb);

/// What generate_ridge will build, estimated from the definition before anything is allocated
/// (the memory guard of `hybridsim ridge`).
struct RidgeEstimate {
  double keel_volume = 0.0, sail_volume = 0.0;  ///< target envelopes, m^3
  double mean_block_volume = 0.0;               ///< E[L B h] of the sampled blocks, m^3
  double blocks = 0.0;  ///< (1 - fill_porosity) (keel + sail volume) / mean block volume
  double bytes = 0.0;   ///< blocks x kRidgeBytesPerBlock
};
/// Resident memory per block while settling (rigid body, shape, broad-phase entry, contact
/// manifolds, joints, placement grid), bytes.
inline constexpr double kRidgeBytesPerBlock = 4096.0;
RidgeEstimate ridge_estimate(const RidgeDef& def);

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
/// Density that makes a plate of contact surfaces [underside, top] float with them there:
/// rho_w (-underside) / (top - underside). Throws hs::InputError unless top > 0 > underside.
double plate_density(double top, double underside, double water_density);
/// Summary: counts, porosity, keel depth / sail height target vs achieved, settle info.
nlohmann::json ridge_report(const RidgeResult& r);

}  // namespace hs::rigid
