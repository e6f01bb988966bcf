// Ridge data: the plain values of a ridge (paper "Generation of Ice Ridges", DESIGN.md "Ridge";
// the generator: ridge/ridge.h): its definition, the settled blocks, the ice boxes, the freeze
// joints, the achieved profile and the statistics. What src/io reads and writes
// (io/ridge_file.h) and what a run builds from. Depends on Eigen (common/types.h) only: no
// Bullet, no JSON (a definition's JSON: ridge/ridge_json.h). See docs/ridge.md.
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

#include <cstddef>
#include <cstdint>
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
  /// The generation record as read from a file: the JSON text of ridge_generation_json at save
  /// (ridge/ridge_json.h); empty for a result fresh from generate_ridge.
  std::string generation;
};

}  // namespace hs::rigid
