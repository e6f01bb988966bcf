// Particle-block contact (docs/bridge.md, "Particle-block contact"): spheres of the particle
// engine against oriented boxes of the rigid world, with the particle-particle contact law of the
// engine (EngineDef::contact_model) and forces on both sides.
//
// The blocks are given as plain kinematic state (no Bullet type): the caller (the multi-rate
// stepper) copies each block's pose and velocities in between rigid steps; the engine calls
// add_forces() in every force evaluation (bonded::ForceSource), on owned particles only.
//
// Geometry, for a sphere of radius r at x and a box of half extents h, centre c, rotation R:
//   l = R^T (x - c)                        sphere centre in the block frame
//   outside (some |l_k| > h_k):  q = clamp(l, -h, h),  n = R (l - q)/|l - q|,  delta = r - |l - q|
//     (face, edge and corner contacts alike: n runs from the closest point to the centre)
//   inside (all |l_k| <= h_k):   k = argmin (h_k - |l_k|),  n = R sign(l_k) e_k,
//                                delta = r + (h_k - |l_k|)   (pushed out through the nearest face)
// Contact law (contact_linear.h / contact_hertz.h, "j" = the particle, "i" = the block):
//   a = -(r - delta/2) n                   contact point relative to the sphere centre
//   v_rel = v + w x a - (v_b + w_b x (x + a - c))
//   v_n = v_rel.n,  v_t = v_rel - v_n n
//   m_eff = m M / (m + M)                  (m_eff = m for an immovable block, M = infinity)
//   R* = r                                 (a face is a sphere of infinite radius; edges and
//                                           corners likewise, as for the engine's mesh walls)
//   friction mu = the block's; stiffness and restitution damping = the engine's particle law.
// Force F on the particle, torque a x F on it; -F on the block, torque (x + a - c) x (-F) about
// its centre. Linear and angular momentum are therefore exchanged exactly.
//
// Tangential spring history is kept per (particle global id, block id) and dropped when the
// contact ends, like the engine's mesh walls. Under MPI each rank holds the history of the
// contacts of the particles it owns, and it migrates with them (pack_history/unpack_history).
#pragma once

#include "bonded/engine.h"

#include <cstdint>
#include <unordered_map>
#include <vector>

namespace hs::bridge {

/// Kinematic state of a rigid block as the particles see it (world frame, SI units).
struct ContactBlock {
  std::uint64_t id = 0;                  ///< caller's stable id (keys the contact history); unique
  Vec3 half_extents{0.5, 0.5, 0.5};      ///< m, all > 0
  Vec3 position = Vec3::Zero();          ///< centre, m
  Quat orientation = Quat::Identity();   ///< body -> world
  Vec3 velocity = Vec3::Zero();          ///< of the centre, m/s
  Vec3 angular_velocity = Vec3::Zero();  ///< world frame, rad/s
  double mass = INFINITY;                ///< kg; INFINITY = immovable (m_eff = particle mass)
  double friction = 0.3;                 ///< Coulomb coefficient ice-block
};

/// What the particles did to a block.
struct BlockLoad {
  Vec3 force = Vec3::Zero();    ///< N, exerted BY the particles ON the block, last force evaluation
  Vec3 torque = Vec3::Zero();   ///< N m about the block centre, last force evaluation
  /// Sum of force * history_dt over the evaluations inside steps since clear_impulses(), N s
  /// (compute_forces() adds nothing). With velocity Verlet the particles receive
  /// dt (F_0/2 + F_1 + ... + F_n/2) over n steps; the two differ by dt (F_n - F_0)/2, zero when no
  /// contact is active at the two ends.
  Vec3 impulse = Vec3::Zero();
  Vec3 angular_impulse = Vec3::Zero();  ///< N m s about the block centre, likewise
  std::size_t contacts = 0;     ///< contacts in the last force evaluation
};

/// Timing and size figures of the last add_forces() call (for benchmarks and the docs).
struct BlockContactStats {
  std::size_t tests = 0;        ///< particle-block pairs the grid proposed (box test done)
  std::size_t candidates = 0;   ///< particle-block pairs that passed the grid and box tests
  std::size_t grid_cells = 0;   ///< cells of the block grid
  double seconds = 0.0;         ///< wall time of the last call
};

class BlockContact final : public bonded::ForceSource {
 public:
  BlockContact() = default;

  /// Adds a block; returns its index k. Throws hs::InputError (path "block") on bad input:
  /// non-positive or non-finite half extents, mass <= 0 or NaN, negative friction, zero quaternion,
  /// a duplicate id.
  std::size_t add_block(const ContactBlock& b);
  /// Removes block k (e.g. when it is converted to particles); later blocks move down one index.
  /// Its contact history is dropped at the next force evaluation.
  void remove_block(std::size_t k);
  /// Removes every block, its loads and its history.
  void clear();
  std::size_t size() const { return blocks_.size(); }
  const ContactBlock& block(std::size_t k) const { return blocks_[k]; }
  /// Moves block k (between rigid steps); the contact history is kept.
  void set_state(std::size_t k, const Vec3& position, const Quat& orientation, const Vec3& velocity,
                 const Vec3& angular_velocity);

  const BlockLoad& load(std::size_t k) const { return loads_[k]; }
  /// With recording on, every force evaluation also keeps each contact's force on the block and
  /// its world point (for the flexural stress estimate, block_stress.h), replacing the last ones.
  struct PointForce {
    std::uint32_t block;  ///< block index k
    Vec3 point, force;    ///< world contact point (m), force on the block (N)
  };
  void set_recording(bool on) { record_ = on; }
  const std::vector<PointForce>& recorded() const { return recorded_; }
  /// Zeroes every block's accumulated impulse (the stepper, after pouring them into the rigid world).
  void clear_impulses();
  const BlockContactStats& stats() const { return stats_; }

  /// Elastic energy stored in the active contacts at the particles' current positions (for
  /// energy bookkeeping), owned particles only. J.
  double elastic_energy(const bonded::ParticleStore& ps, std::size_t n_owned, const bonded::EngineDef& def) const;

  bonded::ForceSourceResult add_forces(bonded::ParticleStore& ps, std::size_t n_owned,
                                       const bonded::ForceSourceContext& ctx) override;
  const char* name() const override { return "rigid block"; }
  /// "rigid block <id> (centre ... m, velocity ... m/s, ...); they close at ... m/s": the block of
  /// the deepest contact of the last add_forces() call, for the blow-up message.
  std::string describe_worst(const bonded::ParticleStore& ps, std::uint32_t i, const Vec3& v_mid) const override;
  /// MPI: the tangential springs of leaving particles travel with them (bonded::ForceSource).
  void pack_history(const std::unordered_map<GlobalId, int>& leaving, std::vector<par::Bytes>& out) override;
  void unpack_history(const char* data, std::size_t size) override;

  /// Checkpoint (hybrid_state.cpp): blocks, loads and accumulated impulses, tangential springs.
  void save_state(StateArchive& a, const std::string& prefix) const;
  void load_state(const StateArchive& a, const std::string& prefix);
  /// From every saved rank (another rank count): blocks from the first, loads and impulses summed
  /// (kept only where `keep_sums`, else zero), tangential springs united.
  void load_state_union(const std::vector<StateArchive>& all, const std::string& prefix, bool keep_sums);

 private:
  struct Key {
    GlobalId gid;
    std::uint64_t block;
    bool operator==(const Key& o) const { return gid == o.gid && block == o.block; }
  };
  struct KeyHash {
    std::size_t operator()(const Key& k) const {
      return std::hash<std::uint64_t>()(k.gid * 0x9E3779B97F4A7C15ull ^ (k.block + 0x632BE59BD9B4E019ull));
    }
  };
  /// The grid of the blocks whose box, grown by r_max, meets the box [plo, phi] of the particles.
  void build_grid(double r_max, std::size_t n_particles, const Vec3& plo, const Vec3& phi);

  std::vector<ContactBlock> blocks_;
  std::vector<BlockLoad> loads_;
  std::unordered_map<Key, Vec3, KeyHash> history_, next_history_;  ///< tangential springs
  BlockContactStats stats_;
  std::size_t worst_block_ = 0;  ///< block index k of the deepest contact of the last add_forces()
  bool record_ = false;
  std::vector<PointForce> recorded_;
  // Block grid (rebuilt every call): cell -> blocks whose box, grown by r_max, meets it; only the
  // blocks that reach the particles' bounding box are in it (a far ridge costs one box test each).
  Vec3 grid_lo_ = Vec3::Zero();
  double grid_h_ = 1.0;
  int nx_ = 0, ny_ = 0, nz_ = 0;
  std::vector<std::uint32_t> cell_start_, cell_blocks_;
  std::vector<Mat3> rot_;  ///< per block: R (body -> world) of the current orientation
  std::vector<Vec3> ext_;    ///< per block: |R| h, the half sizes of its world box
  std::vector<char> dirty_;  ///< per block: rot_ and ext_ are to be recomputed (set_state since)
  std::vector<std::uint32_t> near_;  ///< scratch: the blocks in the grid
};

}  // namespace hs::bridge
