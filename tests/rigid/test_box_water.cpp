// box_water.h: exact submerged volume / centre of buoyancy against closed forms and
// Monte Carlo, and the drag traction against its definition.
#include "rigid/box_water.h"

#include <gtest/gtest.h>

#include <random>

namespace hs::rigid {
namespace {

constexpr double kTight = 1e-12;  // closed forms are exact up to round-off

TEST(RigidBoxWater, AxisAlignedHalfSubmerged) {
  const Vec3 half(1.0, 0.5, 0.3);
  const SubmergedBox s = submerged_box(half, Vec3(2.0, -1.0, 0.0), Quat::Identity(), 0.0);
  EXPECT_NEAR(s.volume, 4.0 * half.prod(), kTight);
  EXPECT_NEAR((s.centre_of_buoyancy - Vec3(2.0, -1.0, -0.15)).norm(), 0.0, kTight);
  EXPECT_NEAR(s.waterplane_area, 4.0 * half.x() * half.y(), kTight);
}

TEST(RigidBoxWater, AxisAlignedAnyDraft) {
  // Draft d = c - z0: V = 4ab d, c_B at the middle of the draft.
  const Vec3 half(1.0, 0.5, 0.3);
  for (double z0 : {-0.25, -0.1, 0.05, 0.2}) {
    const SubmergedBox s = submerged_box(half, Vec3(0, 0, z0), Quat::Identity(), 0.0);
    const double d = half.z() - z0;
    EXPECT_NEAR(s.volume, 4.0 * half.x() * half.y() * d, kTight) << z0;
    EXPECT_NEAR(s.centre_of_buoyancy.z(), -0.5 * d, kTight) << z0;
    EXPECT_NEAR(s.centre_of_buoyancy.head<2>().norm(), 0.0, kTight) << z0;
  }
}

TEST(RigidBoxWater, Tilted45AboutXThroughCentre) {
  // Square section 2b x 2b rotated 45 deg: a diamond; its lower half is a triangle with
  // apex sqrt(2) b below the centre, area 2 b^2, centroid sqrt(2) b / 3 below.
  const double a = 1.0, b = 0.4;
  const Vec3 x(0.3, 0.2, -0.7);
  const Quat q(Eigen::AngleAxisd(kPi / 4.0, Vec3::UnitX()));
  const SubmergedBox s = submerged_box(Vec3(a, b, b), x, q, x.z());
  EXPECT_NEAR(s.volume, 2.0 * a * 2.0 * b * b, kTight);
  EXPECT_NEAR((s.centre_of_buoyancy - (x - Vec3(0, 0, std::sqrt(2.0) * b / 3.0))).norm(), 0.0,
              kTight);
  EXPECT_NEAR(s.waterplane_area, 2.0 * a * 2.0 * std::sqrt(2.0) * b, kTight);
}

TEST(RigidBoxWater, FullySubmergedAndDry) {
  const Vec3 half(0.7, 0.4, 0.2);
  const Quat q(Eigen::AngleAxisd(0.6, Vec3(1, 2, 3).normalized()));
  const SubmergedBox wet = submerged_box(half, Vec3(1, 1, -2), q, 0.0);
  EXPECT_DOUBLE_EQ(wet.volume, 8.0 * half.prod());
  EXPECT_EQ(wet.centre_of_buoyancy, Vec3(1, 1, -2));
  EXPECT_EQ(wet.waterplane_area, 0.0);
  const SubmergedBox dry = submerged_box(half, Vec3(1, 1, 2), q, 0.0);
  EXPECT_EQ(dry.volume, 0.0);
  EXPECT_EQ(dry.waterplane_area, 0.0);
  // Touching the plane from either side.
  EXPECT_DOUBLE_EQ(submerged_box(half, Vec3(0, 0, -0.2), Quat::Identity(), 0.0).volume,
                   8.0 * half.prod());
  EXPECT_EQ(submerged_box(half, Vec3(0, 0, 0.2), Quat::Identity(), 0.0).volume, 0.0);
}

TEST(RigidBoxWater, RandomPosesMatchMonteCarlo) {
  // 1e6 samples, submerged fraction in [0.1, 0.9]: 3 sigma < 0.9 % relative.
  std::mt19937_64 rng(20240607);
  std::uniform_real_distribution<double> u01(0.0, 1.0), um1(-1.0, 1.0);
  int checked = 0;
  for (int trial = 0; trial < 40 && checked < 12; ++trial) {
    const Vec3 half(0.1 + 0.9 * u01(rng), 0.1 + 0.9 * u01(rng), 0.1 + 0.9 * u01(rng));
    const Quat q = Quat::UnitRandom();
    const Vec3 x(um1(rng), um1(rng), 0.8 * um1(rng));
    const SubmergedBox s = submerged_box(half, x, q, 0.0);
    const double vbox = 8.0 * half.prod();
    if (s.volume < 0.1 * vbox || s.volume > 0.9 * vbox) continue;
    const Mat3 R = q.toRotationMatrix();
    const int n = 1000000;
    long in = 0;
    Vec3 sum = Vec3::Zero();
    for (int i = 0; i < n; ++i) {
      const Vec3 p = x + R * Vec3(half.x() * um1(rng), half.y() * um1(rng), half.z() * um1(rng));
      if (p.z() <= 0.0) {
        ++in;
        sum += p;
      }
    }
    const double vmc = vbox * static_cast<double>(in) / n;
    const Vec3 cmc = sum / static_cast<double>(in);
    EXPECT_NEAR(s.volume / vmc, 1.0, 1e-2) << "trial " << trial;
    EXPECT_LT((s.centre_of_buoyancy - cmc).norm(), 1e-2 * half.norm()) << "trial " << trial;
    ++checked;
  }
  EXPECT_GE(checked, 8);
}

TEST(RigidBoxWater, ProjectedAreaOfSubmergedBox) {
  const Vec3 half(1.0, 0.5, 0.3);
  const SubmergedBox s = submerged_box(half, Vec3(0, 0, -1), Quat::Identity(), 0.0);
  EXPECT_NEAR(s.projected_area(Vec3::UnitX()), 4.0 * half.y() * half.z(), kTight);
  EXPECT_NEAR(s.projected_area(Vec3::UnitZ()), 4.0 * half.x() * half.y(), kTight);
  const SubmergedBox h = submerged_box(half, Vec3(0, 0, 0), Quat::Identity(), 0.0);
  EXPECT_NEAR(h.projected_area(Vec3::UnitY()), 2.0 * half.x() * half.z(), kTight);
}

TEST(RigidBoxWater, DragMatchesDefinition) {
  const Vec3 half(1.0, 0.5, 0.3);
  BoxWaterParams p;
  p.density = 1000.0;
  p.drag_coefficient = 1.2;
  // Fully submerged box translating along x: quadratic drag 1/2 rho C_d A |v| v on the
  // leading face only, no torque beyond buoyancy (none: c_B = centre).
  const Vec3 v(2.0, 0.0, 0.0);
  WaterLoad l = box_water_load(p, 9.81, half, Vec3(0, 0, -2), Quat::Identity(), v, Vec3::Zero());
  const double a_x = 4.0 * half.y() * half.z();
  EXPECT_NEAR(l.force.x(), -0.5 * 1000.0 * 1.2 * a_x * 4.0, 1e-9);
  EXPECT_NEAR(l.force.z(), 1000.0 * 9.81 * 8.0 * half.prod(), 1e-9);
  EXPECT_NEAR(l.torque.norm(), 0.0, 1e-9);
  // Half-submerged box heaving: linear drag is the dashpot c_lin A_bottom (5a).
  p.drag_coefficient = 0.0;
  p.linear_drag = 800.0;
  const Vec3 vz(0.0, 0.0, 0.3);
  l = box_water_load(p, 9.81, half, Vec3(0, 0, 0), Quat::Identity(), vz, Vec3::Zero());
  const double buoy = 1000.0 * 9.81 * 4.0 * half.prod();
  EXPECT_NEAR(l.force.z() - buoy, -800.0 * 4.0 * half.x() * half.y() * 0.3, 1e-9);
  // Rolling about x through a fully submerged box: the torque is the exact integral
  // -c sum_f int (r x n)(r x n)^T dA w; for the +-z faces (area 4ab, |y| <= b) it is
  // -c 2 * 4ab * b^2/3 w, for the +-y faces (|z| <= c) -c 2 * 4ac * c^2/3 w.
  const Vec3 w(0.5, 0.0, 0.0);
  l = box_water_load(p, 9.81, half, Vec3(0, 0, -2), Quat::Identity(), Vec3::Zero(), w);
  const double a = half.x(), b = half.y(), c = half.z();
  const double k = 2.0 * 4.0 * a * b * b * b / 3.0 + 2.0 * 4.0 * a * c * c * c / 3.0;
  EXPECT_NEAR(l.torque.x(), -800.0 * k * 0.5, 1e-9);
  EXPECT_NEAR(l.force.head<2>().norm(), 0.0, 1e-9);
}

}  // namespace
}  // namespace hs::rigid
