// Far sleep (RigidWorldDef::far_sleep, docs/rigid.md "Far sleep"): a block far from the action stays
// bit-still and is not stepped; the action reaches a sleeping block in time (a structure approaching,
// a chain of contacts, a chain of joints); a checkpoint taken with blocks asleep continues
// bit-identically.
#include "common/error.h"
#include "common/state_archive.h"
#include "rigid/rigid_world.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

namespace hs::rigid {
namespace {

constexpr double kRhoI = 910.0;

RigidWorldDef sleepy(bool on, bool start_asleep = true) {
  RigidWorldDef d;
  d.dt = 1.0 / 240.0;
  d.far_sleep.enabled = on;
  d.far_sleep.start_asleep = start_asleep;
  d.far_sleep.still_time = 0.2;
  d.far_sleep.wake_distance = 1.0;
  return d;
}

// A vertical square plate (side 2s) in the plane x = 0 of its frame: a structure face pushing in +x.
KinematicMeshDef wall_mesh(double s, const Vec3& at, const Vec3& v) {
  KinematicMeshDef d;
  d.vertices = {Vec3(0, -s, -s), Vec3(0, s, -s), Vec3(0, s, s), Vec3(0, -s, s)};
  d.triangles = {{0, 1, 2}, {0, 2, 3}};
  d.position = at;
  d.velocity = v;
  return d;
}

// A 1 m x 1 m x 0.6 m floe at its flotation draft.
BlockDef floe(double x, double y = 0.0) {
  BlockDef b;
  b.half_extents = Vec3(0.5, 0.5, 0.3);
  b.density = kRhoI;
  b.position = Vec3(x, y, 0.3 - 0.6 * kRhoI / 1025.0);
  return b;
}

bool same_pose(const RigidWorld& w, BlockId id, const Vec3& x, const Quat& q) {
  const Vec3 p = w.position(id);
  const Quat o = w.orientation(id);
  return p.x() == x.x() && p.y() == x.y() && p.z() == x.z() && o.w() == q.w() && o.x() == q.x() && o.y() == q.y() &&
         o.z() == q.z();
}

TEST(FarSleep, FarBlockFallsAsleepAndStaysBitStill) {
  // A floe released 2 cm above its draft, 50 m from a structure moving away from it. It heaves,
  // settles below 1 cm/s, sleeps after still_time, and then keeps its pose to the last bit while the
  // world steps on. Without the rule it is stepped at every sub-step and never asleep.
  for (const bool on : {true, false}) {
    RigidWorld w(sleepy(on, false));
    w.add_kinematic_mesh(wall_mesh(2.0, Vec3(-50, 0, 0), Vec3(-0.5, 0, 0)));
    BlockDef b = floe(0.0);
    b.position.z() += 0.02;
    const BlockId id = w.add_block(b);
    w.step(6.0);
    const Vec3 x = w.position(id);
    const Quat q = w.orientation(id);
    w.step(2.0);
    if (on) {
      EXPECT_TRUE(w.asleep(id));
      EXPECT_EQ(w.awake_count(), 0u);
      EXPECT_TRUE(same_pose(w, id, x, q));
      EXPECT_EQ(w.velocity(id).norm(), 0.0);
      // Slept near its draft: the heave had decayed to < 1 cm/s (the rule's speed).
      // (A heave slower than `speed` is frozen where it is: the rule's error (2), docs/rigid.md.)
      EXPECT_NEAR(w.position(id).z(), floe(0.0).position.z(), 2e-2);  // m; measured 4.6e-3
    } else {
      EXPECT_FALSE(w.asleep(id));
      EXPECT_EQ(w.awake_count(), 1u);
    }
  }
}

TEST(FarSleep, SleepingBlocksCostNothing) {
  // 1600 separate floes far from a structure: with far sleep none of them is stepped (integrated by
  // the solver) once asleep; without it every one at every sub-step. Counted (stepped_body_count),
  // not timed: a timing ratio depends on the machine's load.
  constexpr int kSubsteps = 50;
  auto stepped_in_substeps = [](bool on) {
    RigidWorld w(sleepy(on));
    w.add_kinematic_mesh(wall_mesh(2.0, Vec3(-500, 0, 0), Vec3::Zero()));
    for (int i = 0; i < 40; ++i)
      for (int j = 0; j < 40; ++j) w.add_block(floe(1.5 * i, 1.5 * j));
    w.step(0.05);  // asleep from the first sub-step (start_asleep)
    const std::uint64_t before = w.stepped_body_count();
    for (int k = 0; k < kSubsteps; ++k) w.substep();
    return std::make_pair(w.stepped_body_count() - before, w.awake_count());
  };
  const auto [stepped_on, awake_when_on] = stepped_in_substeps(true);
  const auto [stepped_off, awake_when_off] = stepped_in_substeps(false);
  EXPECT_EQ(awake_when_on, 0u);
  EXPECT_EQ(awake_when_off, 1600u);
  EXPECT_EQ(stepped_on, 0u);                   // measured 0
  EXPECT_EQ(stepped_off, 1600u * kSubsteps);  // measured 80000
  std::printf("[ far sleep ] 1600 floes, %d sub-steps: %llu blocks stepped asleep, %llu awake\n", kSubsteps,
              static_cast<unsigned long long>(stepped_on), static_cast<unsigned long long>(stepped_off));
}

TEST(FarSleep, ApproachingStructureWakesBlockInTime) {
  // A sleeping floe in the path of a structure face moving at 0.5 m/s: it must be awake before the
  // face arrives, or the face (kinematic) would pass through the sleeping (immovable) block without
  // a contact. Checked: the floe is pushed ahead of the face, and moves as it does without the rule.
  double x_end[2];
  for (const bool on : {true, false}) {
    RigidWorld w(sleepy(on));
    const int m = w.add_kinematic_mesh(wall_mesh(2.0, Vec3(-3.0, 0, 0), Vec3(0.5, 0, 0)));
    const BlockId id = w.add_block(floe(0.0));
    w.step(0.5);
    if (on) {
      EXPECT_TRUE(w.asleep(id));  // 2.5 m away: outside the wake distance (1 m + half size)
    }
    w.step(6.0);
    EXPECT_FALSE(w.asleep(id));
    // The face is at x = 0.25 m; the floe's back face ahead of it.
    EXPECT_GT(w.position(id).x() - 0.5, w.mesh_position(m).x() - 0.01) << (on ? "far sleep" : "awake");
    x_end[on] = w.position(id).x();
  }
  EXPECT_NEAR(x_end[1], x_end[0], 0.01);  // m; measured 0 (woken before any contact)
  std::printf("[ far sleep ] pushed floe at x = %.6f m (far sleep) vs %.6f m (all awake)\n", x_end[1], x_end[0]);
}

// A row of n touching floes (with freeze joints between neighbours when `joined`), asleep; the first
// is pushed (an impulse, as the particles give). The motion reaches the last floe through the chain.
std::vector<Vec3> pushed_row(bool on, bool joined, int n, std::vector<bool>* moved = nullptr,
                             bool start_asleep = false, int hops = -1) {
  // (Awake for still_time first, as a ridge at rest: the floes' contacts exist when they fall
  // asleep; with start_asleep they never had any: asleep from the first sub-step.)
  RigidWorldDef d = sleepy(on, start_asleep);
  if (hops >= 0) d.far_sleep.wake_hops = hops;
  RigidWorld w(d);
  std::vector<BlockId> ids;
  for (int i = 0; i < n; ++i) ids.push_back(w.add_block(floe(1.0 * i)));
  if (joined)
    for (int i = 0; i + 1 < n; ++i)
      w.add_freeze_joint({ids[i], ids[i + 1], Vec3(0.5 + i, 0, floe(0).position.z()), Vec3::UnitX(), 0.3});
  w.step(0.5);
  for (const BlockId id : ids) EXPECT_EQ(w.asleep(id), on);
  // 1 m/s into the row: an impulse at the first floe's centre, from the -x side.
  const BlockId first = ids.front();
  w.add_impulse(first, Vec3(w.mass(first) * 1.0, 0, 0), w.position(first));
  w.step(1.0);
  std::vector<Vec3> x;
  for (const BlockId id : ids) x.push_back(w.position(id));
  if (moved) {  // a block never woken keeps its pose to the last bit
    moved->clear();
    for (int i = 0; i < n; ++i) moved->push_back(!(x[i] == floe(1.0 * i).position));
  }
  return x;
}

// The row pushed with far sleep against the same row with every floe awake: every floe woke, the
// push reached the last floe (> 5 cm all awake). Returns the largest position difference and where
// the last far-sleep floe and the first all-awake floe ended.
struct RowResult {
  double worst, last_x, first_awake_x;
};
RowResult row_against_awake(const char* what, bool joined, bool start_asleep = false, int hops = -1) {
  constexpr int n = 6;
  std::vector<bool> woke;
  const auto on = pushed_row(true, joined, n, &woke, start_asleep, hops);
  const auto off = pushed_row(false, joined, n);
  double worst = 0.0;
  for (int i = 0; i < n; ++i) {
    EXPECT_TRUE(woke[i]) << "floe " << i << " never woke";
    worst = std::max(worst, (on[i] - off[i]).norm());
  }
  EXPECT_GT(off.back().x() - (n - 1.0), 0.05);  // the push reached the last floe (moved > 5 cm)
  std::printf("[ far sleep ] %s: last floe moved %.4f m (far sleep) vs %.4f m; worst difference %.2e m\n", what,
              on.back().x() - (n - 1.0), off.back().x() - (n - 1.0), worst);
  return {worst, on.back().x(), off.front().x()};
}

TEST(FarSleep, ChainOfContactsWakesInTime) {
  // The push crosses the sleeping floes within one sub-step: each stops it as an immovable block,
  // the load it takes departs from the one it holds, it wakes and the sub-step is solved again
  // (check_sleepers), so the row moves as with every floe awake.
  const RowResult r = row_against_awake("contact chain", false);
  EXPECT_GT(r.last_x - r.first_awake_x, 0.0);
  EXPECT_LT(r.worst, 1e-12);  // m; measured 1.8e-14 (9.7e-3 when a woken floe was not solved again)
}

TEST(FarSleep, ChainOfContactsStartedAsleepWakesInTime) {
  // The same row asleep from the first sub-step (start_asleep, as bench hybrid's ridge): two
  // sleeping floes were never collided, so a floe woken by the solve is collided with its sleeping
  // neighbours before the repeat (collide_with_inactive); without that it has no contact with the
  // next floe in the repeat and the push does not cross the row within the sub-step.
  const double worst = row_against_awake("contact chain started asleep", false, true).worst;
  EXPECT_LT(worst, 1e-12);  // m; measured 2.3e-14 (5.1e-2 without collide_with_inactive)
}

TEST(FarSleep, ChainOfJointsWakesInTime) {
  const double worst = row_against_awake("joint chain", true).worst;
  // (1.3e-11 before the woken floes' contacts with sleeping ones were collided again before the
  // repeat, collide_with_inactive: the refreshed points move the result in the last bits)
  EXPECT_LT(worst, 6e-10);  // m; measured 6.0e-11 (1.3e-3 when a woken floe was not solved again)
}

// A row of dry blocks on a fixed floor (no water), asleep, the first pushed at 1 m/s: each block the
// push reaches wakes in a repeated solve. The rule's error (1) (docs/rigid.md): a block woken for a
// repeat has no weight in that sub-step (the force pass that gave the other blocks theirs ran
// before the solve), so its floor contact and friction differ from the all-awake row's for one
// sub-step.
TEST(FarSleep, ChainOfDryBlocksOnAFloorWakesInTime) {
  constexpr int n = 5;
  auto row = [&](bool on) {
    RigidWorldDef d = sleepy(on, true);
    d.water = false;
    d.far_sleep.wake_hops = 0;
    RigidWorld w(d);
    BlockDef floor;
    floor.half_extents = Vec3(20, 5, 0.5);
    floor.position = Vec3(2, 0, -0.5);
    floor.fixed = true;
    w.add_block(floor);
    std::vector<BlockId> ids;
    for (int i = 0; i < n; ++i) {
      BlockDef b = floe(1.0 * i);
      b.position.z() = 0.3;
      ids.push_back(w.add_block(b));
    }
    w.step(0.25);
    w.add_impulse(ids[0], Vec3(w.mass(ids[0]) * 1.0, 0, 0), w.position(ids[0]));
    w.step(0.5);
    std::vector<Vec3> x;
    for (const BlockId id : ids) x.push_back(w.position(id));
    return x;
  };
  const auto on = row(true), off = row(false);
  double worst = 0.0;
  for (int i = 0; i < n; ++i) worst = std::max(worst, (on[i] - off[i]).norm());
  EXPECT_GT(off.back().x() - (n - 1.0), 0.005);  // the push reached the last block (7.0 mm)
  // m; measured 3.7e-4 (1.1e-4 with the weight given before the repeat, which is not done:
  // docs/rigid.md "Far sleep"); 7e-3 without the repeated solve, the last block never reached.
  EXPECT_LT(worst, 4e-3);
  std::printf("[ far sleep ] dry chain on a floor: last block moved %.4f m (all awake %.4f m); worst difference %.2e m\n",
              on.back().x() - (n - 1.0), off.back().x() - (n - 1.0), worst);
}

TEST(FarSleep, ChainsWakeInTimeWithoutHops) {
  // wake_hops 0 (bench hybrid's setting): no moving block wakes its neighbours ahead of the push;
  // the solve alone wakes each floe the push reaches, within the sub-step, so the rows move as
  // with the hops and as with every floe awake.
  const double contacts = row_against_awake("contact chain, no hops", false, true, 0).worst;
  const double joints = row_against_awake("joint chain, no hops", true, false, 0).worst;
  EXPECT_LT(contacts, 1e-12);  // m; measured 2.3e-14, as with 4 hops (7.3e-2 without the repeated solve)
  EXPECT_LT(joints, 6e-10);    // m; measured 6.0e-11, as with 4 hops (7.2e-2 without the repeated solve)
}

// An awake floe beside a sleeping one (wake_hops 0: only the solve itself can wake it), the awake
// one driven by a constant caller force of 500 N (which keeps it awake). A sleeping block has no
// mass in the solve (immovable); after each solve it either holds its load, or wakes when the load
// departs from the one it fell asleep under by more than it would take, free, to move faster than
// `speed` in one solve, and the sub-step is solved again with it awake (check_sleepers, docs/rigid.md
// "Far sleep"). These tests fail when the pair of an awake and a sleeping block is dropped (checked
// before check_sleepers: the contact skipped by the near callback, the joint left out of the solve).
struct AwakeBesideAsleep {
  RigidWorld w;
  BlockId asleep, awake;
  Vec3 x0;
  Quat q0;
  // field: 36 more floes, touching one another in a 6 x 6 square 10 m away (see
  // FarSleep.PairIndexDispatch...).
  AwakeBesideAsleep(double gap, bool far_sleep = true, bool field = false) : w(hopless(far_sleep)) {
    w.add_kinematic_mesh(wall_mesh(2.0, Vec3(-50, 0, 0), Vec3::Zero()));
    asleep = w.add_block(floe(0.0));
    awake = w.add_block(floe(1.0 + gap));
    if (field)
      for (int i = 0; i < 6; ++i)
        for (int j = 0; j < 6; ++j) w.add_block(floe(10.0 + i, 10.0 + j));
    w.step(0.05);
    x0 = w.position(asleep);
    q0 = w.orientation(asleep);
  }
  static RigidWorldDef hopless(bool far_sleep) {
    RigidWorldDef d = sleepy(far_sleep);
    d.far_sleep.wake_hops = 0;
    return d;
  }
};

TEST(FarSleep, AwakeBlockPressingOnSleepingBlockIsHeld) {
  // Face to face and pushed into the sleeping floe with 500 N, the awake floe is held where it
  // touches (x = 1.0), and the sleeping one keeps its pose to the last bit: the push changes the
  // load it holds by F h / m ~ 4 mm/s per solve, below `speed`.
  AwakeBesideAsleep s(0.0);
  ASSERT_TRUE(s.w.asleep(s.asleep));
  s.w.add_force(s.awake, Vec3(-500.0, 0, 0), s.w.position(s.awake));
  s.w.step(3.0);
  EXPECT_FALSE(s.w.asleep(s.awake));
  EXPECT_TRUE(s.w.asleep(s.asleep));
  EXPECT_TRUE(same_pose(s.w, s.asleep, s.x0, s.q0));
  EXPECT_NEAR(s.w.position(s.awake).x(), 1.0, 1e-3);  // m; measured 2e-6 (5.2e-2 when the solve moved a sleeper)
  std::printf("[ far sleep ] awake floe pressed on a sleeping one: held at x = %.5f m (face at 1.0)\n",
              s.w.position(s.awake).x());
}

TEST(FarSleep, AwakeBlockHittingSleepingBlockWakesIt) {
  // Driven across a 0.2 m gap, the awake floe hits the sleeping one: the impulse it takes departs
  // from the one it held, it wakes and the sub-step is solved again with it awake, so both end
  // where they end with every block awake (the momentum is passed on, not reflected).
  Vec3 end[2][2];
  for (const bool on : {true, false}) {
    AwakeBesideAsleep s(0.2, on);
    EXPECT_EQ(s.w.asleep(s.asleep), on);
    s.w.add_force(s.awake, Vec3(-500.0, 0, 0), s.w.position(s.awake));
    s.w.step(3.0);
    EXPECT_FALSE(s.w.asleep(s.asleep));
    end[on][0] = s.w.position(s.asleep);
    end[on][1] = s.w.position(s.awake);
  }
  const double worst = std::max((end[1][0] - end[0][0]).norm(), (end[1][1] - end[0][1]).norm());
  EXPECT_LT(end[0][0].x(), -0.1);  // the hit floe was pushed (all awake: measured -0.459 m)
  EXPECT_LT(worst, 3e-5);          // m; measured 3.3e-6 (2.6e-4 when it woke one sub-step late)
  std::printf("[ far sleep ] hit floe at x = %.4f m (far sleep) vs %.4f m (all awake); worst difference %.2e m\n",
              end[1][0].x(), end[0][0].x(), worst);
}

TEST(FarSleep, PairIndexDispatchKeepsTheContactOfAnAwakeAndASleepingBlock) {
  // The two tests above beside a field of 36 sleeping floes that touch one another: their ~100
  // overlapping pairs outnumber four times the pairs the stepped bodies list (the awake floe's one
  // and the wall's none), so every step dispatches through the pair index instead of Bullet's walk
  // over all pairs (CanonicalWorld::performDiscreteCollisionDetection). The same results: held to
  // 1e-3 m and the sleeping floe's pose to the last bit; hit, it moves as with every block awake.
  // Fails when the index leaves out the pair of an awake and a sleeping block (checked).
  {
    AwakeBesideAsleep s(0.0, true, true);
    ASSERT_TRUE(s.w.asleep(s.asleep));
    s.w.add_force(s.awake, Vec3(-500.0, 0, 0), s.w.position(s.awake));
    s.w.step(3.0);
    EXPECT_TRUE(s.w.asleep(s.asleep));
    EXPECT_TRUE(same_pose(s.w, s.asleep, s.x0, s.q0));
    EXPECT_NEAR(s.w.position(s.awake).x(), 1.0, 1e-3);  // m; measured 8e-5, as without the field
  }
  Vec3 end[2];
  for (const bool on : {true, false}) {
    AwakeBesideAsleep s(0.2, on, true);
    s.w.add_force(s.awake, Vec3(-500.0, 0, 0), s.w.position(s.awake));
    s.w.step(3.0);
    EXPECT_FALSE(s.w.asleep(s.asleep));
    end[on] = s.w.position(s.asleep);
  }
  EXPECT_LT(end[0].x(), -0.1);                // the hit floe was pushed
  EXPECT_LT((end[1] - end[0]).norm(), 3e-5);  // m; measured 3.3e-6, as without the field
  std::printf("[ far sleep ] beside 36 sleeping floes: hit floe at x = %.4f m (far sleep) vs %.4f m (all awake)\n",
              end[1].x(), end[0].x());
}

TEST(FarSleep, JointToSleepingBlockHolds) {
  // Jointed face to face to the sleeping floe and pulled away from it with 500 N (a tenth of the
  // 0.1 m^2 joint's strength), the awake floe stays put and the sleeping one keeps its pose: a joint
  // with one awake block is solved. Without it the floe drifts ~1 m in 3 s.
  AwakeBesideAsleep s(0.0);
  FreezeJointDef j;
  j.a = s.asleep;
  j.b = s.awake;
  j.anchor = Vec3(0.5, 0.0, s.x0.z());
  j.normal = Vec3(1, 0, 0);
  j.area = 0.1;
  s.w.add_freeze_joint(j);
  const Vec3 start = s.w.position(s.awake);
  s.w.add_force(s.awake, Vec3(500.0, 0, 0), start);
  s.w.step(3.0);
  EXPECT_FALSE(s.w.asleep(s.awake));
  EXPECT_TRUE(s.w.asleep(s.asleep));
  EXPECT_TRUE(same_pose(s.w, s.asleep, s.x0, s.q0));
  EXPECT_EQ(s.w.broken_joint_count(), 0u);
  EXPECT_LT((s.w.position(s.awake) - start).norm(), 1e-6);  // m; measured 9e-22 (8.0e-5 when the solve moved a sleeper, 5.4e-2 before it was put back)
  std::printf("[ far sleep ] awake floe jointed to a sleeping one, pulled: moved %.2e m\n",
              (s.w.position(s.awake) - start).norm());
}

// A 0.5 m x 0.5 m x 0.3 m block lying on a floating floe (a keel block carrying the ones above it,
// in small): the block is kept awake by the caller (a load of 1 uN, as the particles keep the blocks
// they touch awake), the floe falls asleep under it. Returns the block's largest speed and its
// displacement over the `run` seconds from the sub-step the floe fell asleep.
struct Resting {
  double top_speed = 0.0, top_moved = 0.0;
  bool floe_asleep = false, floe_still = false;
};
Resting block_on_sleeping_floe(bool far_sleep, bool loads_wake_neighbours, double run) {
  RigidWorldDef d = sleepy(far_sleep, false);
  d.far_sleep.loads_wake_neighbours = loads_wake_neighbours;
  RigidWorld w(d);
  w.add_kinematic_mesh(wall_mesh(2.0, Vec3(-50, 0, 0), Vec3::Zero()));
  BlockDef f = floe(0.0);
  f.half_extents = Vec3(1.0, 1.0, 0.3);  // 2 m x 2 m: the load moves its draft by ~2 cm
  const BlockId floe_id = w.add_block(f);
  BlockDef b;
  b.half_extents = Vec3(0.25, 0.25, 0.15);
  b.density = kRhoI;
  b.position = Vec3(0.0, 0.0, f.position.z() + 0.3 + 0.15);
  const BlockId top = w.add_block(b);
  w.add_force(top, Vec3(0, 0, -1e-6), w.position(top));
  // Settles until the floe falls asleep (its heave below `speed` for still_time: ~1.7 s), at most 6 s;
  // all awake: 1.7 s as well.
  for (int k = 0; k < 1440 && !(far_sleep && w.asleep(floe_id)); ++k) w.substep();
  if (!far_sleep) w.step(1.7);
  const Vec3 x0 = w.position(top), f0 = w.position(floe_id);
  const Quat q0 = w.orientation(floe_id);
  Resting r;
  const long n = std::lround(run / d.dt);
  for (long k = 0; k < n; ++k) {
    w.substep();
    r.top_speed = std::max(r.top_speed, w.velocity(top).norm());
  }
  r.top_moved = (w.position(top) - x0).norm();
  r.floe_asleep = w.asleep(floe_id);
  r.floe_still = same_pose(w, floe_id, f0, q0);
  return r;
}

TEST(FarSleep, BlockRestingOnSleepingFloeIsHeld) {
  // The load path of a ridge at rest: a sleeping block carries the awake one lying on it. Asleep, the
  // floe gets no gravity or water load and its other supports are not solved; it holds the block as
  // an immovable one would, and the block stays as still as with every block awake. When the
  // solve moved a sleeping block (it had its mass there and was put back after), the block sank
  // into it after it fell asleep (2.2e-5 m here, block 1/32 of the floe's mass); on the keel ridge
  // at rest that was the jolt that woke most of it again (docs/rigid.md, "Far sleep").
  const Resting on = block_on_sleeping_floe(true, false, 2.0);
  const Resting off = block_on_sleeping_floe(false, false, 2.0);
  EXPECT_TRUE(on.floe_asleep);
  EXPECT_TRUE(on.floe_still);
  EXPECT_FALSE(off.floe_asleep);
  EXPECT_LT(on.top_speed, 1e-9);   // m/s; measured 2.7e-11 (1.0e-3 when the solve moved the sleeper)
  EXPECT_LT(on.top_moved, 1e-10);  // m; measured 4.2e-12 (2.1e-5 when the solve moved the sleeper)
  std::printf("[ far sleep ] block on a sleeping floe: largest speed %.2e m/s, moved %.2e m in 2 s "
              "(all awake: %.2e m/s, %.2e m)\n",
              on.top_speed, on.top_moved, off.top_speed, off.top_moved);
}

TEST(FarSleep, LoadedBlockKeepsOnlyItselfAwake) {
  // The caller's load keeps the block awake; by default it does not keep its neighbour awake while
  // it does not move (the floe sleeps under it, above); with loads_wake_neighbours it does, as a
  // moving block would.
  EXPECT_TRUE(block_on_sleeping_floe(true, false, 0.5).floe_asleep);
  EXPECT_FALSE(block_on_sleeping_floe(true, true, 0.5).floe_asleep);
}

TEST(FarSleep, CheckpointWithSleepingBlocksContinuesBitIdentically) {
  // A structure walks into a field of sleeping floes; a checkpoint while some are awake and some
  // asleep, restored into a world built the same way, continues to the same bits.
  auto build = [](RigidWorld& w) {
    w.add_kinematic_mesh(wall_mesh(2.0, Vec3(-2.0, 0, 0), Vec3(0.5, 0, 0)));
    std::vector<BlockId> ids;
    for (int i = 0; i < 12; ++i)  // 0.2 m apart: only the floes the face pushes into others wake
      for (int j = -2; j <= 2; ++j) ids.push_back(w.add_block(floe(1.2 * i, 1.2 * j)));
    return ids;
  };
  RigidWorld a(sleepy(true));
  const auto ids = build(a);
  a.step(4.0);
  std::size_t asleep = 0;
  for (const BlockId id : ids) asleep += a.asleep(id);
  EXPECT_GT(asleep, 0u);
  EXPECT_LT(asleep, ids.size());
  StateArchive ar;
  a.save_state(ar, "w/");
  RigidWorld b(sleepy(true));
  build(b);
  EXPECT_EQ(b.load_state(ar, "w/"), 0u);
  for (int k = 0; k < 480; ++k) {
    a.substep();
    b.substep();
  }
  for (const BlockId id : ids) {
    EXPECT_TRUE(same_pose(b, id, a.position(id), a.orientation(id))) << "block " << id.index;
    EXPECT_EQ(a.asleep(id), b.asleep(id));
  }
}

TEST(FarSleep, CheckpointKeepsTheLoadASleepingBlockHolds) {
  // An awake floe pushes on a sleeping one with a force growing by 400 N/s from 500 N: the sleeping
  // floe (asleep before the push began) wakes once the load it holds has grown by more than
  // m speed / h = 546 kg x 0.01 m/s x 240 /s = 1,310 N, at (1,310 - 500) / 400 = 2.026 s. A
  // checkpoint at 1 s keeps that reference: restored, the world wakes it at the same sub-step and
  // continues to the same bits (taken again at the restart, the reference would absorb the 900 N
  // pushing then, and the floe would wake at 4.3 s).
  auto push = [](AwakeBesideAsleep& s, long k) {
    s.w.clear_external_forces();
    s.w.add_force(s.awake, Vec3(-(500.0 + 400.0 * static_cast<double>(k) / 240.0), 0, 0), s.w.position(s.awake));
    s.w.substep();
  };
  AwakeBesideAsleep a(0.0);
  long k = 0;
  for (; k < 240; ++k) push(a, k);
  ASSERT_TRUE(a.w.asleep(a.asleep));
  StateArchive ar;
  a.w.save_state(ar, "w/");
  AwakeBesideAsleep b(0.0);
  EXPECT_EQ(b.w.load_state(ar, "w/"), 0u);
  long woke_a = -1, woke_b = -1;
  for (; k < 1200; ++k) {
    push(a, k);
    push(b, k);
    if (woke_a < 0 && !a.w.asleep(a.asleep)) woke_a = k;
    if (woke_b < 0 && !b.w.asleep(b.asleep)) woke_b = k;
  }
  EXPECT_NEAR(static_cast<double>(woke_a) / 240.0, 2.026, 2.0 / 240.0);  // s; measured 2.029 (one sub-step)
  EXPECT_EQ(woke_a, woke_b);
  EXPECT_TRUE(same_pose(b.w, b.asleep, a.w.position(a.asleep), a.w.orientation(a.asleep)));
  EXPECT_TRUE(same_pose(b.w, b.awake, a.w.position(a.awake), a.w.orientation(a.awake)));
  std::printf("[ far sleep ] growing push: the sleeping floe woke at %.3f s (restored at 1 s: %.3f s)\n",
              static_cast<double>(woke_a) / 240.0, static_cast<double>(woke_b) / 240.0);
}

// loads_held: a sleeping floe under the caller's force (as the particles load a keel block) holds a
// steady load asleep, and wakes once the load has changed by m speed / h = 546 kg x 0.01 m/s x 240 /s
// = 1,310 N: a force of 500 N from 0.05 s on (3.8 mm/s per solve, held), growing by 400 N/s from
// 1.05 s on, wakes it at 1.05 + (1,310 - 500) / 400 = 3.076 s.
double held_floe_wakes_at(bool held, bool* still_until_then) {
  RigidWorldDef d = sleepy(true);
  d.far_sleep.wake_hops = 0;
  d.far_sleep.loads_held = held;
  RigidWorld w(d);
  const BlockId f = w.add_block(floe(0.0));
  w.step(0.05);
  EXPECT_TRUE(w.asleep(f));
  const Vec3 x0 = w.position(f);
  const Quat q0 = w.orientation(f);
  *still_until_then = true;
  for (long k = 0; k < 4 * 240; ++k) {
    const double t = static_cast<double>(k) / 240.0;
    w.clear_external_forces();
    w.add_force(f, Vec3(500.0 + 400.0 * std::max(0.0, t - 1.0), 0, 0), w.position(f));
    w.substep();
    if (!w.asleep(f)) return 0.05 + t;
    *still_until_then = *still_until_then && same_pose(w, f, x0, q0);
  }
  return -1.0;
}

TEST(FarSleep, LoadsHeldKeepsASteadyCallerLoadAsleepAndWakesOnItsChange) {
  bool still = false;
  const double t_held = held_floe_wakes_at(true, &still);
  EXPECT_NEAR(t_held, 3.076, 2.0 / 240.0);  // s; measured 3.079 (one sub-step)
  EXPECT_TRUE(still);                        // bit-still while asleep
  bool still_off = false;
  const double t_off = held_floe_wakes_at(false, &still_off);
  EXPECT_NEAR(t_off, 0.05, 1.5 / 240.0);  // without loads_held the load wakes it at once
  std::printf("[ far sleep ] loads held: the loaded floe woke at %.3f s (3.076 s predicted); without: %.3f s\n",
              t_held, t_off);
}

// A block resting on a sleeping floe, both asleep from the start (never solved against each other),
// is woken by a wake box. The solve now hands its weight (546 kg x g x h = 22.3 N s per solve, 4x
// the floe's m speed = 5.5 N s) to the floe, which held it unsolved while both slept: not a change
// of what the floe holds (allow_neighbours), so the floe stays asleep and holds the block.
TEST(FarSleep, AWokenBlockBringsItsWeightWithoutWakingTheBlockBelow) {
  RigidWorldDef d = sleepy(true);
  d.far_sleep.wake_hops = 0;
  RigidWorld w(d);
  const BlockId f = w.add_block(floe(0.0));
  BlockDef top = floe(0.0);
  top.position.z() += 0.6;  // on the floe's top face, dry
  const BlockId b = w.add_block(top);
  w.step(0.05);
  ASSERT_TRUE(w.asleep(f) && w.asleep(b));
  const Vec3 xb = w.position(b);
  w.set_wake_boxes({{xb - Vec3::Constant(0.1), xb + Vec3::Constant(0.1)}});
  double top_speed = 0.0;
  for (int k = 0; k < 240; ++k) {
    w.substep();
    top_speed = std::max(top_speed, w.velocity(b).norm());
  }
  EXPECT_FALSE(w.asleep(b));
  EXPECT_TRUE(w.asleep(f));  // (woken in the first sub-step without allow_neighbours, checked)
  EXPECT_LT(top_speed, 3e-2);  // m/s; measured 3.1e-3 (its first sub-step: it starts exactly in contact)
  EXPECT_LT((w.position(b) - xb).norm(), 2e-4);  // m; measured 2.0e-5
  std::printf("[ far sleep ] woken block on a sleeping floe: floe %s, block's largest speed %.2e m/s, moved %.2e m\n",
              w.asleep(f) ? "asleep" : "awake", top_speed, (w.position(b) - xb).norm());
}

// zone_wakes_neighbours false: a block in a wake box keeps only itself awake; the floe it touches
// stays asleep (with the default it is woken wake_hops away).
TEST(FarSleep, ZoneKeepsOnlyItsOwnBlocksAwakeWhenAsked) {
  for (const bool wakes : {true, false}) {
    RigidWorldDef d = sleepy(true);
    d.far_sleep.zone_wakes_neighbours = wakes;
    RigidWorld w(d);
    const BlockId a = w.add_block(floe(0.0));
    const BlockId n = w.add_block(floe(1.0));
    w.step(0.05);
    w.set_wake_boxes({{w.position(a) - Vec3::Constant(0.1), w.position(a) + Vec3::Constant(0.1)}});
    w.step(0.1);
    EXPECT_FALSE(w.asleep(a));
    EXPECT_EQ(w.asleep(n), !wakes) << "zone_wakes_neighbours " << wakes;
  }
}

TEST(FarSleep, BadSettingsAreRefused) {
  RigidWorldDef d = sleepy(true);
  d.far_sleep.speed = 0.0;
  EXPECT_THROW(RigidWorld w(d), InputError);
  d = sleepy(true);
  d.allow_sleep = true;
  EXPECT_THROW(RigidWorld w(d), InputError);
}

}  // namespace
}  // namespace hs::rigid
