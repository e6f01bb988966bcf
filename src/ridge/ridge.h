// Ridge generator (paper "Generation of Ice Ridges", DESIGN.md "Ridge"): level ice with a
// consolidated layer (fixed boxes at the waterline), a keel of cuboid blocks released under
// the ice that rise by buoyancy and settle, a sail of blocks dropped onto the ice, and
// freeze joints between the touching blocks once everything is at rest. See docs/ridge.md.
//
// A client of src/rigid (RigidWorld's public API settles the blocks). The ridge's values, its
// frame and target envelope: ridge/ridge_data.h; the definition's geometry and checks:
// ridge/definition.h; its JSON: ridge/ridge_json.h; its file: io/ridge_file.h.
#pragma once

#include "ridge/definition.h"
#include "ridge/ridge_data.h"

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

namespace hs::rigid {

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

/// n samples of ln(L/h) from the generator's sampler (seeded, truncated at +-4 sigma).
std::vector<double> sample_log_aspect(const AspectLognormal& a, std::size_t n, std::uint64_t seed);

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

}  // namespace hs::rigid
