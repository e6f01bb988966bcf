// Freeze joints (rigid_world.h: RigidWorldDef's joint fields, FreezeJointDef; docs/rigid.md,
// "Freeze joints"): rigid (btFixedConstraint) or six damped springs, their loads read back after
// every sub-step and broken past the bond strength.
#include "common/error.h"
#include "rigid/rigid_world_impl.h"

#include <algorithm>
#include <cmath>

namespace hs::rigid {

namespace detail {

const std::vector<WorldImpl::IntactJoint>& WorldImpl::intact_list() {
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

// A freeze joint as six damped springs (RigidWorldDef::joint_stiffness): a frame at the anchor
// with x along the normal, all six axes free (lower limit > upper) with a spring at rest in the
// current pose. Normal and shear: k = s A; bending (frame y, z): s I; twist (x): s 2 I, with
// I = A^2 / (4 pi) for a disc of area A. Damping c = 2 zeta sqrt(k m), m the reduced mass
// (linear) or reduced inertia about the axis through the anchor (angular), as Bullet's spring
// rows see them.
std::unique_ptr<btTypedConstraint> WorldImpl::spring_joint(BlockSlot& sa, BlockSlot& sb, const FreezeJointDef& d) {
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
    const SolveMass sm = solve_mass(*this, b);
    return sm.inv_mass > 0.0 ? 1.0 / sm.inv_mass : 0.0;
  };
  auto inertia = [&](const btRigidBody& b, const Vec3& axis) {  // about `axis` through the anchor
    const SolveMass sm = solve_mass(*this, b);
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

void WorldImpl::drop_constraint(JointSlot& j) {
  if (j.constraint) {
    world->removeConstraint(j.constraint.get());
    j.constraint.reset();
    --intact_joints;
    set_joint_order(j);
  }
}

/// The world solves joints in slot (creation) order, whatever order removals left its array in.
void WorldImpl::sync_joint_order() {
  ++joints_version;
  world->joint_order.clear();
  for (const auto& jp : joints) world->joint_order.push_back(jp->constraint.get());
}
/// The same for one slot that changed (made, remade or dropped): O(1) where the whole rebuild
/// made adding the paper-size ridge's 78,000 joints quadratic (~15 s of the bench's set-up).
void WorldImpl::set_joint_order(const JointSlot& j) {
  ++joints_version;
  auto& order = world->joint_order;
  if (j.slot == order.size()) order.push_back(j.constraint.get());
  else order.at(j.slot) = j.constraint.get();
}

void WorldImpl::check_joints() {
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

}  // namespace detail

using namespace detail;

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

}  // namespace hs::rigid
