// Bullet adapter for RigidWorld. The only translation unit of hs_rigid that sees bt*.
#include "rigid/rigid_world.h"

#include "common/error.h"
#include "common/state_archive.h"
#include "rigid/box_water.h"
#include "rigid/canonical_world.h"

#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <cstring>
#include <cmath>
#include <stdexcept>
#include <string>

namespace hs::rigid {

namespace {

btVector3 to_bt(const Vec3& v) { return btVector3(v.x(), v.y(), v.z()); }
Vec3 from_bt(const btVector3& v) { return Vec3(v.x(), v.y(), v.z()); }
btQuaternion to_bt(const Quat& q) { return btQuaternion(q.x(), q.y(), q.z(), q.w()); }
Quat from_bt(const btQuaternion& q) { return Quat(q.w(), q.x(), q.y(), q.z()); }

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
  // Far sleep (RigidWorldDef::far_sleep).
  bool asleep = false;
  double still = 0.0;  // s the block and its neighbours have been still
  // While asleep: its body's pose, kept equal to it (put_to_sleep, set_pose; the solve does not
  // move a sleeping block: it has no mass there), so that update_sleep need not read every
  // sleeping body.
  btTransform sleep_pose = btTransform::getIdentity();
};

struct MeshSlot {
  Vec3 origin = Vec3::Zero(), velocity = Vec3::Zero();
  double friction = 0.1;
  std::vector<btScalar> vertices;  // Bullet keeps pointers into these arrays
  std::vector<int> indices;
  std::vector<std::uint16_t> part;
  Vec3 lo = Vec3::Zero(), hi = Vec3::Zero();  // bounding box of the vertices, mesh frame
  std::unique_ptr<btTriangleIndexVertexArray> array;
  std::unique_ptr<btBvhTriangleMeshShape> shape;
  std::unique_ptr<btRigidBody> body;
  MeshLoad load;
};

using detail::kMeshTag;  // user index 2 of a kinematic mesh body (canonical_world.h)

// Far sleep marks a sleeping block's broadphase proxy with this filter-group bit, so that the
// narrowphase can pass over a pair of two sleeping blocks on the proxies alone. Only dynamic blocks
// sleep, and their group already has DefaultFilter set, which every mask (AllFilter, or AllFilter
// minus StaticFilter) has too: the bit never changes which pairs the broadphase makes.
constexpr int kSleepingProxyBit = 1 << 30;

// The dispatcher's near callback under far sleep. Bullet's dispatch visits every overlapping pair;
// on the paper-size ridge nearly all are pairs of two sleeping blocks, for which its
// needsCollision is false (neither is active) after reading both bodies -- 16 % of an idle
// hybrid step. Here such a pair is recognised on its two proxies and skipped; any other pair takes
// Bullet's own path, so the contacts made are the same.
void far_sleep_near_callback(btBroadphasePair& pair, btCollisionDispatcher& d, const btDispatcherInfo& info) {
  if ((pair.m_pProxy0->m_collisionFilterGroup & pair.m_pProxy1->m_collisionFilterGroup & kSleepingProxyBit) != 0)
    return;
  btCollisionDispatcher::defaultNearCallback(pair, d, info);
}

// Friction of a contact: a mesh imposes its own coefficient; two blocks meet with the
// product of their stored square roots (see add_block).
btScalar combined_friction(const btCollisionObject* a, const btCollisionObject* b) {
  if (a->getUserIndex2() == kMeshTag) return a->getFriction();
  if (b->getUserIndex2() == kMeshTag) return b->getFriction();
  return a->getFriction() * b->getFriction();
}

struct JointSlot {
  std::uint32_t slot = 0;  // its index in Impl::joints (and in the world's joint_order)
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

// Checkpoint records (defined with save_state below).
struct BlockRecord;
struct JointRecord;
struct MeshRecord;
struct ManifoldRecord;

}  // namespace

struct RigidWorld::Impl {
  RigidWorldDef def;
  double tensile_strength = 0.0, shear_strength = 0.0;
  bool joints_breakable = true;  // RigidWorld::set_joints_breakable
  std::unique_ptr<btDefaultCollisionConfiguration> config;
  std::unique_ptr<btCollisionDispatcher> dispatcher;
  std::unique_ptr<btDbvtBroadphase> broadphase;
  std::unique_ptr<detail::PooledSolver> solver;
  std::unique_ptr<detail::CanonicalWorld> world;  // solves in a fixed order (canonical_world.h)
  std::vector<btPersistentManifold*> manifolds_scratch;

  std::vector<BlockSlot> blocks;
  std::vector<std::uint32_t> free_blocks;
  std::size_t block_count = 0;
  // unique_ptr: btJointFeedback addresses must stay put while Bullet holds them.
  std::vector<std::unique_ptr<JointSlot>> joints;
  std::vector<std::uint32_t> free_joints;
  std::size_t intact_joints = 0, broken_joints = 0;
  std::vector<std::unique_ptr<MeshSlot>> meshes;
  double time = 0.0;
  std::uint64_t steps = 0;
  // Far sleep.
  std::vector<std::pair<Vec3, Vec3>> wake_boxes;
  std::vector<char> moving, woken, reset, moving_seen;  // per block slot, scratch of update_sleep
  std::vector<std::uint32_t> adj_start, adj, bfs_a, bfs_b;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> edges;  // scratch of update_sleep
  std::size_t asleep_count = 0;
  detail::PairIndex pair_index;  // the overlapping pairs by proxy (far sleep: CanonicalWorld's dispatch)
  // Per block slot, what the per-sub-step passes over every block or joint ask of a block, one byte
  // beside the 344-byte slots (kept with BlockSlot::alive, fixed and asleep: add_block,
  // remove_block, put_to_sleep, wake). With most of a 29,000-block ridge asleep, those passes read
  // the slots (and each joint's heap slot) only for awake blocks: reading every slot to find that
  // its block sleeps was ~30 % of an idle rigid step (docs/rigid.md, "What a sub-step costs").
  // kLoaded: the caller loads it (a non-zero ext_force, ext_torque, imp_linear or imp_angular).
  enum : std::uint8_t { kAlive = 1, kFixed = 2, kAsleep = 4, kLoaded = 8 };
  std::vector<std::uint8_t> state;
  std::vector<std::uint32_t> gen;  // BlockSlot::generation, for the checks of asleep(id)
  std::vector<Vec3> sleep_centre;  // BlockSlot::sleep_pose's origin (update_sleep's wake-zone test)
  // Far sleep's hold (check_sleepers): per block slot, the impulse that the solve gave the block in
  // its first solve asleep (the reference); hold_fresh: the
  // reference is taken at the next solve (the block fell asleep, or a block it touches or is
  // jointed to did, so that the set of its solved contacts and joints changed).
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
  // loads_held: a sleeping block's caller load of this sub-step, taken off the block (a sleeping
  // block is not integrated, so an impulse left on it would add up over the sub-steps it sleeps).
  void hold_caller_load(std::size_t k, double h) {
    BlockSlot& s = blocks[k];
    if (caller_j.size() < blocks.size()) {
      caller_j.resize(blocks.size(), Vec3::Zero());
      caller_l.resize(blocks.size(), Vec3::Zero());
    }
    caller_j[k] = s.imp_linear + h * s.ext_force;
    caller_l[k] = s.imp_angular + h * s.ext_torque;
    s.imp_linear.setZero();
    s.imp_angular.setZero();
    set_loaded(k);
    caller_loaded.push_back(static_cast<std::uint32_t>(k));
  }
  void mark_hold_fresh(std::size_t k) {
    if (!hold_fresh[k]) hold_fresh_list.push_back(static_cast<std::uint32_t>(k));
    hold_fresh[k] = 1;
  }
  void set_loaded(std::size_t k) {
    const BlockSlot& s = blocks[k];
    const bool loaded = !s.ext_force.isZero(0.0) || !s.ext_torque.isZero(0.0) || !s.imp_linear.isZero(0.0) ||
                        !s.imp_angular.isZero(0.0);
    state[k] = static_cast<std::uint8_t>(loaded ? state[k] | kLoaded : state[k] & ~kLoaded);
  }
  void set_sleep_pose(BlockSlot& s, const btTransform& pose) {
    s.sleep_pose = pose;
    sleep_centre[slot_of(s)] = from_bt(pose.getOrigin());
  }
  std::size_t slot_of(const BlockSlot& s) const { return static_cast<std::size_t>(&s - blocks.data()); }
  /// Alive, dynamic and awake: a body the solver moves.
  bool stepped(std::size_t k) const { return (state[k] & (kAlive | kFixed | kAsleep)) == kAlive; }
  // contact_forces(): every block's contact forces of the last sub-step, built on first use.
  std::vector<std::uint32_t> cf_start;
  std::vector<std::pair<Vec3, Vec3>> cf_list;  // (point, force)
  std::uint64_t cf_step = UINT64_MAX;
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
  const std::vector<IntactJoint>& intact_list() {
    if (ij_version != joints_version) {
      intact.clear();
      for (const auto& jp : joints) {
        const JointSlot& j = *jp;
        if (j.alive && !j.broken && j.constraint) intact.push_back({j.slot, j.a.index, j.b.index});
      }
      ij_version = joints_version;
    }
    return intact;
  }

  BlockSlot& block(BlockId id) {
    if (id.index >= blocks.size() || !blocks[id.index].alive ||
        blocks[id.index].generation != id.generation)
      throw std::out_of_range("rigid: stale or invalid BlockId " + std::to_string(id.index));
    return blocks[id.index];
  }
  JointSlot& joint(JointId id) {
    if (id.index >= joints.size() || !joints[id.index]->alive ||
        joints[id.index]->generation != id.generation)
      throw std::out_of_range("rigid: stale or invalid JointId " + std::to_string(id.index));
    return *joints[id.index];
  }

  // A freeze joint as six damped springs (RigidWorldDef::joint_stiffness): a frame at the anchor
  // with x along the normal, all six axes free (lower limit > upper) with a spring at rest in the
  // current pose. Normal and shear: k = s A; bending (frame y, z): s I; twist (x): s 2 I, with
  // I = A^2 / (4 pi) for a disc of area A. Damping c = 2 zeta sqrt(k m), m the reduced mass
  // (linear) or reduced inertia about the axis through the anchor (angular), as Bullet's spring
  // rows see them.
  std::unique_ptr<btTypedConstraint> spring_joint(BlockSlot& sa, BlockSlot& sb, const FreezeJointDef& d) {
    btRigidBody& A = *sa.body;
    btRigidBody& B = *sb.body;
    const Vec3 n = d.normal.normalized();
    const Quat q = Quat::FromTwoVectors(Vec3::UnitX(), n);
    const btTransform frame(btQuaternion(q.x(), q.y(), q.z(), q.w()), to_bt(d.anchor));
    auto c = std::make_unique<btGeneric6DofSpring2Constraint>(A, B, A.getWorldTransform().inverse() * frame,
                                                              B.getWorldTransform().inverse() * frame);
    c->setLinearLowerLimit(btVector3(1, 1, 1));
    c->setLinearUpperLimit(btVector3(-1, -1, -1));
    c->setAngularLowerLimit(btVector3(1, 1, 1));
    c->setAngularUpperLimit(btVector3(-1, -1, -1));
    const double s = def.joint_stiffness, I = d.area * d.area / (4.0 * 3.14159265358979323846);
    const Mat3 R = q.toRotationMatrix();
    auto reduced = [](double a, double b) { return a > 0.0 && b > 0.0 ? a * b / (a + b) : std::max(a, b); };
    // A sleeping block has no mass in the solve (put_to_sleep): its awake values (solve_mass).
    auto mass = [&](const btRigidBody& b) {
      const SolveMass sm = solve_mass(b);
      return sm.inv_mass > 0.0 ? 1.0 / sm.inv_mass : 0.0;
    };
    auto inertia = [&](const btRigidBody& b, const Vec3& axis) {  // about `axis` through the anchor
      const SolveMass sm = solve_mass(b);
      if (!(sm.inv_mass > 0.0)) return 0.0;
      const Vec3 r = d.anchor - from_bt(b.getCenterOfMassPosition());
      return mass(b) * r.squaredNorm() + 1.0 / from_bt(sm.inv_inertia_world * to_bt(axis)).norm();
    };
    for (int k = 0; k < 6; ++k) {
      const double kk = k < 3 ? s * d.area : s * (k == 3 ? 2.0 * I : I);
      const double me = k < 3 ? reduced(mass(A), mass(B))
                              : reduced(inertia(A, R.col(k - 3)), inertia(B, R.col(k - 3)));
      c->enableSpring(k, true);
      c->setStiffness(k, kk);
      // Damped for the stiffness Bullet will use: it softens a spring to m / (16 dt^2) when
      // omega dt > 0.25 (small blocks at the hybrid's step), which would raise the ratio.
      const double k_used = std::min(kk, me / (16.0 * def.dt * def.dt));
      c->setDamping(k, 2.0 * def.joint_damping_ratio * std::sqrt(k_used * me));
    }
    c->setEquilibriumPoint();
    return c;
  }

  void drop_constraint(JointSlot& j) {
    if (j.constraint) {
      world->removeConstraint(j.constraint.get());
      j.constraint.reset();
      --intact_joints;
      set_joint_order(j);
    }
  }

  /// The world solves joints in slot (creation) order, whatever order removals left its array in.
  void sync_joint_order() {
    ++joints_version;
    world->joint_order.clear();
    for (const auto& jp : joints) world->joint_order.push_back(jp->constraint.get());
  }
  /// The same for one slot that changed (made, remade or dropped): O(1) where the whole rebuild
  /// made adding the paper-size ridge's 78,000 joints quadratic (~15 s of the bench's set-up).
  void set_joint_order(const JointSlot& j) {
    ++joints_version;
    auto& order = world->joint_order;
    if (j.slot == order.size()) order.push_back(j.constraint.get());
    else order.at(j.slot) = j.constraint.get();
  }

  bool overloaded(const JointSlot& j) const {
    return j.load.tension > tensile_strength * j.area || j.load.shear > shear_strength * j.area;
  }

  void check_joints() {
    // Slot order, as over `joints`. A joint broken here makes the list stale (drop_constraint bumps
    // joints_version) but each slot comes once, so the rest of this pass is still right.
    for (const IntactJoint& ij : intact_list()) {
      // Two sleeping blocks: the joint was not solved, its feedback and pose are unchanged since
      // it was last checked (and held).
      if ((state[ij.a] & kAsleep) && (state[ij.b] & kAsleep)) continue;
      JointSlot& j = *joints[ij.slot];
      const btRigidBody& ba = *blocks[j.a.index].body;
      const Vec3 n = from_bt(ba.getWorldTransform().getBasis() * to_bt(j.normal_in_a));
      const Vec3 fb = from_bt(j.feedback.m_appliedForceBodyB);
      const double fn = fb.dot(n);
      j.load.tension = -fn;
      j.load.shear = (fb - fn * n).norm();
      if (joints_breakable && overloaded(j)) {
        j.broken = true;
        drop_constraint(j);
        ++broken_joints;
      }
    }
  }

  // ---- far sleep (RigidWorldDef::far_sleep) ----
  // A sleeping block is a static object to Bullet (CF_STATIC_OBJECT: the solver meets it as an
  // immovable body, it is neither integrated nor given gravity) and ISLAND_SLEEPING (its pairs
  // with other sleeping blocks are not collided, its bounding box not updated); awake blocks are
  // DISABLE_DEACTIVATION as without the rule. Bullet's own island sleeping is switched off
  // (CanonicalWorld::managed_sleep).
  // load_state's parts (defined with it).
  void restore_joints(const std::vector<JointRecord>& joints);
  void restore_blocks(const std::vector<BlockRecord>& blocks);
  std::vector<char> wake_for_restore(const std::vector<double>& still);
  void restore_holds(const StateArchive& a, const std::string& p);
  void restore_meshes(const std::vector<MeshRecord>& meshes, const std::vector<Vec3>& loads,
                      const std::vector<std::uint64_t>& contacts);
  std::size_t restore_manifolds(const std::vector<ManifoldRecord>& saved, const std::vector<btManifoldPoint>& points);

  // A block's inverse mass and world inverse inertia as the solver sees it awake, bit for bit what
  // Bullet holds for an awake body (setMassProps, updateInertiaTensor); a sleeping body holds zeros.
  struct SolveMass {
    double inv_mass = 0.0;
    btMatrix3x3 inv_inertia_world;
  };
  btVector3 local_inertia(const BlockSlot& s) const {
    btVector3 in(0, 0, 0);
    s.shape->calculateLocalInertia(s.mass, in);
    return in;
  }
  SolveMass solve_mass(const btRigidBody& b) const {
    SolveMass sm;
    if (b.getInvMass() > 0.0 || b.getUserIndex2() == kMeshTag) {
      sm.inv_mass = b.getInvMass();
      sm.inv_inertia_world = b.getInvInertiaTensorWorld();
      return sm;
    }
    const BlockSlot& s = blocks[static_cast<std::size_t>(b.getUserIndex())];
    sm.inv_inertia_world.setValue(0, 0, 0, 0, 0, 0, 0, 0, 0);
    if (!(s.mass > 0.0)) return sm;
    sm.inv_mass = 1.0 / s.mass;
    const btVector3 in = local_inertia(s);
    const btVector3 inv(in.x() != 0.0 ? 1.0 / in.x() : 0.0, in.y() != 0.0 ? 1.0 / in.y() : 0.0,
                        in.z() != 0.0 ? 1.0 / in.z() : 0.0);
    const btMatrix3x3& basis = b.getWorldTransform().getBasis();
    sm.inv_inertia_world = basis.scaled(inv) * basis.transpose();
    return sm;
  }

  void put_to_sleep(BlockSlot& s) {
    btRigidBody& b = *s.body;
    b.setLinearVelocity(btVector3(0, 0, 0));
    b.setAngularVelocity(btVector3(0, 0, 0));
    // Immovable in the solve (a fixed solver body: Bullet takes a body without inverse mass as one)
    // until it wakes: an awake block resting on it is held, and its steady load is the hold
    // reference (check_sleepers) against which an impact is told apart.
    b.setMassProps(0.0, btVector3(0, 0, 0));
    b.updateInertiaTensor();
    mark_hold_fresh(slot_of(s));
    b.setCollisionFlags(b.getCollisionFlags() | btCollisionObject::CF_STATIC_OBJECT);
    b.forceActivationState(ISLAND_SLEEPING);
    world->updateSingleAabb(&b);  // a static box at its pose (a restored world computes the same)
    b.getBroadphaseHandle()->m_collisionFilterGroup |= kSleepingProxyBit;
    set_sleep_pose(s, b.getWorldTransform());
    s.asleep = true;
    state[slot_of(s)] |= kAsleep;
    ++asleep_count;
  }
  void wake(BlockSlot& s) {
    s.still = 0.0;
    if (!s.asleep) return;
    btRigidBody& b = *s.body;
    b.setMassProps(s.mass, local_inertia(s));  // the bits it was built with
    b.updateInertiaTensor();
    b.setGravity(world->getGravity());          // as addRigidBody set it (g / inverse mass)
    b.setCollisionFlags(b.getCollisionFlags() & ~btCollisionObject::CF_STATIC_OBJECT);
    b.forceActivationState(DISABLE_DEACTIVATION);
    b.getBroadphaseHandle()->m_collisionFilterGroup &= ~kSleepingProxyBit;
    s.asleep = false;
    state[slot_of(s)] &= static_cast<std::uint8_t>(~kAsleep);
    --asleep_count;
  }
  // Before a solve: the joints it takes (CanonicalWorld::awake_joints), intact, enabled, with a
  // block that is neither fixed nor asleep -- what the world's own filter over joint_order finds.
  void collect_awake_joints() {
    auto& aj = world->awake_joints;
    aj.clear();
    for (const IntactJoint& ij : intact_list()) {
      if (!stepped(ij.a) && !stepped(ij.b)) continue;  // before touching the joint's heap slot
      btTypedConstraint* c = joints[ij.slot]->constraint.get();
      if (c->isEnabled()) aj.push_back(c);
    }
  }
  // After each solve (CanonicalWorld::after_solve): the sleeping blocks it took (a contact or a
  // joint with an awake block; a mesh's contact with a sleeping block is not solved: both have no
  // mass there, and wake_distance keeps meshes away from sleeping blocks, error (3)). A sleeping
  // block is immovable in the solve, so what the solve gives it is the load that holds it; a
  // steady load is held. The first solve after it fell
  // asleep (or after a block it touches did) gives its reference. When the load departs from the
  // reference by more than the block, free, would take in one solve to move faster than `speed`
  // (|dJ| / m > speed), something hit or pulled it: it wakes, and the sub-step's
  // solve is done again from the state before it with the block awake (returns true), so that an
  // impact passes its momentum on as with every block awake, also along a chain of blocks woken
  // one after the other within the sub-step. Only the impulse is compared, not its moment: the
  // moment of a resting contact's impulse wanders as the solver shares it among the contact points
  // (on the keel ridge at rest a test on the rim speed |I^-1 dL| |h| woke 770 blocks in 0.6 s,
  // this one 25; docs/rigid.md "Far sleep").
  bool check_sleepers(bool may_repeat) {
    if (asleep_count == 0 && hold_fresh_list.empty() && touched_before.empty()) return false;
    const double h = def.dt;
    touched.clear();
    auto take_slot = [&](std::size_t k, const Vec3& j) {
      if (!(state[k] & kAsleep)) return;
      if (!solve_seen[k]) {
        solve_seen[k] = 1;
        touched.push_back(static_cast<std::uint32_t>(k));
      }
      solve_j[k] += j;
    };
    auto take = [&](const btCollisionObject* o, const Vec3& j) {
      if (o->getUserIndex2() != kMeshTag) take_slot(static_cast<std::size_t>(o->getUserIndex()), j);
    };
    for (const btPersistentManifold* man : world->solved_manifolds()) {
      const btCollisionObject* b0 = man->getBody0();
      const btCollisionObject* b1 = man->getBody1();
      const bool s0 = is_block(b0) && (state[static_cast<std::size_t>(b0->getUserIndex())] & kAsleep);
      const bool s1 = is_block(b1) && (state[static_cast<std::size_t>(b1->getUserIndex())] & kAsleep);
      if (!s0 && !s1) continue;
      for (int c = 0; c < man->getNumContacts(); ++c) {
        const btManifoldPoint& p = man->getContactPoint(c);
        const Vec3 j = from_bt(p.m_normalWorldOnB * p.m_appliedImpulse +
                               p.m_lateralFrictionDir1 * p.m_appliedImpulseLateral1 +
                               p.m_lateralFrictionDir2 * p.m_appliedImpulseLateral2);  // on body 0
        if (s0) take(b0, j);
        if (s1) take(b1, -j);
      }
    }
    for (const btTypedConstraint* c : world->awake_joints) {
      const btJointFeedback* fb = c->getJointFeedback();
      if (!fb) continue;
      const btRigidBody& A = c->getRigidBodyA();
      const btRigidBody& B = c->getRigidBodyB();
      if (is_block(&A)) take(&A, from_bt(fb->m_appliedForceBodyA) * h);
      if (is_block(&B)) take(&B, from_bt(fb->m_appliedForceBodyB) * h);
    }
    for (const std::uint32_t k : caller_loaded) take_slot(k, caller_j[k]);  // loads_held
    // The test: every sleeper the solve took, and those the last sub-step's solve took (a load
    // that went away), against its reference; not those whose reference is taken now.
    to_wake.clear();
    const double v = def.far_sleep.speed;
    auto test = [&](std::uint32_t k) {
      if (!(state[k] & kAsleep) || hold_fresh[k]) return;
      const double m = blocks[k].mass;
      const double lim = m * v + (k < allow.size() ? allow[k] : 0.0);
      if ((solve_j[k] - hold_j[k]).squaredNorm() > lim * lim) to_wake.push_back(k);
    };
    for (const std::uint32_t k : touched) test(k);
    for (const std::uint32_t k : touched_before)
      if (!solve_seen[k]) test(k);
    std::sort(to_wake.begin(), to_wake.end());
    to_wake.erase(std::unique(to_wake.begin(), to_wake.end()), to_wake.end());
    // Without a repeat left (CanonicalWorld::max_repeats) the woken blocks stopped the impulse in
    // this sub-step as immovable ones (the rule's error (1), docs/rigid.md).
    const bool repeat = !to_wake.empty() && may_repeat;
    sleepers_woken_by_solve += to_wake.size();
    for (const std::uint32_t k : to_wake) {
      wake(blocks[k]);
      allow_neighbours(blocks[k]);
      if (k < caller_j.size() && (!caller_j[k].isZero(0.0) || !caller_l[k].isZero(0.0))) {
        // loads_held: the caller's load of this sub-step, as a stepped block takes it (before the solve)
        blocks[k].body->applyCentralImpulse(to_bt(caller_j[k]));
        blocks[k].body->applyTorqueImpulse(to_bt(caller_l[k]));
        caller_j[k].setZero();
        caller_l[k].setZero();
      }
      if (repeat) world->stepped.push_back(blocks[k].body.get());
    }
    if (!repeat) {  // the sub-step's last solve: references taken, the sleepers it took kept
      for (const std::uint32_t k : hold_fresh_list) {
        if (state[k] & kAsleep) hold_j[k] = solve_j[k];
        hold_fresh[k] = 0;
      }
      for (const std::uint32_t k : allow_list) {  // (allow_neighbours: moved by the allowance at most)
        if ((state[k] & kAsleep) && !hold_fresh[k]) {
          const Vec3 d = solve_j[k] - hold_j[k];
          const double n = d.norm();
          hold_j[k] += n <= allow[k] ? d : (allow[k] / n) * d;
        }
        allow[k] = 0.0;
      }
      allow_list.clear();
      hold_fresh_list.clear();
      touched_before = touched;
    }
    for (const std::uint32_t k : touched) {  // (solve_seen marks only `touched`)
      solve_j[k].setZero();
      solve_seen[k] = 0;
    }
    if (repeat) {
      for (const std::uint32_t k : to_wake) collide_with_inactive(blocks[k]);
      collect_awake_joints();  // the woken blocks' joints to sleeping ones are solved now
    }
    return repeat;
  }
  // A block woken by a solve (check_sleepers), before the repeat: its pairs with inactive bodies
  // (sleeping blocks, and fixed ones if inactive) were not collided this step -- never, for blocks
  // that started asleep (start_asleep) -- so their contacts would be missing or stale in the
  // repeated solve. They are collided now, as this step's collision pass would have done had the
  // block been awake (its pose is the one it slept at; the repeat saves the new points first).
  void collide_with_inactive(BlockSlot& s) {
    btBroadphaseProxy* p = s.body->getBroadphaseHandle();
    btOverlappingPairCache* cache = broadphase->getOverlappingPairCache();
    const btDispatcherInfo& info = world->getDispatchInfo();
    for (btBroadphaseProxy* q : pair_index.partners(p)) {
      const auto* o = static_cast<const btCollisionObject*>(q->m_clientObject);
      if (!is_block(o) || o->isActive()) continue;  // an active partner was collided this step
      if (btBroadphasePair* pair = cache->findPair(p, q)) dispatcher->getNearCallback()(*pair, *dispatcher, info);
    }
  }
  // The sleeping blocks that s touches (an overlapping pair) or is jointed to, each once or more.
  template <class F>
  void for_sleeping_neighbours(BlockSlot& s, F&& f) {
    btRigidBody& b = *s.body;
    for (const btBroadphaseProxy* q : pair_index.partners(b.getBroadphaseHandle())) {
      const auto* o = static_cast<const btCollisionObject*>(q->m_clientObject);
      if (is_block(o) && (state[static_cast<std::size_t>(o->getUserIndex())] & kAsleep))
        f(static_cast<std::size_t>(o->getUserIndex()));
    }
    for (int i = 0; i < b.getNumConstraintRefs(); ++i) {
      const btTypedConstraint* c = b.getConstraintRef(i);
      const btRigidBody& o = &c->getRigidBodyA() == &b ? c->getRigidBodyB() : c->getRigidBodyA();
      if (is_block(&o) && (state[static_cast<std::size_t>(o.getUserIndex())] & kAsleep))
        f(static_cast<std::size_t>(o.getUserIndex()));
    }
  }
  // A block fell asleep: its contacts and joints with sleeping blocks are no longer solved, so those
  // blocks' references are taken again at the next solve (check_sleepers).
  void fresh_neighbours(BlockSlot& s) {
    for_sleeping_neighbours(s, [&](std::size_t k) { mark_hold_fresh(k); });
  }
  // A sleeping block woke: while both slept, its sleeping neighbours held its weight and buoyancy
  // unsolved; now the solve hands that static load to them through their contacts and joints with
  // it, and a neighbour's reference, taken while it was not solved, does not contain it. So each
  // neighbour may depart from its reference by the woken block's net static load (weight and water
  // load at rest) times the sub-step, on top of m speed, for the rest of the sub-step, and its
  // reference moves toward the load of the sub-step's last solve by that much at most
  // (check_sleepers): what else the woken block passes on (a push, a caller's load) stays a change.
  // Without it every wake-up woke the neighbours below and above the woken block (docs/rigid.md,
  // "Far sleep").
  std::vector<double> allow;
  std::vector<std::uint32_t> allow_list;
  void allow_neighbours(BlockSlot& s) {
    const btTransform& tr = s.body->getWorldTransform();
    Vec3 f = s.mass * def.gravity;
    if (def.water) {
      BoxWaterParams wp;
      wp.level = def.water_level;
      wp.density = def.water_density;
      wp.linear_drag = def.linear_drag;
      wp.drag_coefficient = def.quadratic_drag_cd;
      f += box_water_load(wp, -def.gravity.z(), s.half, from_bt(tr.getOrigin()), from_bt(tr.getRotation()),
                          Vec3::Zero(), Vec3::Zero())
               .force;
    }
    const double a = f.norm() * def.dt;
    if (allow.size() < blocks.size()) allow.resize(blocks.size(), 0.0);
    for_sleeping_neighbours(s, [&](std::size_t k) {
      if (allow[k] == 0.0) allow_list.push_back(static_cast<std::uint32_t>(k));
      allow[k] += a;
    });
  }
  bool block_moving(const BlockSlot& s) const {
    const double v = def.far_sleep.speed;
    const btRigidBody& b = *s.body;
    return b.getLinearVelocity().length2() > v * v ||
           b.getAngularVelocity().length2() * s.half.squaredNorm() > v * v;
  }
  bool in_wake_zone(const Vec3& c) const {
    const double d = def.far_sleep.wake_distance;
    for (const auto& mp : meshes) {
      const Vec3 lo = mp->origin + mp->lo - Vec3::Constant(d), hi = mp->origin + mp->hi + Vec3::Constant(d);
      if ((c.array() >= lo.array()).all() && (c.array() <= hi.array()).all()) return true;
    }
    for (const auto& [lo, hi] : wake_boxes)
      if ((c.array() >= lo.array()).all() && (c.array() <= hi.array()).all()) return true;
    return false;
  }
  static bool is_block(const btCollisionObject* o) { return o->getUserIndex2() != kMeshTag; }

  // The far-sleep rule (rigid_world.h) on the state at the start of a sub-step. Every decision is
  // taken from that state (flags first, then applied), so the order of the loops does not matter.
  void update_sleep(double h) {
    const std::size_t n = blocks.size();
    moving.assign(n, 0);
    woken.assign(n, 0);
    reset.assign(n, 0);
    for (std::size_t k = 0; k < n; ++k) {
      const std::uint8_t st = state[k];
      if ((st & (kAlive | kFixed)) != kAlive) continue;
      // (a sleeping block's slot is not read: its centre and flags are kept beside it)
      const bool asleep = st & kAsleep;
      if (!asleep) moving[k] = block_moving(blocks[k]);
      // (2: awake, but not a seed of the hops below: a block the caller loads that does not move;
      // its load reaches a sleeping neighbour through the solve, check_sleepers)
      if (in_wake_zone(asleep ? sleep_centre[k] : from_bt(blocks[k].body->getWorldTransform().getOrigin())))
        woken[k] = def.far_sleep.zone_wakes_neighbours ? 1 : 2;
      else if ((st & kLoaded) && !def.far_sleep.loads_held)
        woken[k] = def.far_sleep.loads_wake_neighbours ? 1 : 2;
    }
    // Every block within wake_hops contacts or joints of a moving block (or of one the caller loads
    // now) is woken, or kept from falling asleep: the solver carries an impulse a few blocks per
    // sub-step, and a sleeping block on its way would stop it like a wall. Breadth first, level by
    // level, so the order of the graph does not matter.
    std::vector<std::uint32_t>& front = bfs_a;
    std::vector<std::uint32_t>& next = bfs_b;
    front.clear();
    for (std::size_t k = 0; k < n; ++k)
      if (moving[k] || woken[k] == 1) front.push_back(static_cast<std::uint32_t>(k));
    std::vector<char>& seen = moving_seen;
    seen.assign(n, 0);
    for (const std::uint32_t k : front) seen[k] = 1;
    if (!front.empty() && def.far_sleep.wake_hops > 0) {
      // The neighbour graph (none needed without a seed): blocks touching (a manifold with a
      // point) or jointed (an intact joint), as an edge list (one pass over the manifolds) turned
      // into adjacency lists by counting. The BFS gives the same sets in any edge order.
      edges.clear();
      const int nm = dispatcher->getNumManifolds();
      for (int k = 0; k < nm; ++k) {
        const btPersistentManifold* man = dispatcher->getManifoldByIndexInternal(k);
        if (man->getNumContacts() == 0 || !is_block(man->getBody0()) || !is_block(man->getBody1())) continue;
        const auto a = static_cast<std::uint32_t>(man->getBody0()->getUserIndex());
        const auto b = static_cast<std::uint32_t>(man->getBody1()->getUserIndex());
        if (!blocks[a].fixed && !blocks[b].fixed) edges.emplace_back(a, b);
      }
      for (const IntactJoint& j : intact_list())
        if (!blocks[j.a].fixed && !blocks[j.b].fixed) edges.emplace_back(j.a, j.b);
      adj_start.assign(n + 1, 0);
      for (const auto& [a, b] : edges) {
        ++adj_start[a + 1];
        ++adj_start[b + 1];
      }
      for (std::size_t k = 0; k < n; ++k) adj_start[k + 1] += adj_start[k];
      adj.resize(adj_start[n]);
      {
        std::vector<std::uint32_t>& fill = bfs_b;  // free until the BFS
        fill.assign(adj_start.begin(), adj_start.end() - 1);
        for (const auto& [a, b] : edges) {
          adj[fill[a]++] = b;
          adj[fill[b]++] = a;
        }
      }
    }
    for (int hop = 0; hop < def.far_sleep.wake_hops && !front.empty(); ++hop) {
      next.clear();
      for (const std::uint32_t a : front)
        for (std::uint32_t e = adj_start[a]; e < adj_start[a + 1]; ++e) {
          const std::uint32_t b = adj[e];
          if (seen[b]) continue;
          seen[b] = 1;
          ((state[b] & kAsleep) ? woken[b] : reset[b]) = 1;
          next.push_back(b);
        }
      std::swap(front, next);
    }
    for (std::size_t k = 0; k < n; ++k) {
      if ((state[k] & (kAlive | kFixed)) != kAlive) continue;
      if (woken[k] || reset[k] || moving[k]) {
        const bool was_asleep = state[k] & kAsleep;
        wake(blocks[k]);
        if (was_asleep) allow_neighbours(blocks[k]);
      } else if (!(state[k] & kAsleep)) {
        BlockSlot& s = blocks[k];
        s.still += h;
        if (s.still >= def.far_sleep.still_time) {
          put_to_sleep(s);
          fresh_neighbours(s);
        }
      }
    }
  }

  // Sums the impulses the solver applied at every contact point of a mesh body during
  // the last step. Bullet applies +(n j_n + d1 j_1 + d2 j_2) to body 0 of a manifold and
  // the opposite to body 1 (n = m_normalWorldOnB, d1, d2 the friction directions).
  void tally_mesh_loads(double h) {
    for (auto& mp : meshes) {
      MeshLoad& L = mp->load;
      L.force.setZero();
      L.moment.setZero();
      std::fill(L.part_force.begin(), L.part_force.end(), Vec3::Zero());
      std::fill(L.part_moment.begin(), L.part_moment.end(), Vec3::Zero());
      L.contacts = 0;
    }
    if (meshes.empty()) return;
    detail::sorted_manifolds_if(dispatcher.get(), manifolds_scratch,  // a fixed summation order
                                [](const btPersistentManifold* man) {
                                  return (man->getBody0()->getUserIndex2() == kMeshTag) !=
                                         (man->getBody1()->getUserIndex2() == kMeshTag);
                                });
    for (const btPersistentManifold* man : manifolds_scratch) {
      const btCollisionObject* b0 = man->getBody0();
      const btCollisionObject* b1 = man->getBody1();
      const bool mesh0 = b0->getUserIndex2() == kMeshTag, mesh1 = b1->getUserIndex2() == kMeshTag;
      if (mesh0 == mesh1) continue;
      MeshSlot& ms = *meshes[static_cast<std::size_t>((mesh0 ? b0 : b1)->getUserIndex())];
      const double sign = mesh0 ? 1.0 : -1.0;  // impulse on the mesh = sign * (impulse on body 0)
      for (int c = 0; c < man->getNumContacts(); ++c) {
        const btManifoldPoint& p = man->getContactPoint(c);
        if (p.m_appliedImpulse == 0.0 && p.m_appliedImpulseLateral1 == 0.0 &&
            p.m_appliedImpulseLateral2 == 0.0)
          continue;
        const Vec3 j = from_bt(p.m_normalWorldOnB * p.m_appliedImpulse +
                               p.m_lateralFrictionDir1 * p.m_appliedImpulseLateral1 +
                               p.m_lateralFrictionDir2 * p.m_appliedImpulseLateral2);
        const Vec3 f = sign * j / h;
        const Vec3 at = from_bt(mesh0 ? p.getPositionWorldOnA() : p.getPositionWorldOnB());
        const Vec3 m = (at - ms.origin).cross(f);
        MeshLoad& L = ms.load;
        L.force += f;
        L.moment += m;
        ++L.contacts;
        const int tri = mesh0 ? p.m_index0 : p.m_index1;
        const std::size_t part =
            (tri >= 0 && static_cast<std::size_t>(tri) < ms.part.size()) ? ms.part[tri] : 0;
        L.part_force[part] += f;
        L.part_moment[part] += m;
      }
    }
  }
};

RigidWorld::RigidWorld(const RigidWorldDef& def) : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  if (!(def.dt > 0.0)) throw InputError("rigid/dt", "must be > 0");
  if (def.friction < 0.0) throw InputError("rigid/friction", "must be >= 0");
  if (def.freeze_bond_strength < 0.0)
    throw InputError("rigid/freeze_bond_strength", "must be >= 0 (Pa)");
  if (!(def.joint_stiffness >= 0.0) || !std::isfinite(def.joint_stiffness))
    throw InputError("rigid/joint_stiffness", "must be >= 0 (Pa/m; 0 = rigid joints)");
  if (!(def.joint_damping_ratio >= 0.0) || !std::isfinite(def.joint_damping_ratio))
    throw InputError("rigid/joint_damping_ratio", "must be >= 0");
  m.def = def;
  m.tensile_strength = def.freeze_bond_strength;
  m.shear_strength =
      def.freeze_bond_shear_strength < 0.0 ? def.freeze_bond_strength : def.freeze_bond_shear_strength;
  m.config = std::make_unique<btDefaultCollisionConfiguration>();
  m.dispatcher = std::make_unique<btCollisionDispatcher>(m.config.get());
  m.broadphase = std::make_unique<btDbvtBroadphase>();
  m.solver = std::make_unique<detail::PooledSolver>();
  m.solver->friction_sees_torque = def.friction_sees_torque;
  m.world = std::make_unique<detail::CanonicalWorld>(m.dispatcher.get(), m.broadphase.get(), m.solver.get(),
                                                     m.config.get());
  m.world->setGravity(to_bt(def.gravity));
  gCalculateCombinedFrictionCallback = &combined_friction;
  m.world->getSolverInfo().m_numIterations = std::max(1, def.solver_iterations);
  if (def.contact_erp > 0.0) m.world->getSolverInfo().m_erp2 = def.contact_erp;
  if (def.joint_erp > 0.0) m.world->getSolverInfo().m_erp = def.joint_erp;
  if (!(def.split_impulse_depth >= 0.0)) throw InputError("rigid/split_impulse_depth", "must be >= 0 (m)");
  m.world->getSolverInfo().m_splitImpulse = true;
  m.world->getSolverInfo().m_splitImpulsePenetrationThreshold = -def.split_impulse_depth;
  if (def.far_sleep.enabled) {
    const auto& fs = def.far_sleep;
    if (def.allow_sleep)
      throw InputError("rigid/far_sleep", "far sleep and Bullet's island sleeping (allow_sleep) exclude each other");
    if (!(fs.wake_distance >= 0.0) || !std::isfinite(fs.wake_distance))
      throw InputError("rigid/far_sleep/wake_distance", "must be a finite distance >= 0 (m)");
    if (!(fs.speed > 0.0) || !std::isfinite(fs.speed))
      throw InputError("rigid/far_sleep/speed", "must be a finite speed > 0 (m/s)");
    if (fs.wake_hops < 0) throw InputError("rigid/far_sleep/wake_hops", "must be >= 0");
    if (!(fs.still_time >= 0.0) || !std::isfinite(fs.still_time))
      throw InputError("rigid/far_sleep/still_time", "must be a finite time >= 0 (s)");
    m.world->managed_sleep = true;
    m.world->setForceUpdateAllAabbs(false);  // sleeping blocks keep theirs
    m.dispatcher->setNearCallback(&far_sleep_near_callback);
    m.broadphase->getOverlappingPairCache()->setInternalGhostPairCallback(&m.pair_index);
    m.world->pair_index = &m.pair_index;
    Impl* impl = &m;
    m.world->after_solve = [impl](bool may_repeat) { return impl->check_sleepers(may_repeat); };
  }
  if (def.fixed_friction_directions)
    m.world->getSolverInfo().m_solverMode |= SOLVER_USE_2_FRICTION_DIRECTIONS |
                                             SOLVER_ENABLE_FRICTION_DIRECTION_CACHING |
                                             SOLVER_DISABLE_VELOCITY_DEPENDENT_FRICTION_DIRECTION;
}

RigidWorld::~RigidWorld() {
  Impl& m = *impl_;
  m.world->release_all();  // every joint and body out of the world, in linear time
  m.meshes.clear();
  m.joints.clear();
  m.blocks.clear();
  m.world.reset();
  m.solver.reset();
  m.broadphase.reset();
  m.dispatcher.reset();
  m.config.reset();
}

const RigidWorldDef& RigidWorld::def() const { return impl_->def; }

BlockId RigidWorld::add_block(const BlockDef& d) {
  Impl& m = *impl_;
  if (!(d.half_extents.minCoeff() > 0.0))
    throw InputError("block/half_extents", "must all be > 0 (m)");
  if (!d.fixed && !(d.density > 0.0)) throw InputError("block/density", "must be > 0 (kg/m^3)");
  std::uint32_t idx;
  if (!m.free_blocks.empty()) {
    idx = m.free_blocks.back();
    m.free_blocks.pop_back();
  } else {
    idx = static_cast<std::uint32_t>(m.blocks.size());
    m.blocks.emplace_back();
    m.state.push_back(0);
    m.gen.push_back(0);
    m.sleep_centre.emplace_back(Vec3::Zero());
    m.hold_j.emplace_back(Vec3::Zero());
    m.hold_fresh.push_back(0);
    m.solve_j.emplace_back(Vec3::Zero());
    m.solve_seen.push_back(0);
  }
  BlockSlot& s = m.blocks[idx];
  s.alive = true;
  s.fixed = d.fixed;
  s.half = d.half_extents;
  s.mass = d.fixed ? 0.0 : d.density * 8.0 * d.half_extents.prod();
  s.shape = std::make_unique<btBoxShape>(to_bt(d.half_extents));
  // btBoxShape keeps the margin inside the half extents (rounded edges, flat faces in
  // place); box–box pairs use btBoxBoxDetector on the full box.
  s.shape->setMargin(std::min(m.def.collision_margin, 0.2 * d.half_extents.minCoeff()));
  btVector3 inertia(0, 0, 0);
  if (!d.fixed) s.shape->calculateLocalInertia(s.mass, inertia);
  btRigidBody::btRigidBodyConstructionInfo info(s.mass, nullptr, s.shape.get(), inertia);
  info.m_startWorldTransform = btTransform(to_bt(d.orientation.normalized()), to_bt(d.position));
  // Bullet combines two bodies' coefficients as a product: store sqrt so that two
  // blocks with the same coefficient meet with exactly that coefficient.
  const double mu = d.friction < 0.0 ? m.def.friction : d.friction;
  info.m_friction = std::sqrt(mu);
  info.m_restitution = std::sqrt(std::max(0.0, m.def.restitution));
  info.m_linearDamping = 0.0;
  info.m_angularDamping = 0.0;
  s.body = std::make_unique<btRigidBody>(info);
  if (!d.fixed) {
    s.body->setLinearVelocity(to_bt(d.velocity));
    s.body->setAngularVelocity(to_bt(d.angular_velocity));
    if (d.linear_factor != Vec3::Ones()) s.body->setLinearFactor(to_bt(d.linear_factor));
    if (d.angular_factor != Vec3::Ones()) s.body->setAngularFactor(to_bt(d.angular_factor));
    if (!m.def.allow_sleep)
      s.body->setActivationState(DISABLE_DEACTIVATION);
    else
      s.body->setSleepingThresholds(m.def.sleep_linear_velocity, m.def.sleep_angular_velocity);
  }
  s.body->setUserIndex(static_cast<int>(idx));
  s.asleep = false;
  m.state[idx] = static_cast<std::uint8_t>(d.fixed ? Impl::kAlive | Impl::kFixed : Impl::kAlive);
  m.gen[idx] = s.generation;
  s.still = m.def.far_sleep.enabled && m.def.far_sleep.start_asleep ? m.def.far_sleep.still_time : 0.0;
  m.world->addRigidBody(s.body.get());
  ++m.block_count;
  m.cf_step = UINT64_MAX;
  return BlockId{idx, s.generation};
}

void RigidWorld::remove_block(BlockId id) {
  Impl& m = *impl_;
  BlockSlot& s = m.block(id);
  for (std::uint32_t j = 0; j < m.joints.size(); ++j) {
    JointSlot& js = *m.joints[j];
    if (js.alive && (js.a == id || js.b == id)) remove_joint(JointId{j, js.generation});
  }
  m.world->removeRigidBody(s.body.get());
  s.body.reset();
  s.shape.reset();
  s.alive = false;
  m.state[id.index] = 0;
  if (s.asleep) --m.asleep_count;
  s.asleep = false;
  s.still = 0.0;
  m.cf_step = UINT64_MAX;
  ++s.generation;
  m.gen[id.index] = s.generation;
  s.ext_force.setZero();
  s.ext_torque.setZero();
  s.imp_linear.setZero();
  s.imp_angular.setZero();
  m.free_blocks.push_back(id.index);
  --m.block_count;
}

bool RigidWorld::alive(BlockId id) const {
  const Impl& m = *impl_;
  return id.index < m.blocks.size() && m.blocks[id.index].alive &&
         m.blocks[id.index].generation == id.generation;
}

std::size_t RigidWorld::block_count() const { return impl_->block_count; }

std::vector<BlockId> RigidWorld::blocks() const {
  std::vector<BlockId> out;
  out.reserve(impl_->block_count);
  for (std::uint32_t i = 0; i < impl_->blocks.size(); ++i)
    if (impl_->blocks[i].alive) out.push_back(BlockId{i, impl_->blocks[i].generation});
  return out;
}

void RigidWorld::step(double duration) {
  const long n = std::max(1L, std::lround(duration / impl_->def.dt));
  for (long i = 0; i < n; ++i) substep();
}

void RigidWorld::substep() {
  Impl& m = *impl_;
  const double h = m.def.dt;
  const double g = -m.def.gravity.z();
  BoxWaterParams wp;
  wp.level = m.def.water_level;
  wp.density = m.def.water_density;
  wp.linear_drag = m.def.linear_drag;
  wp.drag_coefficient = m.def.quadratic_drag_cd;
  wp.current = m.def.water_current;
  if (m.def.far_sleep.enabled) m.update_sleep(h);
  auto& stepped = m.world->stepped;  // what Bullet's per-body passes walk under far sleep (CanonicalWorld)
  stepped.clear();
  for (const std::uint32_t k : m.caller_loaded) {  // loads_held: last sub-step's, applied or not
    m.caller_j[k].setZero();
    m.caller_l[k].setZero();
  }
  m.caller_loaded.clear();
  const bool hold_loads = m.def.far_sleep.enabled && m.def.far_sleep.loads_held;
  constexpr std::uint8_t kHeldLoad = Impl::kAlive | Impl::kAsleep | Impl::kLoaded;  // (not fixed)
  for (std::size_t k = 0; k < m.blocks.size(); ++k) {
    if (!m.stepped(k)) {
      if (hold_loads && (m.state[k] & (kHeldLoad | Impl::kFixed)) == kHeldLoad) m.hold_caller_load(k, h);
      continue;
    }
    BlockSlot& s = m.blocks[k];
    btRigidBody& b = *s.body;
    if (m.world->managed_sleep) stepped.push_back(&b);
    if (!s.imp_linear.isZero(0.0) || !s.imp_angular.isZero(0.0)) {
      b.applyCentralImpulse(to_bt(s.imp_linear));
      b.applyTorqueImpulse(to_bt(s.imp_angular));
      s.imp_linear.setZero();
      s.imp_angular.setZero();
      m.set_loaded(k);
    }
    Vec3 f = s.ext_force, t = s.ext_torque;
    if (m.def.water) {
      const btTransform& tr = b.getWorldTransform();
      const WaterLoad wl =
          box_water_load(wp, g, s.half, from_bt(tr.getOrigin()), from_bt(tr.getRotation()),
                         from_bt(b.getLinearVelocity()), from_bt(b.getAngularVelocity()));
      f += wl.force;
      t += wl.torque;
    }
    b.applyCentralForce(to_bt(f));
    b.applyTorque(to_bt(t));
  }
  // Kinematic meshes: pose at the end of the sub-step. stepSimulation's
  // saveKinematicState turns the displacement into the body's velocity for the solver.
  for (auto& mp : m.meshes) {
    MeshSlot& ms = *mp;
    ms.origin += h * ms.velocity;
    ms.body->setWorldTransform(btTransform(btQuaternion::getIdentity(), to_bt(ms.origin)));
  }
  if (m.world->managed_sleep) {
    m.collect_awake_joints();
    for (const auto& mp : m.meshes) stepped.push_back(mp->body.get());
  }
  // maxSubSteps = 0: exactly one internal step of h; forces are cleared afterwards.
  m.world->check_after_solve =
      m.world->managed_sleep && (m.asleep_count > 0 || !m.touched_before.empty() || !m.hold_fresh_list.empty());
  m.world->stepSimulation(h, 0, h);
  m.world->awake_joints.clear();  // check_joints below may drop some of them
  m.check_joints();
  m.tally_mesh_loads(h);
  m.time += h;
  ++m.steps;
}

std::size_t RigidWorld::sleepers_woken_by_solve() const { return impl_->sleepers_woken_by_solve; }
std::size_t RigidWorld::solves_repeated() const { return impl_->world->repeated_solves; }

double RigidWorld::time() const { return impl_->time; }
void RigidWorld::reset_clock() {
  impl_->time = 0.0;
  impl_->steps = 0;
}
std::uint64_t RigidWorld::step_count() const { return impl_->steps; }

Vec3 RigidWorld::position(BlockId id) const {
  return from_bt(impl_->block(id).body->getWorldTransform().getOrigin());
}
Quat RigidWorld::orientation(BlockId id) const {
  return from_bt(impl_->block(id).body->getWorldTransform().getRotation());
}
Vec3 RigidWorld::velocity(BlockId id) const {
  return from_bt(impl_->block(id).body->getLinearVelocity());
}
Vec3 RigidWorld::angular_velocity(BlockId id) const {
  return from_bt(impl_->block(id).body->getAngularVelocity());
}
Vec3 RigidWorld::half_extents(BlockId id) const { return impl_->block(id).half; }
double RigidWorld::mass(BlockId id) const { return impl_->block(id).mass; }
bool RigidWorld::fixed(BlockId id) const { return impl_->block(id).fixed; }

void RigidWorld::set_velocity(BlockId id, const Vec3& v, const Vec3& w) {
  BlockSlot& s = impl_->block(id);
  if (s.fixed) return;
  if (s.asleep) impl_->wake(s);
  s.body->setLinearVelocity(to_bt(v));
  s.body->setAngularVelocity(to_bt(w));
}

void RigidWorld::set_pose(BlockId id, const Vec3& x, const Quat& q) {
  BlockSlot& s = impl_->block(id);
  s.body->setWorldTransform(btTransform(to_bt(q.normalized()), to_bt(x)));
  impl_->set_sleep_pose(s, s.body->getWorldTransform());  // far sleep's copy (BlockSlot)
  // Keep the broadphase in step for static blocks moved by the caller.
  impl_->world->updateSingleAabb(s.body.get());
}

void RigidWorld::set_friction(BlockId id, double mu) {
  if (!(mu >= 0.0)) throw InputError("rigid/friction", "must be >= 0");
  // Bullet recomputes the combined friction of a manifold point whenever the contact is
  // refreshed (every step for box-box pairs), so the change reaches existing contacts.
  impl_->block(id).body->setFriction(std::sqrt(mu));
}

void RigidWorld::set_solver_iterations(int n) {
  if (n < 1) throw InputError("rigid/solver_iterations", "must be >= 1");
  impl_->def.solver_iterations = n;
  impl_->world->getSolverInfo().m_numIterations = n;
}

void RigidWorld::add_force(BlockId id, const Vec3& f, const Vec3& point) {
  BlockSlot& s = impl_->block(id);
  const Vec3 c = from_bt(s.body->getWorldTransform().getOrigin());
  s.ext_force += f;
  s.ext_torque += (point - c).cross(f);
  impl_->set_loaded(id.index);
}

void RigidWorld::clear_external_forces() {
  for (std::size_t k = 0; k < impl_->blocks.size(); ++k) {
    impl_->blocks[k].ext_force.setZero();
    impl_->blocks[k].ext_torque.setZero();
    impl_->set_loaded(k);
  }
}

void RigidWorld::add_impulse(BlockId id, const Vec3& j, const Vec3& point) {
  BlockSlot& s = impl_->block(id);
  const Vec3 c = from_bt(s.body->getWorldTransform().getOrigin());
  s.imp_linear += j;
  s.imp_angular += (point - c).cross(j);
  impl_->set_loaded(id.index);
}

void RigidWorld::set_wake_boxes(const std::vector<std::pair<Vec3, Vec3>>& boxes) { impl_->wake_boxes = boxes; }

bool RigidWorld::asleep(BlockId id) const {
  // From the bytes beside the slots (the hybrid asks this of every block every rigid step), with
  // block()'s check of the id.
  const Impl& m = *impl_;
  if (id.index >= m.state.size() || !(m.state[id.index] & Impl::kAlive) || m.gen[id.index] != id.generation)
    throw std::out_of_range("rigid: stale or invalid BlockId " + std::to_string(id.index));
  return m.state[id.index] & Impl::kAsleep;
}

std::size_t RigidWorld::awake_count() const {
  std::size_t n = 0;
  for (const BlockSlot& s : impl_->blocks) n += s.alive && !s.fixed;
  return n - impl_->asleep_count;
}

std::size_t RigidWorld::moving_count() const {
  std::size_t n = 0;
  for (const BlockSlot& s : impl_->blocks)
    if (s.alive && !s.fixed && !s.asleep && impl_->block_moving(s)) ++n;
  return n;
}

double RigidWorld::kinetic_energy() const {
  double e = 0.0;
  for (const BlockSlot& s : impl_->blocks) {
    if (!s.alive || s.fixed) continue;
    const btRigidBody& b = *s.body;
    const Vec3 v = from_bt(b.getLinearVelocity());
    const Mat3 R = from_bt(b.getWorldTransform().getRotation()).toRotationMatrix();
    const Vec3 wl = R.transpose() * from_bt(b.getAngularVelocity());  // body frame
    const Vec3 I = from_bt(b.getLocalInertia());
    e += 0.5 * s.mass * v.squaredNorm() + 0.5 * wl.dot(I.cwiseProduct(wl));
  }
  return e;
}

int RigidWorld::add_kinematic_mesh(const KinematicMeshDef& d) {
  Impl& m = *impl_;
  if (d.triangles.empty()) throw InputError("structure/mesh", "a kinematic mesh needs triangles");
  if (d.part_count < 1) throw InputError("structure/mesh", "part_count must be >= 1");
  if (!(d.friction >= 0.0)) throw InputError("structure/friction", "must be >= 0");
  if (!d.triangle_part.empty() && d.triangle_part.size() != d.triangles.size())
    throw InputError("structure/mesh", "triangle_part must have one entry per triangle");
  auto ms = std::make_unique<MeshSlot>();
  ms->origin = d.position;
  ms->velocity = d.velocity;
  ms->friction = d.friction;
  ms->vertices.reserve(3 * d.vertices.size());
  for (const Vec3& v : d.vertices) ms->vertices.insert(ms->vertices.end(), {v.x(), v.y(), v.z()});
  ms->indices.reserve(3 * d.triangles.size());
  for (const auto& t : d.triangles) {
    for (std::uint32_t i : t) {
      if (i >= d.vertices.size())
        throw InputError("structure/mesh", "triangle vertex index out of range");
      ms->indices.push_back(static_cast<int>(i));
    }
  }
  ms->part = d.triangle_part;
  ms->lo = ms->hi = d.vertices.front();
  for (const Vec3& v : d.vertices) {
    ms->lo = ms->lo.cwiseMin(v);
    ms->hi = ms->hi.cwiseMax(v);
  }
  for (std::uint16_t p : ms->part)
    if (p >= d.part_count) throw InputError("structure/mesh", "triangle part out of range");
  btIndexedMesh im;
  im.m_numTriangles = static_cast<int>(d.triangles.size());
  im.m_triangleIndexBase = reinterpret_cast<const unsigned char*>(ms->indices.data());
  im.m_triangleIndexStride = 3 * sizeof(int);
  im.m_numVertices = static_cast<int>(d.vertices.size());
  im.m_vertexBase = reinterpret_cast<const unsigned char*>(ms->vertices.data());
  im.m_vertexStride = 3 * sizeof(btScalar);
  im.m_vertexType = PHY_DOUBLE;
  im.m_indexType = PHY_INTEGER;
  ms->array = std::make_unique<btTriangleIndexVertexArray>();
  ms->array->addIndexedMesh(im, PHY_INTEGER);
  ms->shape = std::make_unique<btBvhTriangleMeshShape>(ms->array.get(), true);
  ms->shape->setMargin(0.0);
  btRigidBody::btRigidBodyConstructionInfo info(0.0, nullptr, ms->shape.get());
  info.m_startWorldTransform = btTransform(btQuaternion::getIdentity(), to_bt(d.position));
  info.m_friction = d.friction;
  info.m_restitution = 0.0;
  ms->body = std::make_unique<btRigidBody>(info);
  ms->body->setCollisionFlags(ms->body->getCollisionFlags() | btCollisionObject::CF_KINEMATIC_OBJECT);
  ms->body->setActivationState(DISABLE_DEACTIVATION);
  ms->body->setUserIndex(static_cast<int>(m.meshes.size()));
  ms->body->setUserIndex2(kMeshTag);
  ms->load.part_force.assign(d.part_count, Vec3::Zero());
  ms->load.part_moment.assign(d.part_count, Vec3::Zero());
  m.world->addRigidBody(ms->body.get());
  m.meshes.push_back(std::move(ms));
  return static_cast<int>(m.meshes.size() - 1);
}

std::size_t RigidWorld::kinematic_mesh_count() const { return impl_->meshes.size(); }
Vec3 RigidWorld::mesh_position(int k) const { return impl_->meshes.at(k)->origin; }
const MeshLoad& RigidWorld::mesh_load(int k) const { return impl_->meshes.at(k)->load; }

std::vector<RigidWorld::ContactForce> RigidWorld::contact_forces(BlockId id) const {
  Impl& m = *impl_;
  m.block(id);  // throws for a stale id
  // Every block's list at once, on the first call after a sub-step (the conversion policy asks for
  // many blocks; walking all manifolds per block cost O(blocks x manifolds)). A block's forces come
  // in the order of a walk over the manifolds sorted by their bodies (canonical_world.h).
  if (m.cf_step != m.steps) {
    const double h = m.def.dt;
    detail::sorted_manifolds(m.dispatcher.get(), m.manifolds_scratch);
    const std::size_t n = m.blocks.size();
    m.cf_start.assign(n + 1, 0);
    auto live = [](const btManifoldPoint& p) {
      return !(p.m_appliedImpulse == 0.0 && p.m_appliedImpulseLateral1 == 0.0 && p.m_appliedImpulseLateral2 == 0.0);
    };
    for (int pass = 0; pass < 2; ++pass) {
      std::vector<std::uint32_t> fill;
      if (pass == 1) {
        for (std::size_t k = 0; k < n; ++k) m.cf_start[k + 1] += m.cf_start[k];
        m.cf_list.resize(m.cf_start[n]);
        fill.assign(m.cf_start.begin(), m.cf_start.end() - 1);
      }
      for (const btPersistentManifold* man : m.manifolds_scratch) {
        for (int side = 0; side < 2; ++side) {
          const btCollisionObject* o = side == 0 ? man->getBody0() : man->getBody1();
          if (!Impl::is_block(o)) continue;
          const auto k = static_cast<std::size_t>(o->getUserIndex());
          const double sign = side == 0 ? 1.0 : -1.0;  // Bullet applies +impulse to body 0
          for (int c = 0; c < man->getNumContacts(); ++c) {
            const btManifoldPoint& p = man->getContactPoint(c);
            if (!live(p)) continue;
            if (pass == 0) {
              ++m.cf_start[k + 1];
              continue;
            }
            const Vec3 j = from_bt(p.m_normalWorldOnB * p.m_appliedImpulse +
                                   p.m_lateralFrictionDir1 * p.m_appliedImpulseLateral1 +
                                   p.m_lateralFrictionDir2 * p.m_appliedImpulseLateral2);
            m.cf_list[fill[k]++] = {from_bt(side == 0 ? p.getPositionWorldOnA() : p.getPositionWorldOnB()),
                                    sign * j / h};
          }
        }
      }
    }
    m.cf_step = m.steps;
  }
  std::vector<ContactForce> out;
  for (std::uint32_t e = m.cf_start[id.index]; e < m.cf_start[id.index + 1]; ++e)
    out.push_back({m.cf_list[e].first, m.cf_list[e].second});
  return out;
}

std::vector<JointId> RigidWorld::joints_of(BlockId id) const {
  Impl& m = *impl_;
  // An index of every block's intact joints (slot order), rebuilt after the joints changed: the
  // conversion policy asks for many blocks, and a walk over all joints per block was O(blocks x joints).
  if (m.jo_version != m.joints_version) {
    const std::size_t n = m.blocks.size();
    m.jo_start.assign(n + 1, 0);
    for (int pass = 0; pass < 2; ++pass) {
      std::vector<std::uint32_t> fill;
      if (pass == 1) {
        for (std::size_t k = 0; k < n; ++k) m.jo_start[k + 1] += m.jo_start[k];
        m.jo_list.resize(m.jo_start[n]);
        fill.assign(m.jo_start.begin(), m.jo_start.end() - 1);
      }
      for (std::uint32_t k = 0; k < m.joints.size(); ++k) {
        const JointSlot& j = *m.joints[k];
        if (!j.alive || j.broken) continue;
        for (const std::uint32_t b : {j.a.index, j.b.index}) {
          if (b >= n) continue;
          if (pass == 0) ++m.jo_start[b + 1];
          else m.jo_list[fill[b]++] = k;
        }
      }
    }
    m.jo_version = m.joints_version;
  }
  std::vector<JointId> out;
  if (id.index + 1 >= m.jo_start.size()) return out;
  for (std::uint32_t e = m.jo_start[id.index]; e < m.jo_start[id.index + 1]; ++e) {
    const JointSlot& j = *m.joints[m.jo_list[e]];
    if (j.alive && !j.broken && (j.a == id || j.b == id)) out.push_back(JointId{m.jo_list[e], j.generation});
  }
  return out;
}

double RigidWorld::joint_area(JointId id) const { return impl_->joint(id).area; }

FreezeJointDef RigidWorld::joint_def(JointId id) const {
  const JointSlot& j = impl_->joint(id);
  const btTransform& ta = impl_->blocks[j.a.index].body->getWorldTransform();
  return FreezeJointDef{j.a, j.b, from_bt(ta * to_bt(j.anchor_in_a)), from_bt(ta.getBasis() * to_bt(j.normal_in_a)),
                        j.area};
}

JointId RigidWorld::add_freeze_joint(const FreezeJointDef& d) {
  Impl& m = *impl_;
  BlockSlot& sa = m.block(d.a);
  BlockSlot& sb = m.block(d.b);
  if (d.a == d.b) throw InputError("freeze_joint", "a joint needs two different blocks");
  if (sa.fixed && sb.fixed) throw InputError("freeze_joint", "both blocks are fixed");
  if (!(d.area > 0.0)) throw InputError("freeze_joint/area", "must be > 0 (m^2)");
  if (!(d.normal.norm() > 0.0)) throw InputError("freeze_joint/normal", "must be non-zero");
  std::uint32_t idx;
  if (!m.free_joints.empty()) {
    idx = m.free_joints.back();
    m.free_joints.pop_back();
  } else {
    idx = static_cast<std::uint32_t>(m.joints.size());
    m.joints.push_back(std::make_unique<JointSlot>());
  }
  JointSlot& j = *m.joints[idx];
  j.slot = idx;
  j.alive = true;
  j.broken = false;
  j.a = d.a;
  j.b = d.b;
  j.area = d.area;
  j.load = {};
  const btTransform& ta = sa.body->getWorldTransform();
  const btTransform& tb = sb.body->getWorldTransform();
  j.normal_in_a = from_bt(ta.getBasis().transpose() * to_bt(d.normal.normalized()));
  j.anchor_in_a = from_bt(ta.inverse() * to_bt(d.anchor));
  if (!(m.def.joint_stiffness > 0.0)) {
    const btTransform anchor(btQuaternion::getIdentity(), to_bt(d.anchor));
    j.constraint = std::make_unique<btFixedConstraint>(*sa.body, *sb.body, ta.inverse() * anchor, tb.inverse() * anchor);
  } else {
    j.constraint = m.spring_joint(sa, sb, d);
  }
  j.feedback = btJointFeedback{};
  j.constraint->setJointFeedback(&j.feedback);
  j.constraint->enableFeedback(true);
  // Contacts between the two blocks stay on: compression goes through the contact,
  // and the blocks must not interpenetrate once the joint breaks.
  m.world->addConstraint(j.constraint.get(), false);
  ++m.intact_joints;
  m.set_joint_order(j);
  return JointId{idx, j.generation};
}

void RigidWorld::remove_joint(JointId id) {
  Impl& m = *impl_;
  JointSlot& j = m.joint(id);
  m.drop_constraint(j);
  j.alive = false;
  ++j.generation;
  m.free_joints.push_back(id.index);
}

RigidWorld::JointStrain RigidWorld::joint_strain(JointId id) const {
  const JointSlot& j = impl_->joint(id);
  JointStrain s;
  const auto* c = dynamic_cast<const btGeneric6DofSpring2Constraint*>(j.constraint.get());
  if (!c) return s;  // broken: no frames
  const btTransform fa = c->getRigidBodyA().getWorldTransform() * c->getFrameOffsetA();
  const btTransform fb = c->getRigidBodyB().getWorldTransform() * c->getFrameOffsetB();
  s.displacement = from_bt(fb.getOrigin() - fa.getOrigin()).norm();
  const btQuaternion dq = fa.getRotation().inverse() * fb.getRotation();
  s.angle = 2.0 * std::atan2(btVector3(dq.x(), dq.y(), dq.z()).length(), std::abs(dq.w()));
  return s;
}

bool RigidWorld::joint_broken(JointId id) const { return impl_->joint(id).broken; }
JointLoad RigidWorld::joint_load(JointId id) const { return impl_->joint(id).load; }
std::size_t RigidWorld::broken_joint_count() const { return impl_->broken_joints; }
std::size_t RigidWorld::joint_count() const { return impl_->intact_joints; }
void RigidWorld::set_joints_breakable(bool on) { impl_->joints_breakable = on; }
std::size_t RigidWorld::overloaded_joint_count() const {
  const Impl& m = *impl_;
  std::size_t n = 0;
  for (const auto& jp : m.joints)
    if (jp->alive && !jp->broken && jp->constraint && m.overloaded(*jp)) ++n;
  return n;
}

// ---------------------------------------------------------------- checkpoint state
// Kept at the end of this file (it needs Impl); docs/output.md, "Checkpoints".

namespace {

// The records below hold 8-byte fields only: no padding, so equal states save equal bytes
// (a padding byte is whatever the last copy left there).

/// One rigid body's state as Bullet holds it: transforms as 3 basis rows + origin.
struct BodyRecord {
  double world[12], interpolation[12];
  double lin_vel[3], ang_vel[3], interp_lin_vel[3], interp_ang_vel[3];
  std::int64_t activation;
  double deactivation_time, hit_fraction, friction;
};

void put3(double* d, const btVector3& v) {
  d[0] = v.x();
  d[1] = v.y();
  d[2] = v.z();
}
btVector3 get3(const double* d) { return btVector3(d[0], d[1], d[2]); }
void put_tr(double* d, const btTransform& t) {
  for (int r = 0; r < 3; ++r) put3(d + 3 * r, t.getBasis()[r]);
  put3(d + 9, t.getOrigin());
}
btTransform get_tr(const double* d) {
  return btTransform(btMatrix3x3(d[0], d[1], d[2], d[3], d[4], d[5], d[6], d[7], d[8]), get3(d + 9));
}

/// A record with every byte set (padding zeroed), so that equal states save equal bytes.
template <class T>
T zeroed() {
  T r;
  std::memset(static_cast<void*>(&r), 0, sizeof r);
  return r;
}

/// x, y, z of a Bullet vector with its unused fourth component zeroed (Bullet leaves whatever
/// its arithmetic put there, which depends on the history).
btVector3 v3(const btVector3& v) { return btVector3(v.x(), v.y(), v.z()); }

BodyRecord body_record(const btRigidBody& b) {
  BodyRecord r = zeroed<BodyRecord>();
  put_tr(r.world, b.getWorldTransform());
  put_tr(r.interpolation, b.getInterpolationWorldTransform());
  put3(r.lin_vel, b.getLinearVelocity());
  put3(r.ang_vel, b.getAngularVelocity());
  put3(r.interp_lin_vel, b.getInterpolationLinearVelocity());
  put3(r.interp_ang_vel, b.getInterpolationAngularVelocity());
  r.activation = b.getActivationState();
  r.deactivation_time = b.getDeactivationTime();
  r.hit_fraction = b.getHitFraction();
  r.friction = b.getFriction();
  return r;
}

/// A contact point copied field by field into a zeroed one (the padding of Bullet's own copy
/// depends on the manifold's history).
btManifoldPoint clean_point(const btManifoldPoint& p) {
  btManifoldPoint q = zeroed<btManifoldPoint>();
  q.m_localPointA = v3(p.m_localPointA);
  q.m_localPointB = v3(p.m_localPointB);
  q.m_positionWorldOnB = v3(p.m_positionWorldOnB);
  q.m_positionWorldOnA = v3(p.m_positionWorldOnA);
  q.m_normalWorldOnB = v3(p.m_normalWorldOnB);
  q.m_distance1 = p.m_distance1;
  q.m_combinedFriction = p.m_combinedFriction;
  q.m_combinedRollingFriction = p.m_combinedRollingFriction;
  q.m_combinedSpinningFriction = p.m_combinedSpinningFriction;
  q.m_combinedRestitution = p.m_combinedRestitution;
  q.m_partId0 = p.m_partId0;
  q.m_partId1 = p.m_partId1;
  q.m_index0 = p.m_index0;
  q.m_index1 = p.m_index1;
  q.m_userPersistentData = nullptr;
  q.m_contactPointFlags = p.m_contactPointFlags;
  q.m_appliedImpulse = p.m_appliedImpulse;
  q.m_prevRHS = p.m_prevRHS;
  q.m_appliedImpulseLateral1 = p.m_appliedImpulseLateral1;
  q.m_appliedImpulseLateral2 = p.m_appliedImpulseLateral2;
  q.m_contactMotion1 = p.m_contactMotion1;
  q.m_contactMotion2 = p.m_contactMotion2;
  q.m_contactCFM = p.m_contactCFM;  // union with m_combinedContactStiffness1
  q.m_contactERP = p.m_contactERP;  // union with m_combinedContactDamping1
  q.m_frictionCFM = p.m_frictionCFM;
  q.m_lifeTime = p.m_lifeTime;
  q.m_lateralFrictionDir1 = v3(p.m_lateralFrictionDir1);
  q.m_lateralFrictionDir2 = v3(p.m_lateralFrictionDir2);
  return q;
}

void apply_record(btRigidBody& b, const BodyRecord& r) {
  b.setCenterOfMassTransform(get_tr(r.world));  // also the world inertia tensor, from the basis
  b.setInterpolationWorldTransform(get_tr(r.interpolation));
  b.setLinearVelocity(get3(r.lin_vel));
  b.setAngularVelocity(get3(r.ang_vel));
  b.setInterpolationLinearVelocity(get3(r.interp_lin_vel));
  b.setInterpolationAngularVelocity(get3(r.interp_ang_vel));
  b.forceActivationState(static_cast<int>(r.activation));
  b.setDeactivationTime(r.deactivation_time);
  b.setHitFraction(r.hit_fraction);
  b.setFriction(r.friction);
}

struct BlockRecord {
  std::uint32_t generation = 0;
  std::uint32_t alive = 0;
  Vec3 ext_force, ext_torque, imp_linear, imp_angular;
  BodyRecord body;
};

struct JointRecord {
  std::uint32_t generation = 0, alive = 0, broken = 0, has_constraint = 0;
  JointLoad load;
  double feedback[4][3];  ///< btJointFeedback: force and torque on A, on B
};

struct MeshRecord {
  Vec3 origin;
  BodyRecord body;
};

struct ManifoldRecord {
  std::uint64_t key0 = 0, key1 = 0;
  std::uint32_t first_point = 0, points = 0;
  btScalar breaking = 0, processing = 0;
};

}  // namespace

void RigidWorld::save_state(StateArchive& a, const std::string& p) const {
  const Impl& m = *impl_;
  std::vector<BlockRecord> blocks(m.blocks.size(), zeroed<BlockRecord>());
  for (std::size_t k = 0; k < m.blocks.size(); ++k) {
    const BlockSlot& s = m.blocks[k];
    BlockRecord& r = blocks[k];
    r.generation = s.generation;
    r.alive = s.alive;
    r.ext_force = s.ext_force;
    r.ext_torque = s.ext_torque;
    r.imp_linear = s.imp_linear;
    r.imp_angular = s.imp_angular;
    if (s.alive) r.body = body_record(*s.body);
  }
  a.put(p + "blocks", blocks);
  a.put(p + "free_blocks", m.free_blocks);
  std::vector<JointRecord> joints(m.joints.size(), zeroed<JointRecord>());
  for (std::size_t k = 0; k < m.joints.size(); ++k) {
    const JointSlot& j = *m.joints[k];
    JointRecord& r = joints[k];
    r.generation = j.generation;
    r.alive = j.alive;
    r.broken = j.broken;
    r.has_constraint = j.constraint ? 1u : 0u;
    r.load = j.load;
    put3(r.feedback[0], j.feedback.m_appliedForceBodyA);
    put3(r.feedback[1], j.feedback.m_appliedTorqueBodyA);
    put3(r.feedback[2], j.feedback.m_appliedForceBodyB);
    put3(r.feedback[3], j.feedback.m_appliedTorqueBodyB);
  }
  a.put(p + "joints", joints);
  a.put(p + "free_joints", m.free_joints);
  std::vector<MeshRecord> meshes;
  std::vector<Vec3> mesh_loads;  // per mesh: force, moment, then parts' force and moment
  std::vector<std::uint64_t> mesh_contacts;
  for (const auto& ms : m.meshes) {
    MeshRecord r = zeroed<MeshRecord>();
    r.origin = ms->origin;
    r.body = body_record(*ms->body);
    meshes.push_back(r);
    mesh_loads.push_back(ms->load.force);
    mesh_loads.push_back(ms->load.moment);
    mesh_loads.insert(mesh_loads.end(), ms->load.part_force.begin(), ms->load.part_force.end());
    mesh_loads.insert(mesh_loads.end(), ms->load.part_moment.begin(), ms->load.part_moment.end());
    mesh_contacts.push_back(ms->load.contacts);
  }
  a.put(p + "meshes", meshes);
  a.put(p + "mesh_loads", mesh_loads);
  a.put(p + "mesh_contacts", mesh_contacts);
  std::vector<ManifoldRecord> manifolds;
  std::vector<btManifoldPoint> points;
  std::vector<btPersistentManifold*> sorted;
  detail::sorted_manifolds(m.dispatcher.get(), sorted);
  for (const btPersistentManifold* man : sorted) {
    if (man->getNumContacts() == 0) continue;
    ManifoldRecord r = zeroed<ManifoldRecord>();
    r.key0 = detail::body_key(man->getBody0());
    r.key1 = detail::body_key(man->getBody1());
    r.first_point = static_cast<std::uint32_t>(points.size());
    r.points = static_cast<std::uint32_t>(man->getNumContacts());
    r.breaking = man->getContactBreakingThreshold();
    r.processing = man->getContactProcessingThreshold();
    for (int c = 0; c < man->getNumContacts(); ++c) points.push_back(clean_point(man->getContactPoint(c)));
    manifolds.push_back(r);
  }
  a.put(p + "manifolds", manifolds);
  a.put(p + "manifold_points", points);
  if (m.def.far_sleep.enabled) {  // the sleeping flag is the saved activation state (ISLAND_SLEEPING)
    std::vector<double> still(m.blocks.size(), 0.0);
    for (std::size_t k = 0; k < m.blocks.size(); ++k) still[k] = m.blocks[k].still;
    a.put(p + "sleep_still", still);
    // The hold references (check_sleepers) and the sleepers the last solve took.
    a.put(p + "sleep_hold_j", m.hold_j);
    std::vector<std::uint8_t> fresh(m.hold_fresh.begin(), m.hold_fresh.end());
    a.put(p + "sleep_hold_fresh", fresh);
    a.put(p + "sleep_touched", m.touched_before);
  }
  a.put_value(p + "time", m.time);
  a.put_value(p + "steps", m.steps);
  const std::uint64_t counts[3] = {m.block_count, m.intact_joints, m.broken_joints};
  a.put(p + "counts", std::vector<std::uint64_t>(counts, counts + 3));
}

/// Joints broken or removed since the scene was built: their constraints leave the world; every
/// slot takes its saved state.
void RigidWorld::Impl::restore_joints(const std::vector<JointRecord>& saved) {
  for (std::uint32_t k = 0; k < saved.size(); ++k) {
    JointSlot& j = *joints[k];
    const JointRecord& r = saved[k];
    if (!r.has_constraint) drop_constraint(j);
    else if (!j.constraint)
      throw std::runtime_error("rigid world checkpoint: joint " + std::to_string(k) + " is intact in the checkpoint "
                               "but not in the rebuilt world");
    j.generation = r.generation;
    j.alive = r.alive != 0;
    j.broken = r.broken != 0;
    j.load = r.load;
    j.feedback.m_appliedForceBodyA = get3(r.feedback[0]);
    j.feedback.m_appliedTorqueBodyA = get3(r.feedback[1]);
    j.feedback.m_appliedForceBodyB = get3(r.feedback[2]);
    j.feedback.m_appliedTorqueBodyB = get3(r.feedback[3]);
  }
}

void RigidWorld::Impl::restore_blocks(const std::vector<BlockRecord>& saved) {
  for (std::uint32_t k = 0; k < saved.size(); ++k) {
    BlockSlot& s = blocks[k];
    const BlockRecord& r = saved[k];
    s.generation = r.generation;
    gen[k] = r.generation;
    s.ext_force = r.ext_force;
    s.ext_torque = r.ext_torque;
    s.imp_linear = r.imp_linear;
    s.imp_angular = r.imp_angular;
    set_loaded(k);
    if (r.alive) {
      if (!s.alive)
        throw std::runtime_error("rigid world checkpoint: block " + std::to_string(k) + " is alive in the checkpoint "
                                 "but not in the rebuilt world");
      apply_record(*s.body, r.body);
    }
  }
}

/// Far sleep: every block awake for the collision pass of the restore (sleeping pairs would make
/// no manifolds), its timer restored; returns which were asleep, to put back to sleep after it.
std::vector<char> RigidWorld::Impl::wake_for_restore(const std::vector<double>& still) {
  std::vector<char> was_asleep(blocks.size(), 0);
  if (still.size() != blocks.size()) throw std::runtime_error("rigid world checkpoint: far-sleep timers missing");
  for (std::size_t k = 0; k < blocks.size(); ++k) {
    BlockSlot& s = blocks[k];
    if (!s.alive || s.fixed) continue;
    was_asleep[k] = s.body->getActivationState() == ISLAND_SLEEPING;
    if (s.asleep) wake(s);
    s.body->forceActivationState(DISABLE_DEACTIVATION);
    s.still = still[k];
  }
  return was_asleep;
}

/// Far sleep: the hold references as saved (a checkpoint without them, older than check_sleepers:
/// every sleeping block takes its reference at the first solve after the restart).
void RigidWorld::Impl::restore_holds(const StateArchive& a, const std::string& p) {
  for (const std::uint32_t k : hold_fresh_list) hold_fresh[k] = 0;
  hold_fresh_list.clear();
  touched_before.clear();
  if (!a.has(p + "sleep_hold_j")) {
    for (std::size_t k = 0; k < blocks.size(); ++k)
      if (state[k] & kAsleep) mark_hold_fresh(k);
    return;
  }
  const auto j = a.get<Vec3>(p + "sleep_hold_j");
  const auto fresh = a.get<std::uint8_t>(p + "sleep_hold_fresh");
  if (j.size() != blocks.size() || fresh.size() != blocks.size())
    throw std::runtime_error("rigid world checkpoint: far-sleep hold references truncated");
  hold_j = j;
  for (std::size_t k = 0; k < blocks.size(); ++k)
    if (fresh[k]) mark_hold_fresh(k);
  touched_before = a.get<std::uint32_t>(p + "sleep_touched");
  for (const std::uint32_t k : touched_before)
    if (k >= blocks.size()) throw std::runtime_error("rigid world checkpoint: far-sleep block index out of range");
}

void RigidWorld::Impl::restore_meshes(const std::vector<MeshRecord>& saved, const std::vector<Vec3>& loads,
                                      const std::vector<std::uint64_t>& contacts) {
  std::size_t o = 0;
  for (std::size_t k = 0; k < saved.size(); ++k) {
    MeshSlot& ms = *meshes[k];
    ms.origin = saved[k].origin;
    apply_record(*ms.body, saved[k].body);
    MeshLoad& L = ms.load;
    const std::size_t np = L.part_force.size();
    if (o + 2 + 2 * np > loads.size()) throw std::runtime_error("rigid world checkpoint: mesh loads truncated");
    L.force = loads[o];
    L.moment = loads[o + 1];
    std::copy(loads.begin() + o + 2, loads.begin() + o + 2 + np, L.part_force.begin());
    std::copy(loads.begin() + o + 2 + np, loads.begin() + o + 2 + 2 * np, L.part_moment.begin());
    o += 2 + 2 * np;
    L.contacts = contacts.at(k);
  }
}

/// Pairs, collision algorithms and manifolds for the restored poses, then every manifold's
/// points replaced by the saved ones (warm-starting impulses included). Returns the saved points
/// that found no manifold.
std::size_t RigidWorld::Impl::restore_manifolds(const std::vector<ManifoldRecord>& saved,
                                                const std::vector<btManifoldPoint>& points) {
  for (BlockSlot& s : blocks)
    if (s.alive) world->updateSingleAabb(s.body.get());
  world->performDiscreteCollisionDetection();
  std::vector<char> used(saved.size(), 0);
  const int nm = dispatcher->getNumManifolds();
  for (int k = 0; k < nm; ++k) {
    btPersistentManifold* man = dispatcher->getManifoldByIndexInternal(k);
    man->clearManifold();
    const std::uint64_t k0 = detail::body_key(man->getBody0()), k1 = detail::body_key(man->getBody1());
    const auto it = std::lower_bound(saved.begin(), saved.end(), std::make_pair(k0, k1),
                                     [](const ManifoldRecord& r, const std::pair<std::uint64_t, std::uint64_t>& key) {
                                       return std::make_pair(r.key0, r.key1) < key;
                                     });
    if (it == saved.end() || it->key0 != k0 || it->key1 != k1) continue;
    used[static_cast<std::size_t>(it - saved.begin())] = 1;
    man->setContactBreakingThreshold(it->breaking);
    man->setContactProcessingThreshold(it->processing);
    for (std::uint32_t c = 0; c < it->points; ++c) {
      const btManifoldPoint& pt = points.at(it->first_point + c);
      const int idx = man->addManifoldPoint(pt);
      man->getContactPoint(idx) = pt;
      man->getContactPoint(idx).m_userPersistentData = nullptr;
    }
  }
  std::size_t lost = 0;
  for (std::size_t k = 0; k < saved.size(); ++k)
    if (!used[k]) lost += saved[k].points;
  return lost;
}

std::size_t RigidWorld::load_state(const StateArchive& a, const std::string& p) {
  Impl& m = *impl_;
  const auto blocks = a.get<BlockRecord>(p + "blocks");
  const auto joints = a.get<JointRecord>(p + "joints");
  const auto meshes = a.get<MeshRecord>(p + "meshes");
  if (blocks.size() != m.blocks.size() || joints.size() != m.joints.size() || meshes.size() != m.meshes.size())
    throw std::runtime_error("rigid world checkpoint: " + std::to_string(blocks.size()) + " block slots, " +
                             std::to_string(joints.size()) + " joint slots and " + std::to_string(meshes.size()) +
                             " meshes saved, but the scene builds " + std::to_string(m.blocks.size()) + ", " +
                             std::to_string(m.joints.size()) + " and " + std::to_string(m.meshes.size()));
  // Blocks gone since the start (converted): removed, with their joints.
  for (std::uint32_t k = 0; k < blocks.size(); ++k)
    if (!blocks[k].alive && m.blocks[k].alive) remove_block(BlockId{k, m.blocks[k].generation});
  m.restore_joints(joints);
  m.free_joints = a.get<std::uint32_t>(p + "free_joints");
  m.restore_blocks(blocks);
  m.free_blocks = a.get<std::uint32_t>(p + "free_blocks");
  const std::vector<char> was_asleep = m.def.far_sleep.enabled ? m.wake_for_restore(a.get<double>(p + "sleep_still"))
                                                                : std::vector<char>(m.blocks.size(), 0);
  m.cf_step = UINT64_MAX;
  m.restore_meshes(meshes, a.get<Vec3>(p + "mesh_loads"), a.get<std::uint64_t>(p + "mesh_contacts"));
  m.time = a.get_value<double>(p + "time");
  m.steps = a.get_value<std::uint64_t>(p + "steps");
  const auto counts = a.get<std::uint64_t>(p + "counts");
  if (counts.size() != 3 || counts[0] != m.block_count || counts[1] != m.intact_joints)
    throw std::runtime_error("rigid world checkpoint: block or joint counts differ after the restore");
  m.broken_joints = counts[2];
  m.sync_joint_order();
  const std::size_t lost =
      m.restore_manifolds(a.get<ManifoldRecord>(p + "manifolds"), a.get<btManifoldPoint>(p + "manifold_points"));
  for (std::size_t k = 0; k < m.blocks.size(); ++k)
    if (was_asleep[k]) {
      const double still = m.blocks[k].still;
      m.put_to_sleep(m.blocks[k]);  // (velocities: zero, as saved)
      m.blocks[k].still = still;
    }
  if (m.def.far_sleep.enabled) m.restore_holds(a, p);
  return lost;
}

}  // namespace hs::rigid
