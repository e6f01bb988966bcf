// Freeze joints break at strength x area, in tension and in shear.
#include "common/state_archive.h"
#include "rigid/rigid_world.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <utility>
#include <vector>

namespace hs::rigid {
namespace {

struct BreakResult {
  double force_at_break = 0.0;  // applied force (N) in the step the joint broke
  JointLoad load_at_break;
  bool broke = false;
};

const Vec3 anchor(0.5025, 0, 0);

// Block a (fixed) and block b (dynamic, 910 kg), 1 m cubes side by side along x with a 5 mm gap
// (so that no contact shares the load), joined at the gap centre (`anchor`) over `area`.
// Returns b and the joint.
std::pair<BlockId, JointId> add_joined_pair(RigidWorld& w, double area) {
  BlockDef a;
  a.half_extents = Vec3(0.5, 0.5, 0.5);
  a.fixed = true;
  BlockDef b = a;
  b.fixed = false;
  b.density = 910.0;
  b.position = Vec3(1.005, 0, 0);
  const BlockId ia = w.add_block(a), ib = w.add_block(b);
  return {ib, w.add_freeze_joint({ia, ib, anchor, Vec3::UnitX(), area})};
}

// The pair of add_joined_pair; b is pulled by a force ramping at `rate` N/s along `dir`, applied at the anchor when
// `at_anchor` (no moment on the joint), else at b's centre.
BreakResult pull_until_break(const RigidWorldDef& def, const Vec3& dir, bool at_anchor,
                             double rate) {
  RigidWorld w(def);
  const auto [ib, j] = add_joined_pair(w, 1.0);
  BreakResult r;
  while (w.time() < 10.0) {
    const double f = rate * (w.time() + def.dt);
    w.clear_external_forces();
    w.add_force(ib, f * dir, at_anchor ? anchor : w.position(ib));
    w.substep();
    if (w.joint_broken(j)) {
      r.broke = true;
      r.force_at_break = f;
      r.load_at_break = w.joint_load(j);
      break;
    }
  }
  EXPECT_EQ(w.broken_joint_count(), r.broke ? 1u : 0u);
  EXPECT_EQ(w.joint_count(), r.broke ? 0u : 1u);
  return r;
}

RigidWorldDef dry_world() {
  RigidWorldDef def;
  def.water = false;
  def.gravity = Vec3::Zero();
  def.freeze_bond_strength = 50e3;
  def.freeze_bond_shear_strength = 30e3;
  return def;
}

TEST(RigidFreezeJoint, BreaksInTensionAtStrength) {
  const RigidWorldDef def = dry_world();
  const BreakResult r = pull_until_break(def, Vec3::UnitX(), false, 20e3);  // 2.5 s ramp
  ASSERT_TRUE(r.broke);
  const double ratio = r.force_at_break / (def.freeze_bond_strength * 1.0);
  // The ramp is checked once per step: the joint breaks in the first step whose load reaches
  // the strength, so 1 <= ratio < 1 + one step of the ramp (20e3 N/s x dt = 83 N = 1.7e-3).
  // Measured: exactly 1 (50 kN is a whole number of ramp steps).
  EXPECT_GE(ratio, 1.0 - 1e-12);
  EXPECT_LE(ratio, 1.0 + 20e3 * def.dt / def.freeze_bond_strength);
  EXPECT_LT(r.load_at_break.shear, 1e-9 * r.load_at_break.tension);  // measured 0
  std::printf("[ rigid ] tension break: F = %.1f N, strength x area = %.1f N, ratio %.7f\n",
              r.force_at_break, def.freeze_bond_strength, ratio);
}

TEST(RigidFreezeJoint, BreaksInShearAtShearStrength) {
  const RigidWorldDef def = dry_world();
  const BreakResult r = pull_until_break(def, Vec3::UnitY(), true, 12e3);
  ASSERT_TRUE(r.broke);
  const double ratio = r.force_at_break / (def.freeze_bond_shear_strength * 1.0);
  // As in tension: 1 <= ratio < 1 + one ramp step (12e3 N/s x dt = 50 N); measured exactly 1.
  EXPECT_GE(ratio, 1.0 - 1e-12);
  EXPECT_LE(ratio, 1.0 + 12e3 * def.dt / def.freeze_bond_shear_strength);
  EXPECT_LT(std::abs(r.load_at_break.tension), 1e-9 * r.load_at_break.shear);  // measured 2.9e-14
  std::printf("[ rigid ] shear break: F = %.1f N, shear strength x area = %.1f N, ratio %.7f\n",
              r.force_at_break, def.freeze_bond_shear_strength, ratio);
}

TEST(RigidFreezeJoint, HoldsBelowStrengthAndUnderCompression) {
  // Held at 80 % of the strength for 2 s: the joint must not break.
  RigidWorldDef def = dry_world();
  RigidWorld w(def);
  BlockDef a;
  a.half_extents = Vec3(0.5, 0.5, 0.5);
  a.fixed = true;
  BlockDef b = a;
  b.fixed = false;
  b.position = Vec3(1.0, 0, 0);  // touching
  const BlockId ia = w.add_block(a), ib = w.add_block(b);
  const JointId j = w.add_freeze_joint({ia, ib, Vec3(0.5, 0, 0), Vec3::UnitX(), 1.0});
  w.add_force(ib, Vec3(0.8 * def.freeze_bond_strength, 0, 0), w.position(ib));
  w.step(2.0);
  EXPECT_FALSE(w.joint_broken(j));
  EXPECT_NEAR(w.joint_load(j).tension / (0.8 * def.freeze_bond_strength), 1.0, 1e-9);  // measured 0
  // Compression (5x the strength) never breaks a joint; contact keeps the blocks apart.
  w.clear_external_forces();
  w.add_force(ib, Vec3(-5.0 * def.freeze_bond_strength, 0, 0), w.position(ib));
  w.step(1.0);
  EXPECT_FALSE(w.joint_broken(j));
  EXPECT_LT(w.position(ib).x(), 1.0 + 1e-3);
  EXPECT_GT(w.position(ib).x(), 1.0 - 2e-2);
}

// Spring joints (RigidWorldDef::joint_stiffness): s = 1e7 Pa/m, a step of 1 ms so that no
// spring is softened by Bullet's limit (omega dt <= 0.25; here <= 0.11).
RigidWorldDef spring_world() {
  RigidWorldDef def = dry_world();
  def.dt = 1e-3;
  def.joint_stiffness = 1e7;
  return def;
}

TEST(RigidFreezeJoint, SpringJointBreaksAtStrengthInTensionAndShear) {
  const RigidWorldDef def = spring_world();
  const BreakResult t = pull_until_break(def, Vec3::UnitX(), false, 20e3);
  const BreakResult s = pull_until_break(def, Vec3::UnitY(), true, 12e3);
  ASSERT_TRUE(t.broke);
  ASSERT_TRUE(s.broke);
  const double rt = t.force_at_break / def.freeze_bond_strength, rs = s.force_at_break / def.freeze_bond_shear_strength;
  std::printf("[ rigid ] spring joint: tension break at %.1f N (ratio %.7f), shear break at %.1f N (ratio %.7f)\n",
              t.force_at_break, rt, s.force_at_break, rs);
  // A spring joint's load is its stretch from the step before: it breaks one ramp step late
  // (measured 1.0004 in both = 20e3 N/s x 1 ms / 50 kN and 12e3 N/s x 1 ms / 30 kN). Allowed:
  // up to two steps late.
  EXPECT_GE(rt, 1.0 - 1e-12);
  EXPECT_LE(rt, 1.0 + 2.0 * 20e3 * def.dt / def.freeze_bond_strength + 1e-12);
  EXPECT_GE(rs, 1.0 - 1e-12);
  EXPECT_LE(rs, 1.0 + 2.0 * 12e3 * def.dt / def.freeze_bond_shear_strength + 1e-12);
}

TEST(RigidFreezeJoint, SpringJointHasTheStatedStiffnesses) {
  // Block b joined to fixed block a over 1 m^2 (1 m cubes, 5 mm gap); a static load held 2 s
  // (damping ratio 0.5: many periods) deflects the joint by load / stiffness: stretch and shear
  // F / (s A), bending and twisting M / (s I) and M / (2 s I), I = A^2 / (4 pi). The pair lies
  // along x, then turned by an oblique rotation Q (blocks, anchor, normal and loads alike): the
  // joint's frame must follow its normal.
  const RigidWorldDef def = spring_world();
  const double A = 1.0, I = A * A / (4.0 * 3.14159265358979323846), F = 10e3, z0 = 0.4;
  const Quat turns[2] = {Quat::Identity(), Quat(Eigen::AngleAxisd(1.1, Vec3(0.3, -0.5, 0.8).normalized()))};
  for (const Quat& Q : turns)
    for (int mode = 0; mode < 4; ++mode) {
      RigidWorld w(def);
      BlockDef a;
      a.half_extents = Vec3(0.5, 0.5, 0.5);
      a.orientation = Q;
      a.fixed = true;
      BlockDef b = a;
      b.fixed = false;
      b.density = 910.0;
      b.position = Q * Vec3(1.005, 0, 0);
      const BlockId ia = w.add_block(a), ib = w.add_block(b);
      const JointId j = w.add_freeze_joint({ia, ib, Q * anchor, Q * Vec3::UnitX(), A});
      const Vec3 c = w.position(ib), ex = Q * Vec3::UnitX(), ey = Q * Vec3::UnitY(), ez = Q * Vec3::UnitZ();
      if (mode == 0) w.add_force(ib, F * ex, c);         // stretch
      if (mode == 1) w.add_force(ib, F * ey, Q * anchor);  // shear, no moment
      if (mode == 2) {                                     // bending couple about the frame's y
        w.add_force(ib, F * ex, c - z0 * ez);
        w.add_force(ib, -F * ex, c + z0 * ez);
      }
      if (mode == 3) {  // twisting couple about the normal
        w.add_force(ib, F * ey, c - z0 * ez);
        w.add_force(ib, -F * ey, c + z0 * ez);
      }
      w.step(2.0);
      ASSERT_FALSE(w.joint_broken(j));
      const Vec3 d = Q.conjugate() * (w.position(ib) - c);
      const Quat turn = w.orientation(ib) * Q.conjugate();  // b's rotation since the start
      const double angle = 2.0 * std::asin(std::min(1.0, turn.vec().norm()));
      const double M = 2.0 * F * z0;
      const char* names[4] = {"stretch", "shear", "bending", "twist"};
      const double got[4] = {d.x(), d.y(), angle, angle};
      const double want[4] = {F / (def.joint_stiffness * A), F / (def.joint_stiffness * A),
                              M / (def.joint_stiffness * I), M / (2.0 * def.joint_stiffness * I)};
      std::printf("[ rigid ] spring joint %s (%s frame): %.4e (expected %.4e), ratio %.6f (%+.1e); speed %.1e m/s\n",
                  names[mode], Q.isApprox(Quat::Identity()) ? "world" : "oblique", got[mode], want[mode],
                  got[mode] / want[mode], got[mode] / want[mode] - 1.0, w.velocity(ib).norm());
      // Measured (both frames): stretch +3.3e-13 / +3.8e-13, shear +1.3e-15 / +5.1e-13, twist -2.4e-15 /
      // +7.3e-14 -> limit 5e-12 (10x). Bending -4.0e-3 in both frames (0.995985 / 0.995986): a
      // deterministic offset of Bullet's 6-DoF spring bending rows, not noise (the small-angle
      // error at 0.01 rad is ~1e-5; not tracked down), so there is nothing to multiply by 10: the
      // limit 0.01 keeps the offset inside and fails a 1 % change in the bending stiffness.
      EXPECT_NEAR(got[mode] / want[mode], 1.0, mode == 2 ? 0.01 : 5e-12);
      EXPECT_LT(w.velocity(ib).norm(), 1e-4) << "damped to rest";
    }
}

TEST(RigidFreezeJoint, RemovedWithItsBlock) {
  RigidWorld w(dry_world());
  const BlockId a = w.add_block(BlockDef{});
  BlockDef bd;
  bd.position = Vec3(1, 0, 0);
  const BlockId b = w.add_block(bd);
  const JointId j = w.add_freeze_joint({a, b, Vec3(0.5, 0, 0), Vec3::UnitX(), 1.0});
  EXPECT_EQ(w.joint_count(), 1u);
  w.remove_block(b);
  EXPECT_EQ(w.joint_count(), 0u);
  EXPECT_THROW(w.joint_broken(j), std::out_of_range);
  w.step(0.1);
}

}  // namespace
}  // namespace hs::rigid

namespace hs::rigid {
namespace {

// The world solves joints in slot (creation) order (docs/rigid.md, "Solve order"); the order is
// kept up to date one slot at a time as joints are made, broken, removed and their slots reused.
// A world restored from a checkpoint rebuilds the order from scratch: both must solve alike, to
// the last bit. Six 1 m cubes in a ring of joints on a fixed slab (over-constrained, so the
// order of the rows changes the bits), two joints removed and two made again in their slots, a
// kick that breaks the one weak joint; the checkpoint's world must then continue bit-identically.
TEST(RigidFreezeJoint, JointOrderKeptSlotBySlotEqualsTheRebuiltOne) {
  RigidWorldDef def;
  def.dt = 1.0 / 240.0;
  def.freeze_bond_strength = 1e6;  // 500 kN on a 0.5 m^2 joint: only the weak one breaks
  auto build = [](RigidWorld& w) {
    BlockDef slab;
    slab.half_extents = Vec3(4.0, 4.0, 0.5);
    slab.position = Vec3(0, 0, -0.5);
    slab.fixed = true;
    w.add_block(slab);
    std::vector<BlockId> ids;
    for (int i = 0; i < 6; ++i) {
      BlockDef b;
      b.half_extents = Vec3(0.5, 0.5, 0.5);
      b.density = 910.0;
      const double a = 2.0 * M_PI * i / 6.0;
      b.position = Vec3(1.2 * std::cos(a), 1.2 * std::sin(a), 0.52 + 0.01 * i);  // 0.2 m apart
      ids.push_back(w.add_block(b));
    }
    std::vector<JointId> js;
    for (int i = 0; i < 6; ++i) {
      const Vec3 mid = 0.5 * (w.position(ids[i]) + w.position(ids[(i + 1) % 6]));
      js.push_back(w.add_freeze_joint({ids[i], ids[(i + 1) % 6], mid, Vec3::UnitX(), i == 2 ? 1e-4 : 0.5}));
    }
    w.remove_joint(js[1]);
    w.remove_joint(js[4]);
    for (int i : {4, 1}) {  // the freed slots are reused, last freed first
      const Vec3 mid = 0.5 * (w.position(ids[i]) + w.position(ids[(i + 1) % 6]));
      w.add_freeze_joint({ids[i], ids[(i + 1) % 6], mid, Vec3::UnitY(), 0.5});
    }
    const Vec3 y = Vec3::UnitY();  // a kick off centre: every joint loaded, none symmetric
    w.add_impulse(ids[0], 300.0 * y, w.position(ids[0]) + Vec3(0.3, 0, 0.2));
    return ids;
  };
  RigidWorld a(def);
  const auto ids = build(a);
  for (int k = 0; k < 60; ++k) a.substep();
  StateArchive ar;
  a.save_state(ar, "w/");
  RigidWorld b(def);
  build(b);
  ASSERT_EQ(b.load_state(ar, "w/"), 0u);
  for (int k = 0; k < 240; ++k) {
    a.substep();
    b.substep();
  }
  for (const BlockId id : ids) {
    EXPECT_EQ(a.position(id), b.position(id)) << "block " << id.index;
    EXPECT_EQ(a.orientation(id).coeffs(), b.orientation(id).coeffs()) << "block " << id.index;
  }
  EXPECT_EQ(a.broken_joint_count(), 1u);  // the weak one
  EXPECT_EQ(a.joint_count(), 5u);
  std::printf("[ joint order ] after 300 sub-steps: %zu joints intact, %zu broken; block 1 at (%.4f, %.4f, %.4f) m\n",
              a.joint_count(), a.broken_joint_count(), a.position(ids[1]).x(), a.position(ids[1]).y(),
              a.position(ids[1]).z());
}

}  // namespace
}  // namespace hs::rigid
