// Bullet adapter for RigidWorld: the world core (Bullet's set-up, the blocks, the sub-step, the
// contact forces). The other concerns have their own files (rigid_world_impl.h lists them); these
// files and canonical_world.h are the only ones of hs_rigid that see bt*.
#include "rigid/rigid_world.h"

#include "common/error.h"
#include "rigid/box_water.h"
#include "rigid/rigid_world_impl.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace hs::rigid {

using namespace detail;

namespace {

// Friction of a contact: a mesh imposes its own coefficient; two blocks meet with the
// product of their stored square roots (see add_block).
btScalar combined_friction(const btCollisionObject* a, const btCollisionObject* b) {
  if (a->getUserIndex2() == kMeshTag) return a->getFriction();
  if (b->getUserIndex2() == kMeshTag) return b->getFriction();
  return a->getFriction() * b->getFriction();
}

}  // namespace

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
  m.solver = std::make_unique<PooledSolver>();
  m.solver->friction_sees_torque = def.friction_sees_torque;
  m.world = std::make_unique<CanonicalWorld>(m.dispatcher.get(), m.broadphase.get(), m.solver.get(),
                                                     m.config.get());
  m.world->setGravity(to_bt(def.gravity));
  gCalculateCombinedFrictionCallback = &combined_friction;
  m.world->getSolverInfo().m_numIterations = std::max(1, def.solver_iterations);
  if (!(def.solver_tolerance >= 0.0) || !std::isfinite(def.solver_tolerance))
    throw InputError("rigid/solver_tolerance", "must be >= 0 (m/s; 0 = every solve takes solver_iterations)");
  // Bullet's residual is the largest squared velocity correction of a row in an iteration.
  m.world->getSolverInfo().m_leastSquaresResidualThreshold = def.solver_tolerance * def.solver_tolerance;
  if (def.contact_erp > 0.0) m.world->getSolverInfo().m_erp2 = def.contact_erp;
  if (def.joint_erp > 0.0) m.world->getSolverInfo().m_erp = def.joint_erp;
  if (!(def.split_impulse_depth >= 0.0)) throw InputError("rigid/split_impulse_depth", "must be >= 0 (m)");
  m.world->getSolverInfo().m_splitImpulse = true;
  m.world->getSolverInfo().m_splitImpulsePenetrationThreshold = -def.split_impulse_depth;
  if (def.far_sleep.enabled) {
    FarSleep::validate(def);
    m.sleep.install(m);
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
    m.sleep.add_slot();
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
  if (s.asleep) --m.sleep.asleep_count;
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
  if (m.def.far_sleep.enabled) m.sleep.update_sleep(m, h);
  auto& stepped = m.world->stepped;  // what Bullet's per-body passes walk under far sleep (CanonicalWorld)
  stepped.clear();
  for (const std::uint32_t k : m.sleep.caller_loaded) {  // loads_held: last sub-step's, applied or not
    m.sleep.caller_j[k].setZero();
    m.sleep.caller_l[k].setZero();
  }
  m.sleep.caller_loaded.clear();
  const bool hold_loads = m.def.far_sleep.enabled && m.def.far_sleep.loads_held;
  constexpr std::uint8_t kHeldLoad = Impl::kAlive | Impl::kAsleep | Impl::kLoaded;  // (not fixed)
  for (std::size_t k = 0; k < m.blocks.size(); ++k) {
    if (!m.stepped(k)) {
      if (hold_loads && (m.state[k] & (kHeldLoad | Impl::kFixed)) == kHeldLoad) m.sleep.hold_caller_load(m, k, h);
      continue;
    }
    ++m.sleep.stepped_bodies;
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
  m.move_meshes(h);  // to their pose at the end of the sub-step
  if (m.world->managed_sleep) {
    m.sleep.collect_awake_joints(m);
    for (const auto& mp : m.meshes) stepped.push_back(mp->body.get());
  }
  // maxSubSteps = 0: exactly one internal step of h; forces are cleared afterwards.
  m.world->check_after_solve =
      m.world->managed_sleep && (m.sleep.asleep_count > 0 || !m.sleep.touched_before.empty() || !m.sleep.hold_fresh_list.empty());
  m.world->stepSimulation(h, 0, h);
  m.world->awake_joints.clear();  // check_joints below may drop some of them
  m.check_joints();
  m.tally_mesh_loads(h);
  m.time += h;
  ++m.steps;
}


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
  if (s.asleep) impl_->sleep.wake(*impl_, s);
  s.body->setLinearVelocity(to_bt(v));
  s.body->setAngularVelocity(to_bt(w));
}

void RigidWorld::set_pose(BlockId id, const Vec3& x, const Quat& q) {
  BlockSlot& s = impl_->block(id);
  s.body->setWorldTransform(btTransform(to_bt(q.normalized()), to_bt(x)));
  impl_->sleep.set_sleep_pose(*impl_, s, s.body->getWorldTransform());  // far sleep's copy of its centre
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

RigidWorld::SolverStats RigidWorld::solver_stats() const {
  const PooledSolver& s = *impl_->solver;
  return {s.solves, s.iterations, s.max_iterations};
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

std::vector<RigidWorld::ContactForce> RigidWorld::contact_forces(BlockId id) const {
  Impl& m = *impl_;
  m.block(id);  // throws for a stale id
  // Every block's list at once, on the first call after a sub-step (the conversion policy asks for
  // many blocks; walking all manifolds per block cost O(blocks x manifolds)). A block's forces come
  // in the order of a walk over the manifolds sorted by their bodies (canonical_world.h).
  if (m.cf_step != m.steps) {
    const double h = m.def.dt;
    sorted_manifolds(m.dispatcher.get(), m.manifolds_scratch);
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
          if (!is_block(o)) continue;
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

}  // namespace hs::rigid
