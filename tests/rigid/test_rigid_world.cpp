// RigidWorld in water: freeboard, undamped heave period, self-righting; handles;
// friction changed at run time.
#include "common/ice_formulas.h"
#include "rigid/rigid_world.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <vector>

namespace hs::rigid {
namespace {

constexpr double kRhoI = 910.0, kRhoW = 1025.0, kG = 9.81;

// Equilibrium centre height of a flat slab of thickness h (draft h rho_i/rho_w).
double z_equilibrium(double h) { return 0.5 * h - flotation_draft(h, kRhoI, kRhoW); }

TEST(RigidWorld, SlabFloatsAtFreeboard) {
  // 2 x 2 x 0.6 m, released with its centre at the water line (off equilibrium).
  RigidWorldDef def;
  RigidWorld w(def);
  BlockDef b;
  b.half_extents = Vec3(1.0, 1.0, 0.3);
  b.density = kRhoI;
  const BlockId id = w.add_block(b);
  w.step(15.0);
  const double freeboard = w.position(id).z() + 0.3;
  const double expected = flotation_freeboard(0.6, kRhoI, kRhoW);
  EXPECT_NEAR(freeboard / expected, 1.0, 0.01) << "freeboard " << freeboard;
  EXPECT_LT(w.velocity(id).norm(), 1e-4);
  std::printf("[ rigid ] freeboard %.6f m, expected %.6f m, rel error %.2e\n", freeboard,
              expected, freeboard / expected - 1.0);
}

TEST(RigidWorld, UndampedHeavePeriod) {
  // Drag off. Theory without added mass: T = 2 pi sqrt(rho_i h / (rho_w g)) (the
  // entrained water would lengthen it; it is not modelled). Amplitude 5 cm keeps the
  // slab wall-sided in the water (freeboard 6.7 cm), so the spring is linear.
  const double h = 0.6;
  RigidWorldDef def;
  def.linear_drag = 0.0;
  def.quadratic_drag_cd = 0.0;
  RigidWorld w(def);
  BlockDef b;
  b.half_extents = Vec3(1.0, 1.0, 0.5 * h);
  b.density = kRhoI;
  const double zeq = z_equilibrium(h);
  b.position = Vec3(0, 0, zeq + 0.05);
  const BlockId id = w.add_block(b);
  std::vector<double> crossings;
  double prev = 0.05, amax_late = 0.0;
  const double t_end = 8.0;
  while (w.time() < t_end) {
    w.substep();
    const double cur = w.position(id).z() - zeq;
    if (prev < 0.0 && cur >= 0.0)  // upward zero crossing, linear interpolation
      crossings.push_back(w.time() - def.dt * cur / (cur - prev));
    if (w.time() > t_end - 2.0) amax_late = std::max(amax_late, std::abs(cur));
    prev = cur;
  }
  ASSERT_GE(crossings.size(), 4u);
  const double period = (crossings.back() - crossings.front()) / (crossings.size() - 1);
  const double theory = 2.0 * kPi * std::sqrt(kRhoI * h / (kRhoW * kG));
  EXPECT_NEAR(period / theory, 1.0, 0.05);
  // Symplectic integration: no numerical damping or growth of the amplitude.
  EXPECT_NEAR(amax_late / 0.05, 1.0, 0.02);
  std::printf("[ rigid ] heave period %.5f s, theory %.5f s, rel error %.2e\n", period, theory,
              period / theory - 1.0);
}

TEST(RigidWorld, TiltedSlabRightsItself) {
  // A wide flat slab (3 x 3 x 0.5 m) released at 30 deg roll ends flat (drag on).
  RigidWorld w{RigidWorldDef{}};
  BlockDef b;
  b.half_extents = Vec3(1.5, 1.5, 0.25);
  b.density = kRhoI;
  b.position = Vec3(0, 0, z_equilibrium(0.5));
  b.orientation = Quat(Eigen::AngleAxisd(30.0 * kPi / 180.0, Vec3::UnitX()));
  const BlockId id = w.add_block(b);
  w.step(12.0);
  const Vec3 up = w.orientation(id) * Vec3::UnitZ();
  const double tilt_deg = std::acos(std::min(1.0, std::abs(up.z()))) * 180.0 / kPi;
  EXPECT_LT(tilt_deg, 2.0);
  EXPECT_LT(w.angular_velocity(id).norm(), 1e-2);
  std::printf("[ rigid ] final tilt %.4f deg\n", tilt_deg);
}

TEST(RigidWorld, BlockIdsAreGenerational) {
  RigidWorld w{RigidWorldDef{}};
  const BlockId a = w.add_block(BlockDef{});
  const BlockId b = w.add_block(BlockDef{});
  EXPECT_EQ(w.block_count(), 2u);
  w.remove_block(a);
  EXPECT_FALSE(w.alive(a));
  EXPECT_TRUE(w.alive(b));
  EXPECT_THROW(w.position(a), std::out_of_range);
  const BlockId c = w.add_block(BlockDef{});
  EXPECT_EQ(c.index, a.index);  // slot reused
  EXPECT_NE(c.generation, a.generation);
  EXPECT_FALSE(w.alive(a));
  EXPECT_EQ(w.blocks().size(), 2u);
}

TEST(RigidWorld, ImpulseChangesMomentum) {
  // Out of water, no gravity: an impulse J at the centre gives dv = J/m exactly.
  RigidWorldDef def;
  def.water = false;
  def.gravity = Vec3::Zero();
  RigidWorld w(def);
  BlockDef b;
  b.half_extents = Vec3(0.5, 0.4, 0.2);
  const BlockId id = w.add_block(b);
  const double m = w.mass(id);
  EXPECT_NEAR(m, kRhoI * 1.0 * 0.8 * 0.4, 1e-9);  // rho * 8 * prod(half)
  w.add_impulse(id, Vec3(100.0, 0, 0), w.position(id));
  w.substep();
  EXPECT_NEAR(w.velocity(id).x(), 100.0 / m, 1e-12);
  EXPECT_NEAR(w.kinetic_energy(), 0.5 * m * std::pow(100.0 / m, 2), 1e-9);
}

// Sliding distance of a block launched at v0 on a fixed floor, out of water:
// Coulomb friction decelerates it at mu g, so it stops after v0^2 / (2 mu g).
double slide_distance(double mu_def, double mu_set) {
  RigidWorldDef def;
  def.water = false;
  def.dt = 1.0 / 120.0;
  def.friction = mu_def;
  RigidWorld w(def);
  BlockDef floor;
  floor.half_extents = Vec3(20.0, 2.0, 0.5);
  floor.position = Vec3(0, 0, -0.5);
  floor.fixed = true;
  const BlockId f = w.add_block(floor);
  BlockDef b;
  b.half_extents = Vec3(0.5, 0.5, 0.1);
  b.position = Vec3(-10.0, 0, 0.1);
  const BlockId id = w.add_block(b);
  w.step(0.5);  // come to rest on the floor
  if (mu_set >= 0.0) {
    w.set_friction(f, mu_set);
    w.set_friction(id, mu_set);
  }
  const double x0 = w.position(id).x();
  w.set_velocity(id, Vec3(2.0, 0, 0), Vec3::Zero());
  w.step(3.0);
  EXPECT_LT(w.velocity(id).norm(), 1e-3);
  return w.position(id).x() - x0;
}

TEST(RigidWorld, SetFrictionChangesSliding) {
  const double v0 = 2.0;
  const double d05 = slide_distance(0.5, -1.0), d02 = slide_distance(0.5, 0.2);
  std::printf("[ rigid ] slide %.4f m (mu 0.5, theory %.4f), %.4f m (set to 0.2, theory %.4f)\n", d05,
              v0 * v0 / (2 * 0.5 * kG), d02, v0 * v0 / (2 * 0.2 * kG));
  EXPECT_NEAR(d05 / (v0 * v0 / (2 * 0.5 * kG)), 1.0, 0.05);
  EXPECT_NEAR(d02 / (v0 * v0 / (2 * 0.2 * kG)), 1.0, 0.05);
}

// Block resting on a fixed 20 deg incline (tan 20 = 0.36 < mu 0.5: it must stay put), out
// of water; returns how far it moved along the slope over 10 s after 1 s of settling.
double incline_creep(bool fixed_directions) {
  RigidWorldDef def;
  def.water = false;
  def.dt = 1.0 / 30.0;  // the ridge's step
  def.friction = 0.5;
  def.fixed_friction_directions = fixed_directions;
  RigidWorld w(def);
  const Quat q(Eigen::AngleAxisd(20.0 * 3.14159265358979323846 / 180.0, Vec3::UnitY()));
  const Vec3 n = q * Vec3::UnitZ();
  BlockDef slope;
  slope.half_extents = Vec3(10.0, 2.0, 0.5);
  slope.orientation = q;
  slope.fixed = true;
  w.add_block(slope);
  BlockDef b;
  b.half_extents = Vec3(0.8, 0.6, 0.3);
  b.orientation = q;
  b.position = (0.5 + 0.3) * n;
  const BlockId id = w.add_block(b);
  w.step(1.0);
  const Vec3 x0 = w.position(id);
  w.step(10.0);
  return (w.position(id) - x0).norm();
}

TEST(RigidWorld, FixedFrictionDirectionsHoldOnIncline) {
  const double creep_default = incline_creep(false), creep_fixed = incline_creep(true);
  std::printf("[ rigid ] creep on a 20 deg incline (mu 0.5) over 10 s: %.3e m (one velocity-"
              "dependent friction direction), %.3e m (two fixed directions)\n",
              creep_default, creep_fixed);
  EXPECT_LT(creep_fixed, 1e-3);
}

// Sliding with two fixed friction directions: each is clamped to mu N on its own, so the
// friction force is mu N along a basis direction and up to sqrt(2) mu N diagonally.
TEST(RigidWorld, FixedFrictionDirectionsSlide) {
  for (const double angle : {0.0, 45.0}) {
    RigidWorldDef def;
    def.water = false;
    def.dt = 1.0 / 120.0;
    def.friction = 0.5;
    def.fixed_friction_directions = true;
    RigidWorld w(def);
    BlockDef floor;
    floor.half_extents = Vec3(20.0, 20.0, 0.5);
    floor.position = Vec3(0, 0, -0.5);
    floor.fixed = true;
    w.add_block(floor);
    BlockDef b;
    b.half_extents = Vec3(0.5, 0.5, 0.1);
    b.position = Vec3(0, 0, 0.1);
    const BlockId id = w.add_block(b);
    w.step(0.5);
    const Vec3 x0 = w.position(id);
    const double a = angle * 3.14159265358979323846 / 180.0;
    w.set_velocity(id, 2.0 * Vec3(std::cos(a), std::sin(a), 0.0), Vec3::Zero());
    w.step(3.0);
    EXPECT_LT(w.velocity(id).norm(), 1e-3);
    const double d = (w.position(id) - x0).norm(), d_mu = 2.0 * 2.0 / (2 * 0.5 * kG);
    std::printf("[ rigid ] fixed friction directions: slide at %.0f deg %.4f m, mu 0.5 gives %.4f m "
                "(effective mu %.3f)\n", angle, d, d_mu, 0.5 * d_mu / d);
    EXPECT_GT(d, d_mu / std::sqrt(2.0) * 0.95);
    EXPECT_LT(d, d_mu * 1.05);
  }
}

}  // namespace
}  // namespace hs::rigid
