// A btDiscreteDynamicsWorld whose constraint solve happens in an order fixed by the bodies and
// joints themselves, not by the world's history (docs/rigid.md, "Solve order").
// Private to hs_rigid (includes Bullet).
//
// Why: Bullet solves contacts island by island, islands in the order of the union-find roots,
// manifolds in the dispatcher's array order (creation and swap-removal history) sorted by an
// unstable quickSort on island id, and joints in the world's constraint array (swap-removal
// history). A world rebuilt from a checkpoint holds the same bodies, joints and contact points
// but not that history, so it would solve in another order and drift from the original in the
// last bits. Here every step solves all contacts and joints as one group (what Bullet itself
// does with split islands off): manifolds sorted by their two bodies' keys, joints in creation
// (slot) order. Islands are still built, only to put bodies to sleep and wake them (Bullet's
// buildIslands); the contacts and joints of sleeping islands are left out as Bullet leaves them.
// Islands do not interact, so one group gives each island the same physics as solving it
// alone; only the order of the rows inside an island changed (results moved once, in the last
// bits, when this was introduced).
#pragma once

#include <BulletCollision/CollisionDispatch/btSimulationIslandManager.h>
#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <cstdint>
#include <functional>
#include <vector>

namespace hs::rigid::detail {

/// User index 2 of a kinematic mesh body; blocks keep Bullet's default (-1).
constexpr int kMeshTag = 1;

/// A body's stable key: blocks by slot index, kinematic meshes after every block.
inline std::uint64_t body_key(const btCollisionObject* o) {
  const auto idx = static_cast<std::uint64_t>(static_cast<std::uint32_t>(o->getUserIndex()));
  return o->getUserIndex2() == kMeshTag ? (std::uint64_t{1} << 32) + idx : idx;
}

/// The dispatcher's manifolds for which keep(manifold) holds, sorted by (key of body 0, key of
/// body 1). Two bodies share at most one manifold (box-box and box-mesh pairs each make one), so
/// the keys are unique and filtering before or after the sort gives the same sequence.
template <class Keep>
void sorted_manifolds_if(btDispatcher* d, std::vector<btPersistentManifold*>& out, Keep keep) {
  out.clear();
  const int n = d->getNumManifolds();
  for (int k = 0; k < n; ++k) {
    btPersistentManifold* m = d->getManifoldByIndexInternal(k);
    if (keep(m)) out.push_back(m);
  }
  std::sort(out.begin(), out.end(), [](const btPersistentManifold* a, const btPersistentManifold* b) {
    const std::uint64_t a0 = body_key(a->getBody0()), b0 = body_key(b->getBody0());
    if (a0 != b0) return a0 < b0;
    return body_key(a->getBody1()) < body_key(b->getBody1());
  });
}

/// The dispatcher's manifolds sorted by (key of body 0, key of body 1).
inline void sorted_manifolds(btDispatcher* d, std::vector<btPersistentManifold*>& out) {
  out.reserve(static_cast<std::size_t>(d->getNumManifolds()));
  sorted_manifolds_if(d, out, [](const btPersistentManifold*) { return true; });
}

/// Bullet's sequential-impulse solver with its scratch pools kept at least 25 % above their
/// last use. Bullet sizes the body, joint-row and order pools to exactly the step's need
/// (resizeNoInitialize -> reserve allocates no more than asked), so every step that needs one row
/// more than any before copies the whole pool to fresh pages -- under far sleep, while the awake
/// set grows, that was every rigid step (page faults and the memset of new rows: ~17 % of a hybrid
/// step on the paper-size ridge). Only the capacities change: the same rows are solved in the same
/// order.
class PooledSolver final : public btSequentialImpulseConstraintSolver {
 public:
  /// RigidWorldDef::friction_sees_torque: correct every friction row for the external torque.
  bool friction_sees_torque = false;

  /// Bullet 3.x's setupFrictionConstraint takes the velocity an external force gives a body in
  /// this step (m_externalForceImpulse) but not the one an external torque gives it
  /// (m_externalTorqueImpulse), while setupContactConstraint takes both. A block resting on a face
  /// under an off-centre load then slides: the normal rows stop the torque's rotation, the friction
  /// rows, blind to it, cancel the tangential motion it would have caused, and what is left is the
  /// block translating at torque x dt x lever / I (docs/rigid.md, "External torques and
  /// friction"). Here each friction row's target is corrected by the torque's velocity along it,
  /// as the normal rows have it.
  void convertContacts(btPersistentManifold** manifolds, int n, const btContactSolverInfo& info) override {
    btSequentialImpulseConstraintSolver::convertContacts(manifolds, n, info);
    if (!friction_sees_torque) return;
    for (int i = 0; i < m_tmpSolverContactFrictionConstraintPool.size(); ++i) {
      btSolverConstraint& c = m_tmpSolverContactFrictionConstraintPool[i];
      const btSolverBody& a = m_tmpSolverBodyPool[c.m_solverBodyIdA];
      const btSolverBody& b = m_tmpSolverBodyPool[c.m_solverBodyIdB];
      const btScalar v = (a.m_originalBody ? c.m_relpos1CrossNormal.dot(a.m_externalTorqueImpulse) : btScalar(0)) +
                         (b.m_originalBody ? c.m_relpos2CrossNormal.dot(b.m_externalTorqueImpulse) : btScalar(0));
      c.m_rhs -= v * c.m_jacDiagABInv;
    }
  }

  /// Counted for RigidWorld::solver_stats; the arithmetic is Bullet's.
  std::uint64_t solves = 0, iterations = 0;
  int max_iterations = 0;

  btScalar solveGroupCacheFriendlyIterations(btCollisionObject** bodies, int numBodies, btPersistentManifold** manifolds,
                                             int numManifolds, btTypedConstraint** constraints, int numConstraints,
                                             const btContactSolverInfo& info, btIDebugDraw* draw) override {
    const std::uint64_t before = iterations;
    const btScalar r = btSequentialImpulseConstraintSolver::solveGroupCacheFriendlyIterations(
        bodies, numBodies, manifolds, numManifolds, constraints, numConstraints, info, draw);
    ++solves;
    max_iterations = std::max(max_iterations, static_cast<int>(iterations - before));
    return r;
  }

  btScalar solveSingleIteration(int iteration, btCollisionObject** bodies, int numBodies, btPersistentManifold** manifolds,
                                int numManifolds, btTypedConstraint** constraints, int numConstraints,
                                const btContactSolverInfo& info, btIDebugDraw* draw) override {
    ++iterations;
    return btSequentialImpulseConstraintSolver::solveSingleIteration(iteration, bodies, numBodies, manifolds,
                                                                     numManifolds, constraints, numConstraints, info,
                                                                     draw);
  }

  btScalar solveGroupCacheFriendlyFinish(btCollisionObject** bodies, int numBodies,
                                         const btContactSolverInfo& info) override {
    // The pools still hold this step's sizes here (the base class empties them).
    grow(m_tmpSolverBodyPool);
    grow(m_tmpSolverContactConstraintPool);
    grow(m_tmpSolverNonContactConstraintPool);
    grow(m_tmpSolverContactFrictionConstraintPool);
    grow(m_tmpSolverContactRollingFrictionConstraintPool);
    grow(m_orderTmpConstraintPool);
    grow(m_orderNonContactConstraintPool);
    grow(m_orderFrictionConstraintPool);
    grow(m_tmpConstraintSizesPool);
    return btSequentialImpulseConstraintSolver::solveGroupCacheFriendlyFinish(bodies, numBodies, info);
  }

 private:
  template <class A>
  static void grow(A& a) {
    const int n = a.size();
    if (a.capacity() < n + n / 4 + 16) a.reserve(2 * n + 16);  // copies the n live entries once
  }
};

/// Every overlapping pair of the broadphase, listed by each of its two proxies (by unique id), kept
/// up to date by the pair cache's ghost callback, which the hashed cache calls for every pair it
/// adds and every pair it removes (one by one, also when a proxy is destroyed).
class PairIndex final : public btOverlappingPairCallback {
 public:
  btBroadphasePair* addOverlappingPair(btBroadphaseProxy* a, btBroadphaseProxy* b) override {
    link(a, b);
    link(b, a);
    return nullptr;
  }
  void* removeOverlappingPair(btBroadphaseProxy* a, btBroadphaseProxy* b, btDispatcher*) override {
    unlink(a, b);
    unlink(b, a);
    return nullptr;
  }
  void removeOverlappingPairsContainingProxy(btBroadphaseProxy*, btDispatcher*) override {}  // (pair by pair above)
  const std::vector<btBroadphaseProxy*>& partners(const btBroadphaseProxy* p) const {
    static const std::vector<btBroadphaseProxy*> none;
    const auto u = static_cast<std::size_t>(p->getUid());
    return u < by_uid_.size() ? by_uid_[u] : none;
  }

 private:
  void link(btBroadphaseProxy* a, btBroadphaseProxy* b) {
    const auto u = static_cast<std::size_t>(a->getUid());
    if (u >= by_uid_.size()) by_uid_.resize(u + 1);
    by_uid_[u].push_back(b);
  }
  void unlink(btBroadphaseProxy* a, btBroadphaseProxy* b) {
    auto& v = by_uid_[static_cast<std::size_t>(a->getUid())];
    for (std::size_t k = 0; k < v.size(); ++k)
      if (v[k] == b) {
        v[k] = v.back();
        v.pop_back();
        return;
      }
  }
  std::vector<std::vector<btBroadphaseProxy*>> by_uid_;
};

class CanonicalWorld final : public btDiscreteDynamicsWorld {
 public:
  using btDiscreteDynamicsWorld::btDiscreteDynamicsWorld;

  /// The world's joints in creation order (RigidWorld keeps it: its joint slots in slot order;
  /// entries may be null for slots without a constraint).
  std::vector<btTypedConstraint*> joint_order;

  /// True when RigidWorld decides which bodies sleep (its far-sleep rule, rigid_world.h): Bullet's
  /// islands are then neither built nor used, and its deactivation timers are not run.
  bool managed_sleep = false;
  /// With managed_sleep: the joints to solve this step, set by the owner just before it steps (its
  /// intact joints with an awake block, in joint_order's order). The filter below over joint_order
  /// reads every constraint and both its bodies; on the paper-size ridge (63,000 joints, nearly
  /// all asleep) that was 10 % of a stepped-while-idle hybrid step.
  std::vector<btTypedConstraint*> awake_joints;

  /// Takes every joint and body out of the world in O(joints + bodies + pairs), for the world's
  /// destruction: Bullet's removeConstraint and removeRigidBody each search an array (and each
  /// body's removal scans every overlapping pair), which made tearing down a paper-size ridge
  /// (78,000 joints, 29,000 blocks) quadratic, ~5 s. The bodies and constraints stay owned by the
  /// caller, to be deleted after this.
  void release_all() {
    for (int k = 0; k < m_constraints.size(); ++k) {
      btTypedConstraint* c = m_constraints[k];
      c->getRigidBodyA().removeConstraintRef(c);
      c->getRigidBodyB().removeConstraintRef(c);
    }
    m_constraints.clear();
    // Every overlapping pair at once (each with its manifold), so that no removal below scans any.
    struct RemoveAll : btOverlapCallback {
      bool processOverlap(btBroadphasePair&) override { return true; }
    } all;
    getBroadphase()->getOverlappingPairCache()->processAllOverlappingPairs(&all, getDispatcher());
    m_nonStaticRigidBodies.clear();  // removeRigidBody below then finds nothing to search
    all_nonstatic_.clear();
    for (int k = getNumCollisionObjects() - 1; k >= 0; --k) {
      btCollisionObject* o = getCollisionObjectArray()[k];
      if (btRigidBody* b = btRigidBody::upcast(o)) removeRigidBody(b);
      else removeCollisionObject(o);
    }
  }

  /// With managed_sleep: the bodies the owner steps this sub-step, set just before stepSimulation
  /// in any order: its awake blocks and its kinematic meshes. Every other body is static to Bullet
  /// (a fixed block, or a sleeping one: CF_STATIC_OBJECT, ISLAND_SLEEPING), and Bullet's per-body
  /// passes do nothing to it: no gravity (inactive), no damping, prediction or integration (static),
  /// no bounding-box update (inactive, setForceUpdateAllAabbs(false)), no kinematic state (not
  /// kinematic), no forces to clear (none is applied to it). stepSimulation below runs those passes
  /// over these bodies only, in the orders Bullet's own arrays hold them, so the step computes the
  /// same bits; with 29,000 blocks asleep the passes over every body were ~20 % of an idle rigid
  /// step (reading each body to find that it sleeps).
  std::vector<btRigidBody*> stepped;

  int stepSimulation(btScalar timeStep, int maxSubSteps, btScalar fixedTimeStep) override {
    if (!managed_sleep) return btDiscreteDynamicsWorld::stepSimulation(timeStep, maxSubSteps, fixedTimeStep);
    if (nonstatic_order_stale_) {  // bodies were added or removed: their places in the array
      for (int i = 0; i < m_nonStaticRigidBodies.size(); ++i) m_nonStaticRigidBodies[i]->setUserIndex3(i);
      all_nonstatic_.copyFromArray(m_nonStaticRigidBodies);
      nonstatic_order_stale_ = false;
    }
    // The array Bullet's passes and solveConstraints walk: the stepped bodies in its own order.
    restep_bodies();
    // updateAabbs and saveKinematicState walk the collision-object array: the same bodies in its order.
    by_world_index_.assign(stepped.begin(), stepped.end());
    std::sort(by_world_index_.begin(), by_world_index_.end(), [](const btRigidBody* a, const btRigidBody* b) {
      return a->getWorldArrayIndex() < b->getWorldArrayIndex();
    });
    in_step_ = true;
    const int n = btDiscreteDynamicsWorld::stepSimulation(timeStep, maxSubSteps, fixedTimeStep);
    in_step_ = false;
    m_nonStaticRigidBodies.copyFromArray(all_nonstatic_);
    return n;
  }
  /// With managed_sleep: the overlapping pairs as PairIndex lists them (set by the owner before any
  /// body is added). A managed step then dispatches only the pairs with a stepped body, each once, to
  /// the dispatcher's near callback: the others (two sleeping blocks, or a sleeping and a fixed one)
  /// are pairs of two inactive bodies, which Bullet's needsCollision refuses, so the contacts made
  /// are the same; Bullet's own dispatch visits every pair (~40 % of an idle rigid step on the
  /// paper-size ridge). The order differs from Bullet's, and nothing depends on it: a pair's
  /// collision writes only its own manifold, and every reader of the manifolds sorts them (body_key).
  /// A lookup per listed pair costs more than Bullet's walk over the pair array per pair, so with
  /// many bodies stepped (more than a quarter of the pairs listed by them) Bullet's walk is used.
  PairIndex* pair_index = nullptr;

  void performDiscreteCollisionDetection() override {
    if (!in_step_ || !pair_index) return btDiscreteDynamicsWorld::performDiscreteCollisionDetection();
    updateAabbs();
    computeOverlappingPairs();
    auto* d = static_cast<btCollisionDispatcher*>(getDispatcher());
    btOverlappingPairCache* cache = getBroadphase()->getOverlappingPairCache();
    const btDispatcherInfo& info = getDispatchInfo();
    std::size_t listed = 0;
    for (btRigidBody* b : stepped) listed += pair_index->partners(b->getBroadphaseHandle()).size();
    if (4 * listed > static_cast<std::size_t>(cache->getNumOverlappingPairs())) {
      d->dispatchAllCollisionPairs(cache, info, d);
      return;
    }
    for (btRigidBody* b : stepped) mark(b->getBroadphaseHandle(), 1);
    for (btRigidBody* b : stepped) {
      btBroadphaseProxy* p = b->getBroadphaseHandle();
      for (btBroadphaseProxy* q : pair_index->partners(p)) {
        if (marked(q) && q->getUid() < p->getUid()) continue;  // a pair of two stepped bodies: once
        if (btBroadphasePair* pair = cache->findPair(p, q)) d->getNearCallback()(*pair, *d, info);
      }
    }
    for (btRigidBody* b : stepped) mark(b->getBroadphaseHandle(), 0);
  }
  // (Outside stepSimulation, e.g. the collision pass of a checkpoint restore, Bullet's own.)
  void updateAabbs() override {
    if (!in_step_ || m_forceUpdateAllAabbs) return btDiscreteDynamicsWorld::updateAabbs();
    for (btRigidBody* b : by_world_index_)
      if (b->isActive()) updateSingleAabb(b);
  }
  void saveKinematicState(btScalar timeStep) override {
    if (!in_step_) return btDiscreteDynamicsWorld::saveKinematicState(timeStep);
    for (btRigidBody* b : by_world_index_)
      if (b->getActivationState() != ISLAND_SLEEPING && b->isKinematicObject()) b->saveKinematicState(timeStep);
  }
  void addRigidBody(btRigidBody* body) override {
    btDiscreteDynamicsWorld::addRigidBody(body);
    nonstatic_order_stale_ = true;
  }
  void addRigidBody(btRigidBody* body, int group, int mask) override {
    btDiscreteDynamicsWorld::addRigidBody(body, group, mask);
    nonstatic_order_stale_ = true;
  }
  void removeRigidBody(btRigidBody* body) override {
    btDiscreteDynamicsWorld::removeRigidBody(body);
    nonstatic_order_stale_ = true;
  }

  void calculateSimulationIslands() override {
    if (!managed_sleep) btDiscreteDynamicsWorld::calculateSimulationIslands();
  }
  void updateActivationState(btScalar dt) override {
    if (!managed_sleep) btDiscreteDynamicsWorld::updateActivationState(dt);
  }

  /// With managed_sleep: called after each solve (set by the owner). Returns true when it woke
  /// sleeping bodies the solve took (RigidWorld's check_sleepers: each now dynamic, appended to
  /// `stepped`, its joints to `awake_joints`); the solve is then done again from the state before
  /// it -- the stepped bodies' velocities and poses, the solved contact points' impulses and
  /// friction directions -- with those bodies awake, and they are integrated with the others.
  /// The argument: whether the solve may be done again (false after max_repeats repeats: the owner
  /// then wakes what it would have woken without a repeat).
  std::function<bool(bool)> after_solve;
  /// Repeats of one step's solve at most: each costs a solve of every stepped body, and each wakes
  /// the sleeping blocks the last one stopped (a chain of sleeping blocks crossed in one step needs
  /// one per block).
  int max_repeats = 16;
  std::size_t repeated_solves = 0;  ///< solves done again (a count, for tests and benches)
  /// With managed_sleep: set by the owner before each step, false when no block sleeps and nothing
  /// is left to check (the solve is then neither saved nor checked).
  bool check_after_solve = false;

  void solveConstraints(btContactSolverInfo& info) override {
    if (!managed_sleep || !after_solve || !check_after_solve) return solve_once(info, false);
    first_round_ = true;
    solve_once(info, true);
    int repeats = 0;
    for (std::size_t n = stepped.size(); after_solve(repeats < max_repeats); n = stepped.size()) {
      ++repeats;
      ++repeated_solves;
      // The woken bodies were fixed in the solve (not written): their state now is the one before it.
      for (std::size_t i = n; i < stepped.size(); ++i)
        saved_bodies_.push_back({stepped[i], stepped[i]->getLinearVelocity(), stepped[i]->getAngularVelocity(),
                                 stepped[i]->getWorldTransform()});
      restore_before_solve();
      restep_bodies();
      solve_once(info, true);  // (saves the contact points the woken bodies brought in)
    }
  }

  /// The contact manifolds of the last solve (those with an awake body), in solve order.
  const std::vector<btPersistentManifold*>& solved_manifolds() const { return manifolds_; }

 private:
  // What a solve writes: the bodies' velocities and (split impulse) poses, and each solved contact
  // point's impulses and friction directions (Bullet's btSequentialImpulseConstraintSolver; the
  // joints' rows and feedback start from zero in every solve).
  struct BodyState {
    btRigidBody* body;
    btVector3 v, w;
    btTransform pose;
  };
  struct PointState {
    btManifoldPoint* point;
    btScalar j, j1, j2;
    btVector3 d1, d2;
    int flags;
  };
  std::vector<BodyState> saved_bodies_;
  std::vector<PointState> saved_points_;
  std::vector<btPersistentManifold*> saved_manifolds_;  // sorted (by address)
  bool first_round_ = true;
  /// The first solve of a step: the stepped bodies and the solved contact points; a repeated one:
  /// the contact points not saved yet (the woken bodies' contacts with sleeping ones).
  void save_before_solve() {
    if (first_round_) {
      saved_bodies_.clear();
      for (int i = 0; i < m_nonStaticRigidBodies.size(); ++i) {
        btRigidBody* b = m_nonStaticRigidBodies[i];
        saved_bodies_.push_back({b, b->getLinearVelocity(), b->getAngularVelocity(), b->getWorldTransform()});
      }
      saved_points_.clear();
      saved_manifolds_.clear();
    }
    const std::size_t before = saved_manifolds_.size();
    for (btPersistentManifold* m : manifolds_) {
      if (!first_round_ && std::binary_search(saved_manifolds_.begin(), saved_manifolds_.begin() + before, m)) continue;
      saved_manifolds_.push_back(m);
      for (int c = 0; c < m->getNumContacts(); ++c) {
        btManifoldPoint& p = m->getContactPoint(c);
        saved_points_.push_back({&p, p.m_appliedImpulse, p.m_appliedImpulseLateral1, p.m_appliedImpulseLateral2,
                                 p.m_lateralFrictionDir1, p.m_lateralFrictionDir2, p.m_contactPointFlags});
      }
    }
    std::sort(saved_manifolds_.begin(), saved_manifolds_.end());
    first_round_ = false;
  }
  void restore_before_solve() {
    for (const BodyState& s : saved_bodies_) {
      s.body->setLinearVelocity(s.v);
      s.body->setAngularVelocity(s.w);
      s.body->setWorldTransform(s.pose);
    }
    for (const PointState& s : saved_points_) {
      btManifoldPoint& p = *s.point;
      p.m_appliedImpulse = s.j;
      p.m_appliedImpulseLateral1 = s.j1;
      p.m_appliedImpulseLateral2 = s.j2;
      p.m_lateralFrictionDir1 = s.d1;
      p.m_lateralFrictionDir2 = s.d2;
      p.m_contactPointFlags = s.flags;
    }
  }
  /// The stepped bodies (with those woken after a solve) as the array the solve and the integration
  /// walk, in Bullet's order.
  void restep_bodies() {
    std::sort(stepped.begin(), stepped.end(),
              [](const btRigidBody* a, const btRigidBody* b) { return a->getUserIndex3() < b->getUserIndex3(); });
    m_nonStaticRigidBodies.resize(static_cast<int>(stepped.size()));
    for (std::size_t i = 0; i < stepped.size(); ++i) m_nonStaticRigidBodies[static_cast<int>(i)] = stepped[i];
  }

  void solve_once(btContactSolverInfo& info, bool save) {
    btDispatcher* d = getDispatcher();
    // Sleeping and waking, as Bullet's buildAndProcessIslands does before it solves.
    if (!managed_sleep) m_islandManager->buildIslands(d, this);
    auto awake = [](const btCollisionObject* o) {
      return !o->isStaticOrKinematicObject() && o->getActivationState() != ISLAND_SLEEPING;
    };
    bodies_.clear();
    for (int i = 0; i < m_nonStaticRigidBodies.size(); ++i)
      if (awake(m_nonStaticRigidBodies[i])) bodies_.push_back(m_nonStaticRigidBodies[i]);
    // (The same sequence as sorting all manifolds and filtering afterwards: the keys are unique.)
    sorted_manifolds_if(d, manifolds_, [&](const btPersistentManifold* m) {
      const btCollisionObject* a = m->getBody0();
      const btCollisionObject* b = m->getBody1();
      return (awake(a) || awake(b)) && d->needsResponse(a, b);
    });
    constraints_.clear();
    if (managed_sleep) {
      constraints_ = awake_joints;
    } else {
      for (btTypedConstraint* c : joint_order)
        if (c && c->isEnabled() && (awake(&c->getRigidBodyA()) || awake(&c->getRigidBodyB())))
          constraints_.push_back(c);
    }
    if (save) save_before_solve();
    m_constraintSolver->prepareSolve(getNumCollisionObjects(), d->getNumManifolds());
    if (!bodies_.empty() || !manifolds_.empty() || !constraints_.empty())
      m_constraintSolver->solveGroup(bodies_.empty() ? nullptr : bodies_.data(), static_cast<int>(bodies_.size()),
                                     manifolds_.empty() ? nullptr : manifolds_.data(),
                                     static_cast<int>(manifolds_.size()),
                                     constraints_.empty() ? nullptr : constraints_.data(),
                                     static_cast<int>(constraints_.size()), info, m_debugDrawer, d);
    m_constraintSolver->allSolved(info, m_debugDrawer);
  }

  bool nonstatic_order_stale_ = true;
  bool in_step_ = false;  // inside a managed stepSimulation
  btAlignedObjectArray<btRigidBody*> all_nonstatic_;  // m_nonStaticRigidBodies outside a managed step
  std::vector<btRigidBody*> by_world_index_;
  std::vector<char> root_mark_;  // by proxy uid: a stepped body's, during a dispatch
  void mark(const btBroadphaseProxy* p, char v) {
    const auto u = static_cast<std::size_t>(p->getUid());
    if (u >= root_mark_.size()) root_mark_.resize(u + 1, 0);
    root_mark_[u] = v;
  }
  bool marked(const btBroadphaseProxy* p) const {
    const auto u = static_cast<std::size_t>(p->getUid());
    return u < root_mark_.size() && root_mark_[u];
  }
  std::vector<btCollisionObject*> bodies_;
  std::vector<btPersistentManifold*> manifolds_;
  std::vector<btTypedConstraint*> constraints_;
};

}  // namespace hs::rigid::detail
