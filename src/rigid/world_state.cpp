// The checkpoint of a rigid world (RigidWorld::save_state, load_state; docs/output.md,
// "Checkpoints"): every block, joint, mesh and contact manifold as Bullet holds it, and far
// sleep's state.
#include "common/state_archive.h"
#include "rigid/rigid_world_impl.h"

#include <algorithm>
#include <cstring>
#include <stdexcept>
#include <string>

namespace hs::rigid {

using namespace detail;

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

/// Joints broken or removed since the scene was built: their constraints leave the world; every
/// slot takes its saved state.
void restore_joints(WorldImpl& m, const std::vector<JointRecord>& saved) {
  for (std::uint32_t k = 0; k < saved.size(); ++k) {
    JointSlot& j = *m.joints[k];
    const JointRecord& r = saved[k];
    if (!r.has_constraint) m.drop_constraint(j);
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

void restore_blocks(WorldImpl& m, const std::vector<BlockRecord>& saved) {
  for (std::uint32_t k = 0; k < saved.size(); ++k) {
    BlockSlot& s = m.blocks[k];
    const BlockRecord& r = saved[k];
    s.generation = r.generation;
    m.gen[k] = r.generation;
    s.ext_force = r.ext_force;
    s.ext_torque = r.ext_torque;
    s.imp_linear = r.imp_linear;
    s.imp_angular = r.imp_angular;
    m.set_loaded(k);
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
std::vector<char> wake_for_restore(WorldImpl& m, const std::vector<double>& still) {
  std::vector<char> was_asleep(m.blocks.size(), 0);
  if (still.size() != m.blocks.size()) throw std::runtime_error("rigid world checkpoint: far-sleep timers missing");
  for (std::size_t k = 0; k < m.blocks.size(); ++k) {
    BlockSlot& s = m.blocks[k];
    if (!s.alive || s.fixed) continue;
    was_asleep[k] = s.body->getActivationState() == ISLAND_SLEEPING;
    if (s.asleep) m.sleep.wake(m, s);
    s.body->forceActivationState(DISABLE_DEACTIVATION);
    s.still = still[k];
  }
  return was_asleep;
}

/// Far sleep: the hold references as saved (a checkpoint without them, older than check_sleepers:
/// every sleeping block takes its reference at the first solve after the restart).
void restore_holds(WorldImpl& m, const StateArchive& a, const std::string& p) {
  for (const std::uint32_t k : m.sleep.hold_fresh_list) m.sleep.hold_fresh[k] = 0;
  m.sleep.hold_fresh_list.clear();
  m.sleep.touched_before.clear();
  if (!a.has(p + "sleep_hold_j")) {
    for (std::size_t k = 0; k < m.blocks.size(); ++k)
      if (m.state[k] & WorldImpl::kAsleep) m.sleep.mark_hold_fresh(k);
    return;
  }
  const auto j = a.get<Vec3>(p + "sleep_hold_j");
  const auto fresh = a.get<std::uint8_t>(p + "sleep_hold_fresh");
  if (j.size() != m.blocks.size() || fresh.size() != m.blocks.size())
    throw std::runtime_error("rigid world checkpoint: far-sleep hold references truncated");
  m.sleep.hold_j = j;
  for (std::size_t k = 0; k < m.blocks.size(); ++k)
    if (fresh[k]) m.sleep.mark_hold_fresh(k);
  m.sleep.touched_before = a.get<std::uint32_t>(p + "sleep_touched");
  for (const std::uint32_t k : m.sleep.touched_before)
    if (k >= m.blocks.size()) throw std::runtime_error("rigid world checkpoint: far-sleep block index out of range");
}

void restore_meshes(WorldImpl& m, const std::vector<MeshRecord>& saved, const std::vector<Vec3>& loads,
                    const std::vector<std::uint64_t>& contacts) {
  std::size_t o = 0;
  for (std::size_t k = 0; k < saved.size(); ++k) {
    MeshSlot& ms = *m.meshes[k];
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
std::size_t restore_manifolds(WorldImpl& m, const std::vector<ManifoldRecord>& saved,
                              const std::vector<btManifoldPoint>& points) {
  for (BlockSlot& s : m.blocks)
    if (s.alive) m.world->updateSingleAabb(s.body.get());
  m.world->performDiscreteCollisionDetection();
  std::vector<char> used(saved.size(), 0);
  const int nm = m.dispatcher->getNumManifolds();
  for (int k = 0; k < nm; ++k) {
    btPersistentManifold* man = m.dispatcher->getManifoldByIndexInternal(k);
    man->clearManifold();
    const std::uint64_t k0 = body_key(man->getBody0()), k1 = body_key(man->getBody1());
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
  sorted_manifolds(m.dispatcher.get(), sorted);
  for (const btPersistentManifold* man : sorted) {
    if (man->getNumContacts() == 0) continue;
    ManifoldRecord r = zeroed<ManifoldRecord>();
    r.key0 = body_key(man->getBody0());
    r.key1 = body_key(man->getBody1());
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
    a.put(p + "sleep_hold_j", m.sleep.hold_j);
    std::vector<std::uint8_t> fresh(m.sleep.hold_fresh.begin(), m.sleep.hold_fresh.end());
    a.put(p + "sleep_hold_fresh", fresh);
    a.put(p + "sleep_touched", m.sleep.touched_before);
  }
  a.put_value(p + "time", m.time);
  a.put_value(p + "steps", m.steps);
  const std::uint64_t counts[3] = {m.block_count, m.intact_joints, m.broken_joints};
  a.put(p + "counts", std::vector<std::uint64_t>(counts, counts + 3));
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
  restore_joints(m, joints);
  m.free_joints = a.get<std::uint32_t>(p + "free_joints");
  restore_blocks(m, blocks);
  m.free_blocks = a.get<std::uint32_t>(p + "free_blocks");
  const std::vector<char> was_asleep = m.def.far_sleep.enabled ? wake_for_restore(m, a.get<double>(p + "sleep_still"))
                                                               : std::vector<char>(m.blocks.size(), 0);
  m.cf_step = UINT64_MAX;
  restore_meshes(m, meshes, a.get<Vec3>(p + "mesh_loads"), a.get<std::uint64_t>(p + "mesh_contacts"));
  m.time = a.get_value<double>(p + "time");
  m.steps = a.get_value<std::uint64_t>(p + "steps");
  const auto counts = a.get<std::uint64_t>(p + "counts");
  if (counts.size() != 3 || counts[0] != m.block_count || counts[1] != m.intact_joints)
    throw std::runtime_error("rigid world checkpoint: block or joint counts differ after the restore");
  m.broken_joints = counts[2];
  m.sync_joint_order();
  const std::size_t lost =
      restore_manifolds(m, a.get<ManifoldRecord>(p + "manifolds"), a.get<btManifoldPoint>(p + "manifold_points"));
  for (std::size_t k = 0; k < m.blocks.size(); ++k)
    if (was_asleep[k]) {
      const double still = m.blocks[k].still;
      m.sleep.put_to_sleep(m, m.blocks[k]);  // (velocities: zero, as saved)
      m.blocks[k].still = still;
    }
  if (m.def.far_sleep.enabled) restore_holds(m, a, p);
  return lost;
}

}  // namespace hs::rigid
