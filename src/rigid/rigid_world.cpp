// Bullet adapter for RigidWorld. The only translation unit of hs_rigid that sees bt*.
#include "rigid/rigid_world.h"

#include "common/error.h"
#include "rigid/box_water.h"

#include <btBulletDynamicsCommon.h>

#include <algorithm>
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
};

struct JointSlot {
  std::uint32_t generation = 0;
  bool alive = false;   // slot in use (intact or broken)
  bool broken = false;
  BlockId a, b;
  Vec3 normal_in_a = Vec3::UnitZ();  // joint normal in a's body frame
  double area = 1.0;
  JointLoad load;
  btJointFeedback feedback{};
  std::unique_ptr<btFixedConstraint> constraint;
};

}  // namespace

struct RigidWorld::Impl {
  RigidWorldDef def;
  double tensile_strength = 0.0, shear_strength = 0.0;
  std::unique_ptr<btDefaultCollisionConfiguration> config;
  std::unique_ptr<btCollisionDispatcher> dispatcher;
  std::unique_ptr<btDbvtBroadphase> broadphase;
  std::unique_ptr<btSequentialImpulseConstraintSolver> solver;
  std::unique_ptr<btDiscreteDynamicsWorld> world;

  std::vector<BlockSlot> blocks;
  std::vector<std::uint32_t> free_blocks;
  std::size_t block_count = 0;
  // unique_ptr: btJointFeedback addresses must stay put while Bullet holds them.
  std::vector<std::unique_ptr<JointSlot>> joints;
  std::vector<std::uint32_t> free_joints;
  std::size_t intact_joints = 0, broken_joints = 0;
  double time = 0.0;
  std::uint64_t steps = 0;

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

  void drop_constraint(JointSlot& j) {
    if (j.constraint) {
      world->removeConstraint(j.constraint.get());
      j.constraint.reset();
      --intact_joints;
    }
  }

  void check_joints() {
    for (auto& jp : joints) {
      JointSlot& j = *jp;
      if (!j.alive || j.broken || !j.constraint) continue;
      const btRigidBody& ba = *blocks[j.a.index].body;
      const Vec3 n = from_bt(ba.getWorldTransform().getBasis() * to_bt(j.normal_in_a));
      const Vec3 fb = from_bt(j.feedback.m_appliedForceBodyB);
      const double fn = fb.dot(n);
      j.load.tension = -fn;
      j.load.shear = (fb - fn * n).norm();
      if (j.load.tension > tensile_strength * j.area || j.load.shear > shear_strength * j.area) {
        j.broken = true;
        drop_constraint(j);
        ++broken_joints;
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
  m.def = def;
  m.tensile_strength = def.freeze_bond_strength;
  m.shear_strength =
      def.freeze_bond_shear_strength < 0.0 ? def.freeze_bond_strength : def.freeze_bond_shear_strength;
  m.config = std::make_unique<btDefaultCollisionConfiguration>();
  m.dispatcher = std::make_unique<btCollisionDispatcher>(m.config.get());
  m.broadphase = std::make_unique<btDbvtBroadphase>();
  m.solver = std::make_unique<btSequentialImpulseConstraintSolver>();
  m.world = std::make_unique<btDiscreteDynamicsWorld>(m.dispatcher.get(), m.broadphase.get(),
                                                      m.solver.get(), m.config.get());
  m.world->setGravity(to_bt(def.gravity));
  m.world->getSolverInfo().m_numIterations = std::max(1, def.solver_iterations);
  if (def.fixed_friction_directions)
    m.world->getSolverInfo().m_solverMode |= SOLVER_USE_2_FRICTION_DIRECTIONS |
                                             SOLVER_ENABLE_FRICTION_DIRECTION_CACHING |
                                             SOLVER_DISABLE_VELOCITY_DEPENDENT_FRICTION_DIRECTION;
}

RigidWorld::~RigidWorld() {
  Impl& m = *impl_;
  for (auto& j : m.joints)
    if (j->constraint) m.world->removeConstraint(j->constraint.get());
  for (auto& b : m.blocks)
    if (b.alive) m.world->removeRigidBody(b.body.get());
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
    if (!m.def.allow_sleep)
      s.body->setActivationState(DISABLE_DEACTIVATION);
    else
      s.body->setSleepingThresholds(m.def.sleep_linear_velocity, m.def.sleep_angular_velocity);
  }
  s.body->setUserIndex(static_cast<int>(idx));
  m.world->addRigidBody(s.body.get());
  ++m.block_count;
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
  ++s.generation;
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
  for (BlockSlot& s : m.blocks) {
    if (!s.alive || s.fixed) continue;
    btRigidBody& b = *s.body;
    if (!s.imp_linear.isZero(0.0) || !s.imp_angular.isZero(0.0)) {
      b.applyCentralImpulse(to_bt(s.imp_linear));
      b.applyTorqueImpulse(to_bt(s.imp_angular));
      s.imp_linear.setZero();
      s.imp_angular.setZero();
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
  // maxSubSteps = 0: exactly one internal step of h; forces are cleared afterwards.
  m.world->stepSimulation(h, 0, h);
  m.check_joints();
  m.time += h;
  ++m.steps;
}

double RigidWorld::time() const { return impl_->time; }
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
  s.body->setLinearVelocity(to_bt(v));
  s.body->setAngularVelocity(to_bt(w));
}

void RigidWorld::set_pose(BlockId id, const Vec3& x, const Quat& q) {
  BlockSlot& s = impl_->block(id);
  s.body->setWorldTransform(btTransform(to_bt(q.normalized()), to_bt(x)));
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
}

void RigidWorld::clear_external_forces() {
  for (BlockSlot& s : impl_->blocks) {
    s.ext_force.setZero();
    s.ext_torque.setZero();
  }
}

void RigidWorld::add_impulse(BlockId id, const Vec3& j, const Vec3& point) {
  BlockSlot& s = impl_->block(id);
  const Vec3 c = from_bt(s.body->getWorldTransform().getOrigin());
  s.imp_linear += j;
  s.imp_angular += (point - c).cross(j);
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
  j.alive = true;
  j.broken = false;
  j.a = d.a;
  j.b = d.b;
  j.area = d.area;
  j.load = {};
  const btTransform& ta = sa.body->getWorldTransform();
  const btTransform& tb = sb.body->getWorldTransform();
  j.normal_in_a = from_bt(ta.getBasis().transpose() * to_bt(d.normal.normalized()));
  const btTransform anchor(btQuaternion::getIdentity(), to_bt(d.anchor));
  j.constraint = std::make_unique<btFixedConstraint>(*sa.body, *sb.body, ta.inverse() * anchor,
                                                     tb.inverse() * anchor);
  j.feedback = btJointFeedback{};
  j.constraint->setJointFeedback(&j.feedback);
  j.constraint->enableFeedback(true);
  // Contacts between the two blocks stay on: compression goes through the contact,
  // and the blocks must not interpenetrate once the joint breaks.
  m.world->addConstraint(j.constraint.get(), false);
  ++m.intact_joints;
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

bool RigidWorld::joint_broken(JointId id) const { return impl_->joint(id).broken; }
JointLoad RigidWorld::joint_load(JointId id) const { return impl_->joint(id).load; }
std::size_t RigidWorld::broken_joint_count() const { return impl_->broken_joints; }
std::size_t RigidWorld::joint_count() const { return impl_->intact_joints; }

}  // namespace hs::rigid
