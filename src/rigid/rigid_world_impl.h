// RigidWorld's state (the pimpl), shared by the files that implement it, one concern each:
//   rigid_world.cpp     the world core: Bullet set-up, blocks, the sub-step, contact forces;
//   joints.cpp          freeze joints (rigid or springs), their loads and breaking;
//   far_sleep.cpp/.h    far sleep, a component with its own state (FarSleep);
//   kinematic_mesh.cpp  the kinematic meshes (the structure) and their loads;
//   world_state.cpp     the checkpoint of the world (save_state, load_state).
// Private to hs_rigid (includes Bullet); no public header includes it.
#pragma once

#include "rigid/canonical_world.h"
#include "rigid/far_sleep.h"
#include "rigid/rigid_world.h"

#include <btBulletDynamicsCommon.h>

#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace hs::rigid::detail {

inline btVector3 to_bt(const Vec3& v) { return btVector3(v.x(), v.y(), v.z()); }
inline Vec3 from_bt(const btVector3& v) { return Vec3(v.x(), v.y(), v.z()); }
inline btQuaternion to_bt(const Quat& q) { return btQuaternion(q.x(), q.y(), q.z(), q.w()); }
inline Quat from_bt(const btQuaternion& q) { return Quat(q.w(), q.x(), q.y(), q.z()); }

struct BlockSlot {
  std::uint32_t generation = 0;
  bool alive = false;
  bool fixed = false;
  Vec3 half = Vec3::Zero();
  double mass = 0.0;
  std::unique_ptr<btBoxShape> shape;
  std::unique_ptr<btRigidBody> body;
  // Caller loads, world frame, about the centre of mass.
  Vec3 ext_force = Vec3::Zero(), ext_torque = Vec3::Zero();
  Vec3 imp_linear = Vec3::Zero(), imp_angular = Vec3::Zero();
  // Far sleep (RigidWorldDef::far_sleep; the centre of a sleeping block is FarSleep::sleep_centre).
  bool asleep = false;
  double still = 0.0;  // s the block and its neighbours have been still
};

struct MeshSlot {
  Vec3 origin = Vec3::Zero(), velocity = Vec3::Zero();
  std::vector<btScalar> vertices;  // Bullet keeps pointers into these arrays
  std::vector<int> indices;
  std::vector<std::uint16_t> part;
  Vec3 lo = Vec3::Zero(), hi = Vec3::Zero();  // bounding box of the vertices, mesh frame
  std::unique_ptr<btTriangleIndexVertexArray> array;
  std::unique_ptr<btBvhTriangleMeshShape> shape;
  std::unique_ptr<btRigidBody> body;
  MeshLoad load;
};

struct JointSlot {
  std::uint32_t slot = 0;  // its index in WorldImpl::joints (and in the world's joint_order)
  std::uint32_t generation = 0;
  bool alive = false;   // slot in use (intact or broken)
  bool broken = false;
  BlockId a, b;
  Vec3 normal_in_a = Vec3::UnitZ();  // joint normal in a's body frame
  Vec3 anchor_in_a = Vec3::Zero();   // anchor in a's body frame
  double area = 1.0;
  JointLoad load;
  btJointFeedback feedback{};
  std::unique_ptr<btTypedConstraint> constraint;  // btFixedConstraint, or a 6-dof spring
};

/// A block's body, not a kinematic mesh's (canonical_world.h's kMeshTag in user index 2).
inline bool is_block(const btCollisionObject* o) { return o->getUserIndex2() != kMeshTag; }

struct WorldImpl {
  RigidWorldDef def;
  std::unique_ptr<btDefaultCollisionConfiguration> config;
  std::unique_ptr<btCollisionDispatcher> dispatcher;
  std::unique_ptr<btDbvtBroadphase> broadphase;
  std::unique_ptr<PooledSolver> solver;
  std::unique_ptr<CanonicalWorld> world;  // solves in a fixed order (canonical_world.h)
  std::vector<btPersistentManifold*> manifolds_scratch;
  double time = 0.0;
  std::uint64_t steps = 0;

  // ---- blocks (rigid_world.cpp) ----
  std::vector<BlockSlot> blocks;
  std::vector<std::uint32_t> free_blocks;
  std::size_t block_count = 0;
  // Per block slot, what the per-sub-step passes over every block or joint ask of a block, one byte
  // beside the ~220-byte slots (kept with BlockSlot::alive, fixed and asleep: add_block,
  // remove_block, FarSleep::put_to_sleep, FarSleep::wake). With most of a 29,000-block ridge
  // asleep, those passes read the slots (and each joint's heap slot) only for awake blocks: reading
  // every slot to find that its block sleeps was ~30 % of an idle rigid step (docs/rigid.md, "What
  // a sub-step costs"). kLoaded: the caller loads it (a non-zero ext_force, ext_torque, imp_linear
  // or imp_angular).
  enum : std::uint8_t { kAlive = 1, kFixed = 2, kAsleep = 4, kLoaded = 8 };
  std::vector<std::uint8_t> state;
  std::vector<std::uint32_t> gen;  // BlockSlot::generation, for the checks of asleep(id)
  // contact_forces(): every block's contact forces of the last sub-step, built on first use.
  std::vector<std::uint32_t> cf_start;
  std::vector<std::pair<Vec3, Vec3>> cf_list;  // (point, force)
  std::uint64_t cf_step = UINT64_MAX;

  BlockSlot& block(BlockId id) {
    if (id.index >= blocks.size() || !blocks[id.index].alive ||
        blocks[id.index].generation != id.generation)
      throw std::out_of_range("rigid: stale or invalid BlockId " + std::to_string(id.index));
    return blocks[id.index];
  }
  std::size_t slot_of(const BlockSlot& s) const { return static_cast<std::size_t>(&s - blocks.data()); }
  /// Alive, dynamic and awake: a body the solver moves.
  bool stepped(std::size_t k) const { return (state[k] & (kAlive | kFixed | kAsleep)) == kAlive; }
  void set_loaded(std::size_t k) {
    const BlockSlot& s = blocks[k];
    const bool loaded = !s.ext_force.isZero(0.0) || !s.ext_torque.isZero(0.0) || !s.imp_linear.isZero(0.0) ||
                        !s.imp_angular.isZero(0.0);
    state[k] = static_cast<std::uint8_t>(loaded ? state[k] | kLoaded : state[k] & ~kLoaded);
  }
  btVector3 local_inertia(const BlockSlot& s) const {
    btVector3 in(0, 0, 0);
    s.shape->calculateLocalInertia(s.mass, in);
    return in;
  }

  // ---- joints (joints.cpp) ----
  double tensile_strength = 0.0, shear_strength = 0.0;
  bool joints_breakable = true;  // RigidWorld::set_joints_breakable
  // unique_ptr: btJointFeedback addresses must stay put while Bullet holds them.
  std::vector<std::unique_ptr<JointSlot>> joints;
  std::vector<std::uint32_t> free_joints;
  std::size_t intact_joints = 0, broken_joints = 0;
  // joints_of(): intact joints by block slot, rebuilt when the joints changed (sync_joint_order,
  // set_joint_order).
  std::uint64_t joints_version = 0, jo_version = UINT64_MAX;
  std::vector<std::uint32_t> jo_start, jo_list;
  // The intact joints in slot order as (slot, block a, block b): what check_joints and the far-sleep
  // graph walk every sub-step, without a pointer per joint (JointSlot lives on the heap). Rebuilt
  // when the joints changed (joints_version).
  struct IntactJoint {
    std::uint32_t slot, a, b;
  };
  std::uint64_t ij_version = UINT64_MAX;
  std::vector<IntactJoint> intact;

  JointSlot& joint(JointId id) {
    if (id.index >= joints.size() || !joints[id.index]->alive ||
        joints[id.index]->generation != id.generation)
      throw std::out_of_range("rigid: stale or invalid JointId " + std::to_string(id.index));
    return *joints[id.index];
  }
  const std::vector<IntactJoint>& intact_list();
  std::unique_ptr<btTypedConstraint> spring_joint(BlockSlot& sa, BlockSlot& sb, const FreezeJointDef& d);
  void drop_constraint(JointSlot& j);
  void sync_joint_order();
  void set_joint_order(const JointSlot& j);
  bool overloaded(const JointSlot& j) const {
    return j.load.tension > tensile_strength * j.area || j.load.shear > shear_strength * j.area;
  }
  void check_joints();

  // ---- kinematic meshes (kinematic_mesh.cpp) ----
  std::vector<std::unique_ptr<MeshSlot>> meshes;
  void move_meshes(double h);
  void tally_mesh_loads(double h);

  // ---- far sleep (far_sleep.cpp) ----
  FarSleep sleep;
};

}  // namespace hs::rigid::detail

namespace hs::rigid {

/// RigidWorld's pimpl (private in rigid_world.h) is the state above, which the components'
/// functions name as detail::WorldImpl.
struct RigidWorld::Impl : detail::WorldImpl {};

}  // namespace hs::rigid
