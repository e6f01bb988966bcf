// Far sleep (RigidWorldDef::far_sleep; docs/rigid.md, "Far sleep"): blocks far from anything that
// moves are not stepped. A component of RigidWorld with its own state (FarSleep); its functions
// take the world (WorldImpl: the blocks, the Bullet world, the joints, the meshes) they act on.
// Private to hs_rigid (includes Bullet).
//
// A sleeping block is a static object to Bullet (CF_STATIC_OBJECT: the solver meets it as an
// immovable body, it is neither integrated nor given gravity) and ISLAND_SLEEPING (its pairs
// with other sleeping blocks are not collided, its bounding box not updated); awake blocks are
// DISABLE_DEACTIVATION as without the rule. Bullet's own island sleeping is switched off
// (CanonicalWorld::managed_sleep).
#pragma once

#include "common/types.h"
#include "rigid/canonical_world.h"
#include "rigid/rigid_world.h"

#include <btBulletDynamicsCommon.h>

#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

namespace hs::rigid::detail {

struct BlockSlot;
struct WorldImpl;

/// A block's inverse mass and world inverse inertia as the solver sees it awake, bit for bit what
/// Bullet holds for an awake body (setMassProps, updateInertiaTensor); a sleeping body holds zeros.
struct SolveMass {
  double inv_mass = 0.0;
  btMatrix3x3 inv_inertia_world;
};
SolveMass solve_mass(const WorldImpl& w, const btRigidBody& b);

struct FarSleep {
  /// Throws hs::InputError for a far-sleep definition out of range (def.far_sleep.enabled).
  static void validate(const RigidWorldDef& def);
  /// Switches the world over to far sleep: managed sleep, the near callback that skips pairs of
  /// sleeping blocks, the pair index, check_sleepers after every solve.
  void install(WorldImpl& w);
  /// A new block slot (add_block).
  void add_slot();

  // ---- the rule, at the start of a sub-step (update_sleep) ----
  /// The far-sleep rule (rigid_world.h) on the state at the start of a sub-step. Every decision is
  /// taken from that state (flags first, then applied), so the order of the loops does not matter.
  void update_sleep(WorldImpl& w, double h);
  bool block_moving(const RigidWorldDef& def, const BlockSlot& s) const;
  void put_to_sleep(WorldImpl& w, BlockSlot& s);
  void wake(WorldImpl& w, BlockSlot& s);
  /// A sleeping block's centre (sleep_centre) from its body's pose: kept equal to it (put_to_sleep,
  /// set_pose; the solve does not move a sleeping block: it has no mass there), so that update_sleep
  /// need not read every sleeping body.
  void set_sleep_pose(WorldImpl& w, BlockSlot& s, const btTransform& pose);

  // ---- the hold, after every solve (check_sleepers) ----
  /// Before a solve: the joints it takes (CanonicalWorld::awake_joints).
  void collect_awake_joints(WorldImpl& w);
  /// After each solve (CanonicalWorld::after_solve): wakes the sleepers whose load departed from
  /// their reference; true when the solve is to be done again.
  bool check_sleepers(WorldImpl& w, bool may_repeat);
  /// loads_held: a sleeping block's caller load of this sub-step, taken off the block.
  void hold_caller_load(WorldImpl& w, std::size_t k, double h);
  void mark_hold_fresh(std::size_t k) {
    if (!hold_fresh[k]) hold_fresh_list.push_back(static_cast<std::uint32_t>(k));
    hold_fresh[k] = 1;
  }

  // ---- state ----
  std::vector<std::pair<Vec3, Vec3>> wake_boxes;  // RigidWorld::set_wake_boxes
  std::size_t asleep_count = 0;
  PairIndex pair_index;  // the overlapping pairs by proxy (far sleep: CanonicalWorld's dispatch)
  std::vector<Vec3> sleep_centre;  // per block slot: a sleeping block's centre (update_sleep's wake-zone test)
  // The hold (check_sleepers): per block slot, the impulse that the solve gave the block in its
  // first solve asleep (the reference); hold_fresh: the reference is taken at the next solve (the
  // block fell asleep, or a block it touches or is jointed to did, so that the set of its solved
  // contacts and joints changed).
  std::vector<Vec3> hold_j;
  std::vector<char> hold_fresh;
  std::vector<std::uint32_t> hold_fresh_list;
  // Scratch of check_sleepers: this solve's impulses on sleeping blocks, the sleepers the solve
  // took (touched) and those of the sub-step's last solve (touched_before).
  std::vector<Vec3> solve_j;
  std::vector<char> solve_seen;
  std::vector<std::uint32_t> touched, touched_before, to_wake;
  std::size_t sleepers_woken_by_solve = 0;  // a count, for tests and benches
  // loads_held: per block slot, the caller's impulse on a sleeping block over this sub-step (linear,
  // angular; taken from its add_impulse / add_force at the sub-step's start and counted in its load
  // by check_sleepers), and the slots that have one.
  std::vector<Vec3> caller_j, caller_l;
  std::vector<std::uint32_t> caller_loaded;
  // allow_neighbours: per block slot, how far its load may depart from its reference this sub-step
  // beyond m speed, and the slots that have an allowance.
  std::vector<double> allow;
  std::vector<std::uint32_t> allow_list;
  // Scratch of update_sleep: per block slot, and the neighbour graph.
  std::vector<char> moving, woken, reset, moving_seen;
  std::vector<std::uint32_t> adj_start, adj, bfs_a, bfs_b;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> edges;
  /// Dynamic blocks stepped, summed over the sub-steps (RigidWorld::stepped_body_count; counted
  /// with far sleep off too).
  std::uint64_t stepped_bodies = 0;

 private:
  // update_sleep's steps.
  void flag_blocks(WorldImpl& w);
  void build_neighbour_graph(WorldImpl& w);
  void spread_wake(WorldImpl& w);
  void apply_rule(WorldImpl& w, double h);
  bool in_wake_zone(const WorldImpl& w, const Vec3& c) const;
  // check_sleepers' steps.
  void take_solve_loads(WorldImpl& w);
  void find_departed(WorldImpl& w);
  void wake_departed(WorldImpl& w, bool repeat);
  void settle_references(const WorldImpl& w);
  // Neighbours of a block that fell asleep or woke.
  void collide_with_inactive(WorldImpl& w, BlockSlot& s);
  template <class F>
  void for_sleeping_neighbours(WorldImpl& w, BlockSlot& s, F&& f);
  void fresh_neighbours(WorldImpl& w, BlockSlot& s);
  void allow_neighbours(WorldImpl& w, BlockSlot& s);
};

}  // namespace hs::rigid::detail
