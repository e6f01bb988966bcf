// Far sleep (far_sleep.h; docs/rigid.md, "Far sleep").
#include "rigid/far_sleep.h"

#include "common/error.h"
#include "rigid/box_water.h"
#include "rigid/rigid_world_impl.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace hs::rigid {

namespace detail {

namespace {

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

constexpr std::uint8_t kAlive = WorldImpl::kAlive, kFixed = WorldImpl::kFixed, kAsleep = WorldImpl::kAsleep,
                       kLoaded = WorldImpl::kLoaded;

}  // namespace

void FarSleep::validate(const RigidWorldDef& def) {
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
}

void FarSleep::install(WorldImpl& w) {
  w.world->managed_sleep = true;
  w.world->setForceUpdateAllAabbs(false);  // sleeping blocks keep theirs
  w.dispatcher->setNearCallback(&far_sleep_near_callback);
  w.broadphase->getOverlappingPairCache()->setInternalGhostPairCallback(&pair_index);
  w.world->pair_index = &pair_index;
  WorldImpl* impl = &w;
  w.world->after_solve = [impl](bool may_repeat) { return impl->sleep.check_sleepers(*impl, may_repeat); };
}

void FarSleep::add_slot() {
  sleep_centre.emplace_back(Vec3::Zero());
  hold_j.emplace_back(Vec3::Zero());
  hold_fresh.push_back(0);
  solve_j.emplace_back(Vec3::Zero());
  solve_seen.push_back(0);
}

// loads_held: a sleeping block's caller load of this sub-step, taken off the block (a sleeping
// block is not integrated, so an impulse left on it would add up over the sub-steps it sleeps).
void FarSleep::hold_caller_load(WorldImpl& w, std::size_t k, double h) {
  BlockSlot& s = w.blocks[k];
  if (caller_j.size() < w.blocks.size()) {
    caller_j.resize(w.blocks.size(), Vec3::Zero());
    caller_l.resize(w.blocks.size(), Vec3::Zero());
  }
  caller_j[k] = s.imp_linear + h * s.ext_force;
  caller_l[k] = s.imp_angular + h * s.ext_torque;
  s.imp_linear.setZero();
  s.imp_angular.setZero();
  w.set_loaded(k);
  caller_loaded.push_back(static_cast<std::uint32_t>(k));
}

void FarSleep::set_sleep_pose(WorldImpl& w, BlockSlot& s, const btTransform& pose) {
  sleep_centre[w.slot_of(s)] = from_bt(pose.getOrigin());
}

SolveMass solve_mass(const WorldImpl& w, const btRigidBody& b) {
  SolveMass sm;
  if (b.getInvMass() > 0.0 || b.getUserIndex2() == kMeshTag) {
    sm.inv_mass = b.getInvMass();
    sm.inv_inertia_world = b.getInvInertiaTensorWorld();
    return sm;
  }
  const BlockSlot& s = w.blocks[static_cast<std::size_t>(b.getUserIndex())];
  sm.inv_inertia_world.setValue(0, 0, 0, 0, 0, 0, 0, 0, 0);
  if (!(s.mass > 0.0)) return sm;
  sm.inv_mass = 1.0 / s.mass;
  const btVector3 in = w.local_inertia(s);
  const btVector3 inv(in.x() != 0.0 ? 1.0 / in.x() : 0.0, in.y() != 0.0 ? 1.0 / in.y() : 0.0,
                      in.z() != 0.0 ? 1.0 / in.z() : 0.0);
  const btMatrix3x3& basis = b.getWorldTransform().getBasis();
  sm.inv_inertia_world = basis.scaled(inv) * basis.transpose();
  return sm;
}

void FarSleep::put_to_sleep(WorldImpl& w, BlockSlot& s) {
  btRigidBody& b = *s.body;
  b.setLinearVelocity(btVector3(0, 0, 0));
  b.setAngularVelocity(btVector3(0, 0, 0));
  // Immovable in the solve (a fixed solver body: Bullet takes a body without inverse mass as one)
  // until it wakes: an awake block resting on it is held, and its steady load is the hold
  // reference (check_sleepers) against which an impact is told apart.
  b.setMassProps(0.0, btVector3(0, 0, 0));
  b.updateInertiaTensor();
  mark_hold_fresh(w.slot_of(s));
  b.setCollisionFlags(b.getCollisionFlags() | btCollisionObject::CF_STATIC_OBJECT);
  b.forceActivationState(ISLAND_SLEEPING);
  w.world->updateSingleAabb(&b);  // a static box at its pose (a restored world computes the same)
  b.getBroadphaseHandle()->m_collisionFilterGroup |= kSleepingProxyBit;
  set_sleep_pose(w, s, b.getWorldTransform());
  s.asleep = true;
  w.state[w.slot_of(s)] |= kAsleep;
  ++asleep_count;
}

void FarSleep::wake(WorldImpl& w, BlockSlot& s) {
  s.still = 0.0;
  if (!s.asleep) return;
  btRigidBody& b = *s.body;
  b.setMassProps(s.mass, w.local_inertia(s));  // the bits it was built with
  b.updateInertiaTensor();
  b.setGravity(w.world->getGravity());          // as addRigidBody set it (g / inverse mass)
  b.setCollisionFlags(b.getCollisionFlags() & ~btCollisionObject::CF_STATIC_OBJECT);
  b.forceActivationState(DISABLE_DEACTIVATION);
  b.getBroadphaseHandle()->m_collisionFilterGroup &= ~kSleepingProxyBit;
  s.asleep = false;
  w.state[w.slot_of(s)] &= static_cast<std::uint8_t>(~kAsleep);
  --asleep_count;
}

// Before a solve: the joints it takes (CanonicalWorld::awake_joints), intact, enabled, with a
// block that is neither fixed nor asleep -- what the world's own filter over joint_order finds.
void FarSleep::collect_awake_joints(WorldImpl& w) {
  auto& aj = w.world->awake_joints;
  aj.clear();
  for (const WorldImpl::IntactJoint& ij : w.intact_list()) {
    if (!w.stepped(ij.a) && !w.stepped(ij.b)) continue;  // before touching the joint's heap slot
    btTypedConstraint* c = w.joints[ij.slot]->constraint.get();
    if (c->isEnabled()) aj.push_back(c);
  }
}

// ---------------------------------------------------------------- the hold (check_sleepers)

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
bool FarSleep::check_sleepers(WorldImpl& w, bool may_repeat) {
  if (asleep_count == 0 && hold_fresh_list.empty() && touched_before.empty()) return false;
  take_solve_loads(w);
  find_departed(w);
  // Without a repeat left (CanonicalWorld::max_repeats) the woken blocks stopped the impulse in
  // this sub-step as immovable ones (the rule's error (1), docs/rigid.md).
  const bool repeat = !to_wake.empty() && may_repeat;
  sleepers_woken_by_solve += to_wake.size();
  wake_departed(w, repeat);
  if (!repeat) settle_references(w);
  for (const std::uint32_t k : touched) {  // (solve_seen marks only `touched`)
    solve_j[k].setZero();
    solve_seen[k] = 0;
  }
  if (repeat) {
    for (const std::uint32_t k : to_wake) collide_with_inactive(w, w.blocks[k]);
    collect_awake_joints(w);  // the woken blocks' joints to sleeping ones are solved now
  }
  return repeat;
}

// This solve's impulses on the sleeping blocks it took (solve_j, touched): their contacts', their
// joints', and the caller's (loads_held).
void FarSleep::take_solve_loads(WorldImpl& w) {
  const double h = w.def.dt;
  touched.clear();
  auto take_slot = [&](std::size_t k, const Vec3& j) {
    if (!(w.state[k] & kAsleep)) return;
    if (!solve_seen[k]) {
      solve_seen[k] = 1;
      touched.push_back(static_cast<std::uint32_t>(k));
    }
    solve_j[k] += j;
  };
  auto take = [&](const btCollisionObject* o, const Vec3& j) {
    if (o->getUserIndex2() != kMeshTag) take_slot(static_cast<std::size_t>(o->getUserIndex()), j);
  };
  for (const btPersistentManifold* man : w.world->solved_manifolds()) {
    const btCollisionObject* b0 = man->getBody0();
    const btCollisionObject* b1 = man->getBody1();
    const bool s0 = is_block(b0) && (w.state[static_cast<std::size_t>(b0->getUserIndex())] & kAsleep);
    const bool s1 = is_block(b1) && (w.state[static_cast<std::size_t>(b1->getUserIndex())] & kAsleep);
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
  for (const btTypedConstraint* c : w.world->awake_joints) {
    const btJointFeedback* fb = c->getJointFeedback();
    if (!fb) continue;
    const btRigidBody& A = c->getRigidBodyA();
    const btRigidBody& B = c->getRigidBodyB();
    if (is_block(&A)) take(&A, from_bt(fb->m_appliedForceBodyA) * h);
    if (is_block(&B)) take(&B, from_bt(fb->m_appliedForceBodyB) * h);
  }
  for (const std::uint32_t k : caller_loaded) take_slot(k, caller_j[k]);  // loads_held
}

// The test (to_wake, sorted): every sleeper the solve took, and those the last sub-step's solve
// took (a load that went away), against its reference; not those whose reference is taken now.
void FarSleep::find_departed(WorldImpl& w) {
  to_wake.clear();
  const double v = w.def.far_sleep.speed;
  auto test = [&](std::uint32_t k) {
    if (!(w.state[k] & kAsleep) || hold_fresh[k]) return;
    const double m = w.blocks[k].mass;
    const double lim = m * v + (k < allow.size() ? allow[k] : 0.0);
    if ((solve_j[k] - hold_j[k]).squaredNorm() > lim * lim) to_wake.push_back(k);
  };
  for (const std::uint32_t k : touched) test(k);
  for (const std::uint32_t k : touched_before)
    if (!solve_seen[k]) test(k);
  std::sort(to_wake.begin(), to_wake.end());
  to_wake.erase(std::unique(to_wake.begin(), to_wake.end()), to_wake.end());
}

void FarSleep::wake_departed(WorldImpl& w, bool repeat) {
  for (const std::uint32_t k : to_wake) {
    wake(w, w.blocks[k]);
    allow_neighbours(w, w.blocks[k]);
    if (k < caller_j.size() && (!caller_j[k].isZero(0.0) || !caller_l[k].isZero(0.0))) {
      // loads_held: the caller's load of this sub-step, as a stepped block takes it (before the solve)
      w.blocks[k].body->applyCentralImpulse(to_bt(caller_j[k]));
      w.blocks[k].body->applyTorqueImpulse(to_bt(caller_l[k]));
      caller_j[k].setZero();
      caller_l[k].setZero();
    }
    if (repeat) {
      w.world->stepped.push_back(w.blocks[k].body.get());
      ++stepped_bodies;
    }
  }
}

// The sub-step's last solve: references taken, the sleepers it took kept.
void FarSleep::settle_references(const WorldImpl& w) {
  for (const std::uint32_t k : hold_fresh_list) {
    if ((w.state[k] & kAsleep)) hold_j[k] = solve_j[k];
    hold_fresh[k] = 0;
  }
  for (const std::uint32_t k : allow_list) {  // (allow_neighbours: moved by the allowance at most)
    if ((w.state[k] & kAsleep) && !hold_fresh[k]) {
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

// A block woken by a solve (check_sleepers), before the repeat: its pairs with inactive bodies
// (sleeping blocks, and fixed ones if inactive) were not collided this step -- never, for blocks
// that started asleep (start_asleep) -- so their contacts would be missing or stale in the
// repeated solve. They are collided now, as this step's collision pass would have done had the
// block been awake (its pose is the one it slept at; the repeat saves the new points first).
void FarSleep::collide_with_inactive(WorldImpl& w, BlockSlot& s) {
  btBroadphaseProxy* p = s.body->getBroadphaseHandle();
  btOverlappingPairCache* cache = w.broadphase->getOverlappingPairCache();
  const btDispatcherInfo& info = w.world->getDispatchInfo();
  for (btBroadphaseProxy* q : pair_index.partners(p)) {
    const auto* o = static_cast<const btCollisionObject*>(q->m_clientObject);
    if (!is_block(o) || o->isActive()) continue;  // an active partner was collided this step
    if (btBroadphasePair* pair = cache->findPair(p, q)) w.dispatcher->getNearCallback()(*pair, *w.dispatcher, info);
  }
}

// The sleeping blocks that s touches (an overlapping pair) or is jointed to, each once or more.
template <class F>
void FarSleep::for_sleeping_neighbours(WorldImpl& w, BlockSlot& s, F&& f) {
  btRigidBody& b = *s.body;
  for (const btBroadphaseProxy* q : pair_index.partners(b.getBroadphaseHandle())) {
    const auto* o = static_cast<const btCollisionObject*>(q->m_clientObject);
    if (is_block(o) && (w.state[static_cast<std::size_t>(o->getUserIndex())] & kAsleep))
      f(static_cast<std::size_t>(o->getUserIndex()));
  }
  for (int i = 0; i < b.getNumConstraintRefs(); ++i) {
    const btTypedConstraint* c = b.getConstraintRef(i);
    const btRigidBody& o = &c->getRigidBodyA() == &b ? c->getRigidBodyB() : c->getRigidBodyA();
    if (is_block(&o) && (w.state[static_cast<std::size_t>(o.getUserIndex())] & kAsleep))
      f(static_cast<std::size_t>(o.getUserIndex()));
  }
}

// A block fell asleep: its contacts and joints with sleeping blocks are no longer solved, so those
// blocks' references are taken again at the next solve (check_sleepers).
void FarSleep::fresh_neighbours(WorldImpl& w, BlockSlot& s) {
  for_sleeping_neighbours(w, s, [&](std::size_t k) { mark_hold_fresh(k); });
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
void FarSleep::allow_neighbours(WorldImpl& w, BlockSlot& s) {
  const RigidWorldDef& def = w.def;
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
  if (allow.size() < w.blocks.size()) allow.resize(w.blocks.size(), 0.0);
  for_sleeping_neighbours(w, s, [&](std::size_t k) {
    if (allow[k] == 0.0) allow_list.push_back(static_cast<std::uint32_t>(k));
    allow[k] += a;
  });
}

// ---------------------------------------------------------------- the rule (update_sleep)

bool FarSleep::block_moving(const RigidWorldDef& def, const BlockSlot& s) const {
  const double v = def.far_sleep.speed;
  const btRigidBody& b = *s.body;
  return b.getLinearVelocity().length2() > v * v ||
         b.getAngularVelocity().length2() * s.half.squaredNorm() > v * v;
}

bool FarSleep::in_wake_zone(const WorldImpl& w, const Vec3& c) const {
  const double d = w.def.far_sleep.wake_distance;
  for (const auto& mp : w.meshes) {
    const Vec3 lo = mp->origin + mp->lo - Vec3::Constant(d), hi = mp->origin + mp->hi + Vec3::Constant(d);
    if ((c.array() >= lo.array()).all() && (c.array() <= hi.array()).all()) return true;
  }
  for (const auto& [lo, hi] : wake_boxes)
    if ((c.array() >= lo.array()).all() && (c.array() <= hi.array()).all()) return true;
  return false;
}

void FarSleep::update_sleep(WorldImpl& w, double h) {
  flag_blocks(w);
  spread_wake(w);
  apply_rule(w, h);
}

// Per block: moving, or woken by the zone or the caller's load (1: a seed of the hops, 2: awake
// only itself).
void FarSleep::flag_blocks(WorldImpl& w) {
  const std::size_t n = w.blocks.size();
  moving.assign(n, 0);
  woken.assign(n, 0);
  reset.assign(n, 0);
  const auto& fs = w.def.far_sleep;
  for (std::size_t k = 0; k < n; ++k) {
    const std::uint8_t st = w.state[k];
    if ((st & (kAlive | kFixed)) != kAlive) continue;
    // (a sleeping block's slot is not read: its centre and flags are kept beside it)
    const bool asleep = st & kAsleep;
    if (!asleep) moving[k] = block_moving(w.def, w.blocks[k]);
    // (2: awake, but not a seed of the hops below: a block the caller loads that does not move;
    // its load reaches a sleeping neighbour through the solve, check_sleepers)
    if (in_wake_zone(w, asleep ? sleep_centre[k] : from_bt(w.blocks[k].body->getWorldTransform().getOrigin())))
      woken[k] = fs.zone_wakes_neighbours ? 1 : 2;
    else if ((st & kLoaded) && !fs.loads_held)
      woken[k] = fs.loads_wake_neighbours ? 1 : 2;
  }
}

// Every block within wake_hops contacts or joints of a moving block (or of one the caller loads
// now) is woken, or kept from falling asleep: the solver carries an impulse a few blocks per
// sub-step, and a sleeping block on its way would stop it like a wall. Breadth first, level by
// level, so the order of the graph does not matter.
void FarSleep::spread_wake(WorldImpl& w) {
  const std::size_t n = w.blocks.size();
  std::vector<std::uint32_t>& front = bfs_a;
  std::vector<std::uint32_t>& next = bfs_b;
  front.clear();
  for (std::size_t k = 0; k < n; ++k)
    if (moving[k] || woken[k] == 1) front.push_back(static_cast<std::uint32_t>(k));
  std::vector<char>& seen = moving_seen;
  seen.assign(n, 0);
  for (const std::uint32_t k : front) seen[k] = 1;
  if (!front.empty() && w.def.far_sleep.wake_hops > 0) build_neighbour_graph(w);
  for (int hop = 0; hop < w.def.far_sleep.wake_hops && !front.empty(); ++hop) {
    next.clear();
    for (const std::uint32_t a : front)
      for (std::uint32_t e = adj_start[a]; e < adj_start[a + 1]; ++e) {
        const std::uint32_t b = adj[e];
        if (seen[b]) continue;
        seen[b] = 1;
        ((w.state[b] & kAsleep) ? woken[b] : reset[b]) = 1;
        next.push_back(b);
      }
    std::swap(front, next);
  }
}

// The neighbour graph (none needed without a seed): blocks touching (a manifold with a point) or
// jointed (an intact joint), as an edge list (one pass over the manifolds) turned into adjacency
// lists by counting. The BFS gives the same sets in any edge order.
void FarSleep::build_neighbour_graph(WorldImpl& w) {
  const std::size_t n = w.blocks.size();
  edges.clear();
  const int nm = w.dispatcher->getNumManifolds();
  for (int k = 0; k < nm; ++k) {
    const btPersistentManifold* man = w.dispatcher->getManifoldByIndexInternal(k);
    if (man->getNumContacts() == 0 || !is_block(man->getBody0()) || !is_block(man->getBody1())) continue;
    const auto a = static_cast<std::uint32_t>(man->getBody0()->getUserIndex());
    const auto b = static_cast<std::uint32_t>(man->getBody1()->getUserIndex());
    if (!w.blocks[a].fixed && !w.blocks[b].fixed) edges.emplace_back(a, b);
  }
  for (const WorldImpl::IntactJoint& j : w.intact_list())
    if (!w.blocks[j.a].fixed && !w.blocks[j.b].fixed) edges.emplace_back(j.a, j.b);
  adj_start.assign(n + 1, 0);
  for (const auto& [a, b] : edges) {
    ++adj_start[a + 1];
    ++adj_start[b + 1];
  }
  for (std::size_t k = 0; k < n; ++k) adj_start[k + 1] += adj_start[k];
  adj.resize(adj_start[n]);
  std::vector<std::uint32_t>& fill = bfs_b;  // free until the BFS
  fill.assign(adj_start.begin(), adj_start.end() - 1);
  for (const auto& [a, b] : edges) {
    adj[fill[a]++] = b;
    adj[fill[b]++] = a;
  }
}

// The flags applied: a flagged block wakes (or stays awake, its timer reset); an unflagged awake
// one counts its still time and falls asleep after still_time.
void FarSleep::apply_rule(WorldImpl& w, double h) {
  for (std::size_t k = 0; k < w.blocks.size(); ++k) {
    if ((w.state[k] & (kAlive | kFixed)) != kAlive) continue;
    if (woken[k] || reset[k] || moving[k]) {
      const bool was_asleep = w.state[k] & kAsleep;
      wake(w, w.blocks[k]);
      if (was_asleep) allow_neighbours(w, w.blocks[k]);
    } else if (!(w.state[k] & kAsleep)) {
      BlockSlot& s = w.blocks[k];
      s.still += h;
      if (s.still >= w.def.far_sleep.still_time) {
        put_to_sleep(w, s);
        fresh_neighbours(w, s);
      }
    }
  }
}

}  // namespace detail

// ---------------------------------------------------------------- RigidWorld's far-sleep API

using namespace detail;

std::size_t RigidWorld::sleepers_woken_by_solve() const { return impl_->sleep.sleepers_woken_by_solve; }
std::size_t RigidWorld::solves_repeated() const { return impl_->world->repeated_solves; }
std::uint64_t RigidWorld::stepped_body_count() const { return impl_->sleep.stepped_bodies; }

void RigidWorld::set_wake_boxes(const std::vector<std::pair<Vec3, Vec3>>& boxes) { impl_->sleep.wake_boxes = boxes; }

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
  return n - impl_->sleep.asleep_count;
}

std::size_t RigidWorld::moving_count() const {
  std::size_t n = 0;
  for (const BlockSlot& s : impl_->blocks)
    if (s.alive && !s.fixed && !s.asleep && impl_->sleep.block_moving(impl_->def, s)) ++n;
  return n;
}

}  // namespace hs::rigid
