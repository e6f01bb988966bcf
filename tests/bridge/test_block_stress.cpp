// Block stress estimates and the conversion region (docs/bridge.md): beam bending against closed
// forms (three- and four-point bending, a free block under one end force), invariance under
// rotation and mirroring, freeze-bond utilisation, the conversion rule and the region.
#include "bridge/block_stress.h"
#include "bridge/conversion_criteria.h"
#include "bridge/criterion_freeze_bond.h"
#include "common/error.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

using namespace hs;
using namespace hs::bridge;

namespace {

constexpr double kSigmaF = 0.5e6;  // Pa

// A 4 m x 1 m x 0.5 m block (length L along local x, width w along y, depth h along z).
BlockBox slab() {
  BlockBox b;
  b.half_extents = Vec3(2.0, 0.5, 0.25);
  b.centre = Vec3(10.0, -3.0, -0.2);
  return b;
}

// A load given in the block's frame, returned in the world frame.
PointLoad local_load(const BlockBox& b, const Vec3& p, const Vec3& f) {
  const Quat q = b.orientation.normalized();
  return {b.centre + q * p, q * f};
}

std::vector<PointLoad> random_loads(const BlockBox& b, int n, unsigned seed) {
  std::mt19937 gen(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<PointLoad> out;
  for (int k = 0; k < n; ++k) {
    Vec3 p(u(gen), u(gen), u(gen));
    p = p.cwiseProduct(b.half_extents);
    out.push_back(local_load(b, p, 1e4 * Vec3(u(gen), u(gen), u(gen))));
  }
  return out;
}

double rel(double x, double ref) { return std::abs(x - ref) / std::abs(ref); }

}  // namespace

// ---- flexure ----

// Three-point bending as a self-equilibrated load set: F/2 down at each end (bottom face), F up at
// mid-span (top face). M_max = F L / 4 at mid-span, sigma = 6 M / (w h^2) = 3 F L / (2 w h^2).
TEST(BlockStress, ThreePointBendingMatchesBeamTheory) {
  const BlockBox b = slab();
  const double F = 2e4, L = 4.0, w = 1.0, h = 0.5;
  const std::vector<PointLoad> loads{local_load(b, Vec3(-2.0, 0.0, -0.25), Vec3(0, 0, -F / 2)),
                                     local_load(b, Vec3(2.0, 0.0, -0.25), Vec3(0, 0, -F / 2)),
                                     local_load(b, Vec3(0.0, 0.0, 0.25), Vec3(0, 0, F))};
  const FlexureEstimate e = flexure_estimate(b, loads, kSigmaF);
  const double expect = 3.0 * F * L / (2.0 * w * h * h);
  std::printf("three-point: sigma %.12g Pa, 3FL/(2wh^2) %.12g Pa, rel. diff %.2e, at axis %d s = %.3g m, u_b %.6f\n",
              e.stress, expect, rel(e.stress, expect), e.axis, e.position, e.utilisation);
  EXPECT_LT(rel(e.stress, expect), 1e-12);
  EXPECT_EQ(e.axis, 0);
  EXPECT_NEAR(e.position, 0.0, 1e-12);
  // Moment about y of what lies beyond mid-span: F/2 down at arm a = L/2 -> +F L/4.
  EXPECT_NEAR(e.moment_local.y(), F * L / 4.0, 1e-12 * F * L);
  EXPECT_DOUBLE_EQ(e.utilisation, e.stress / kSigmaF);
  EXPECT_LT((e.section_centre - b.centre).norm(), 1e-12);
}

// Four-point bending: F up at both ends, F down at distance e in from each end. Between the inner
// loads M = F e is uniform: sigma = 6 F e / (w h^2).
TEST(BlockStress, FourPointBendingHasAUniformMomentBetweenTheInnerLoads) {
  const BlockBox b = slab();
  const double F = 1e4, e_in = 0.7, w = 1.0, h = 0.5, a = 2.0;
  const std::vector<PointLoad> loads{local_load(b, Vec3(-a, 0.0, -0.25), Vec3(0, 0, F)),
                                     local_load(b, Vec3(a, 0.0, -0.25), Vec3(0, 0, F)),
                                     local_load(b, Vec3(-(a - e_in), 0.0, 0.25), Vec3(0, 0, -F)),
                                     local_load(b, Vec3(a - e_in, 0.0, 0.25), Vec3(0, 0, -F))};
  const double expect = 6.0 * F * e_in / (w * h * h);
  const FlexureEstimate est = flexure_estimate(b, loads, kSigmaF);
  double lo = INFINITY, hi = 0;
  for (int n = 0; n <= 20; ++n) {
    const double s = -(a - e_in) + 2.0 * (a - e_in) * n / 20.0;
    const BeamSection q = beam_section(b, loads, 0, s);
    lo = std::min(lo, q.stress);
    hi = std::max(hi, q.stress);
    EXPECT_LT(rel(q.stress, expect), 1e-12) << "s = " << s;
    EXPECT_NEAR(q.moment_local.y(), -F * e_in, 1e-12 * F * e_in);  // the couple of the outer pair
  }
  std::printf("four-point: 6Fe/(wh^2) %.12g Pa; over the inner span sigma in [%.12g, %.12g] Pa; estimate %.12g Pa\n",
              expect, lo, hi, est.stress);
  EXPECT_LT(rel(est.stress, expect), 1e-12);
  EXPECT_LE(std::abs(est.position), a - e_in + 1e-12);
}

// One transverse force F at the end of a free block: it accelerates and turns. With the
// d'Alembert line loads (uniform -F/L, linear from the angular acceleration, and the rotary inertia
// couple) the bending moment at distance x from the loaded end, for half length a, half depth c, is
//   M(x) = F [ -x + x^2/(4a) + (c^2 x/2 + x^2 (3a - x)/4) / (a^2 + c^2) ],
// stationary where 3x^2 - (2(a^2 + c^2)/a + 6a) x + 4a^2 + 2c^2 = 0. For c -> 0 (Euler-Bernoulli)
// M = F (-x + x^2/a - x^3/(4a^2)): maximum |M| = 4 F L / 27 at x = L/3 (L = 2a).
TEST(BlockStress, FreeBlockUnderAnEndForceMatchesTheDAlembertBeam) {
  for (const double c : {0.25, 2e-3}) {
    BlockBox b;
    b.half_extents = Vec3(2.0, 0.5, c);
    b.centre = Vec3(1.0, 2.0, 3.0);
    b.orientation = Quat(Eigen::AngleAxisd(0.7, Vec3(0.3, -1.0, 0.5).normalized()));
    const double a = 2.0, F = 1e3, S = 4.0 * 0.5 * c * c / 3.0;
    const std::vector<PointLoad> loads{local_load(b, Vec3(a, 0.0, 0.0), Vec3(0, 0, F))};
    const FlexureEstimate e = flexure_estimate(b, loads, kSigmaF);

    const double B = 2.0 * (a * a + c * c) / a + 6.0 * a, C = 4.0 * a * a + 2.0 * c * c;
    const double x = (B - std::sqrt(B * B - 12.0 * C)) / 6.0;
    const double M = F * (-x + x * x / (4 * a) + (c * c * x / 2 + x * x * (3 * a - x) / 4) / (a * a + c * c));
    const double M_eb = 4.0 * F * (2 * a) / 27.0;
    std::printf("free block, end force, c = %g m: max |M| %.12g N m (closed form %.12g, rel. %.1e) at x = %.9f m from "
                "the loaded end (closed form %.9f); Euler-Bernoulli 4FL/27 = %.12g at L/3 = %.9f (|M|/that - 1 = %.2e)\n",
                c, e.stress * S, std::abs(M), rel(e.stress * S, std::abs(M)), a - e.position, x, M_eb, 2 * a / 3,
                e.stress * S / M_eb - 1.0);
    EXPECT_EQ(e.axis, 0);
    EXPECT_LT(rel(e.stress, std::abs(M) / S), 1e-12);
    EXPECT_NEAR(a - e.position, x, 1e-9);
    EXPECT_NEAR(e.axial, 0.0, 1e-9 * F);
    if (c < 0.01) {
      EXPECT_LT(rel(std::abs(M), M_eb), 1e-5);  // rotary inertia ~ c^2/a^2
    }
    // The moment diagram closes at both free ends, and the unloaded end (x = L) has M = 0.
    const BeamSection left = beam_section(b, loads, 0, -a);
    EXPECT_LT(left.moment_local.norm(), 1e-12 * F * a);
    EXPECT_LT(std::abs(left.axial), 1e-12 * F);
  }
}

// For any load set the d'Alembert section forces vanish at both free ends, and the exact maximum
// is what dense sampling of the moment diagram approaches from below.
TEST(BlockStress, MomentDiagramClosesAndTheMaximumIsExact) {
  BlockBox b = slab();
  b.orientation = Quat(0.3, -0.5, 0.7, 0.2).normalized();
  const std::vector<PointLoad> loads = random_loads(b, 40, 7);
  // Closure needs every load strictly inside the ends (a load on an end face is a load *at* the
  // end section: eccentric end loads are real end moments).
  double worst = 0;
  for (int axis = 0; axis < 3; ++axis) {
    const double a = b.half_extents[axis];
    for (double s : {-a, a}) {
      const BeamSection q = beam_section(b, loads, axis, s);
      worst = std::max({worst, std::abs(q.axial) / 1e4, q.moment_local.norm() / (1e4 * a)});
    }
  }
  std::printf("closure at the free ends, 40 random loads of 1e4 N: largest |N|/F, |M|/(F a) = %.2e\n", worst);
  EXPECT_LT(worst, 1e-12);

  const FlexureEstimate e = flexure_estimate(b, loads, kSigmaF);
  double sampled = 0;
  int axes[2];
  flexure_beam_axes(b.half_extents, axes);
  for (int axis : axes) {
    const double a = b.half_extents[axis];
    for (int n = 0; n <= 40000; ++n) sampled = std::max(sampled, beam_section(b, loads, axis, -a + 2 * a * n / 40000.0).stress);
  }
  // The maximum may sit at a load point (a kink of the diagram): refine the sampling around it.
  double fine = 0;
  for (int n = -10000; n <= 10000; ++n) {
    const double s = std::clamp(e.position + 1e-4 * n / 10000.0, -b.half_extents[e.axis], b.half_extents[e.axis]);
    fine = std::max(fine, beam_section(b, loads, e.axis, s).stress);
  }
  const BeamSection at = beam_section(b, loads, e.axis, e.position);
  std::printf("max sigma: exact %.12g Pa at axis %d s = %.6f m; 80002 samples along both beams reach %.12g Pa "
              "(%.1e below), 20001 samples 1e-8 m apart around s reach %.12g Pa (%.1e below)\n",
              e.stress, e.axis, e.position, sampled, 1 - sampled / e.stress, fine, 1 - fine / e.stress);
  EXPECT_GE(e.stress, sampled * (1 - 1e-14));
  EXPECT_GE(e.stress, fine * (1 - 1e-14));
  EXPECT_LT(1 - sampled / e.stress, 1e-4);
  EXPECT_LT(1 - fine / e.stress, 1e-8);
  EXPECT_LE(at.stress, e.stress * (1 + 1e-12));
}

// Axial loads and uniform pressure do not bend the block; axial tension gives sigma = N / A.
TEST(BlockStress, AxialLoadsAndUniformPressureDoNotBend) {
  const BlockBox b = slab();
  const double P = 3e4;
  const std::vector<PointLoad> compression{local_load(b, Vec3(-2, 0, 0), Vec3(P, 0, 0)),
                                           local_load(b, Vec3(2, 0, 0), Vec3(-P, 0, 0))};
  const FlexureEstimate ec = flexure_estimate(b, compression, kSigmaF);
  const FlexureEstimate ecb = flexure_estimate(b, compression, kSigmaF, {.axial = false});
  const std::vector<PointLoad> tension{local_load(b, Vec3(-2, 0, 0), Vec3(-P, 0, 0)),
                                       local_load(b, Vec3(2, 0, 0), Vec3(P, 0, 0))};
  const FlexureEstimate et = flexure_estimate(b, tension, kSigmaF);
  const double A = 1.0 * 0.5;
  std::printf("axial: compression sigma %.3g Pa (bending alone %.3g); tension sigma %.12g Pa = N/A %.12g Pa\n",
              ec.stress, ecb.stress, et.stress, P / A);
  EXPECT_EQ(ec.stress, 0.0);
  EXPECT_EQ(ec.utilisation, 0.0);
  EXPECT_EQ(ecb.stress, 0.0);
  EXPECT_LT(rel(et.stress, P / A), 1e-12);
  EXPECT_NEAR(et.moment_local.norm(), 0.0, 1e-12 * P);

  // Pressure p on all six faces, 6 x 6 point loads per face at the face cells' centres.
  const double p = 1e5;
  std::vector<PointLoad> pressure;
  const Vec3 he = b.half_extents;
  for (int axis = 0; axis < 3; ++axis)
    for (double side : {-1.0, 1.0}) {
      const int u = (axis + 1) % 3, v = (axis + 2) % 3;
      const double cell_force = p * (2 * he[u]) * (2 * he[v]) / 36.0;
      for (int m = 0; m < 6; ++m)
        for (int n = 0; n < 6; ++n) {
          Vec3 x = Vec3::Zero(), f = Vec3::Zero();
          x[axis] = side * he[axis];
          x[u] = he[u] * (-1 + (2 * m + 1) / 6.0);
          x[v] = he[v] * (-1 + (2 * n + 1) / 6.0);
          f[axis] = -side * cell_force;
          pressure.push_back(local_load(b, x, f));
        }
    }
  const FlexureEstimate ep = flexure_estimate(b, pressure, kSigmaF);
  const FlexureEstimate epb = flexure_estimate(b, pressure, kSigmaF, {.axial = false});
  std::printf("uniform pressure %.0f Pa on every face: sigma %.3g Pa, bending alone %.3g Pa (%.1e p)\n", p, ep.stress,
              epb.stress, epb.stress / p);
  EXPECT_EQ(ep.utilisation, 0.0);
  EXPECT_LT(epb.stress, 1e-12 * p);
}

// The estimate is a property of the block and its loads, not of the frame: loads rotated and
// translated with the block, or mirrored through any of its symmetry planes, give the same u_b.
TEST(BlockStress, RotatedOrMirroredLoadsGiveTheSameUtilisation) {
  BlockBox b;
  b.half_extents = Vec3(1.5, 2.5, 0.4);  // longest axis y: beams along y then x
  const std::vector<PointLoad> base = random_loads(b, 25, 11);
  const FlexureEstimate e0 = flexure_estimate(b, base, kSigmaF);

  BlockBox r = b;
  r.orientation = Quat(0.8, -0.3, 0.45, 0.25).normalized();
  r.centre = Vec3(123.4, -56.7, -0.8);
  std::vector<PointLoad> rotated;
  for (const PointLoad& l : base) rotated.push_back(local_load(r, l.point, l.force));
  const FlexureEstimate er = flexure_estimate(r, rotated, kSigmaF);
  std::printf("rotation: u_b %.15f (axis %d, s %.9f) vs %.15f (axis %d, s %.9f), rel. %.1e\n", e0.utilisation, e0.axis,
              e0.position, er.utilisation, er.axis, er.position, rel(er.utilisation, e0.utilisation));
  EXPECT_LT(rel(er.utilisation, e0.utilisation), 1e-12);
  EXPECT_EQ(er.axis, e0.axis);
  EXPECT_NEAR(er.position, e0.position, 1e-9);

  for (int m = 0; m < 3; ++m) {
    std::vector<PointLoad> mirrored;
    for (const PointLoad& l : base) {
      PointLoad q = l;
      q.point[m] = -q.point[m];
      q.force[m] = -q.force[m];
      mirrored.push_back(q);
    }
    const FlexureEstimate em = flexure_estimate(b, mirrored, kSigmaF);
    std::printf("mirror x%d -> -x%d: u_b %.15f, rel. %.1e\n", m, m, em.utilisation, rel(em.utilisation, e0.utilisation));
    EXPECT_LT(rel(em.utilisation, e0.utilisation), 1e-12);
    EXPECT_EQ(em.axis, e0.axis);
    EXPECT_NEAR(std::abs(em.position), std::abs(e0.position), 1e-9);
  }
  EXPECT_GT(e0.utilisation, 0.0);
}

TEST(BlockStress, BeamAxesAreTheTwoLongest) {
  int ax[2];
  flexure_beam_axes(Vec3(1.5, 2.5, 0.4), ax);
  EXPECT_EQ(ax[0], 1);
  EXPECT_EQ(ax[1], 0);
  flexure_beam_axes(Vec3(0.3, 1.0, 1.0), ax);
  EXPECT_EQ(ax[0], 1);
  EXPECT_EQ(ax[1], 2);
  const FlexureEstimate none = flexure_estimate(slab(), {}, kSigmaF);
  EXPECT_EQ(none.axis, -1);
  EXPECT_EQ(none.utilisation, 0.0);
}

// ---- freeze bonds ----

TEST(BlockStress, FreezeBondUtilisation) {
  const FreezeBondStrength s{50e3, 80e3};
  // Joint 1 governs in tension (0.6) over joint 0's shear (0.5); joint 2's compression is ignored.
  std::vector<FreezeJointSample> j{{-1e3, 0.5 * 80e3 * 0.2, 0.2}, {0.6 * 50e3 * 0.5, 0.0, 0.5}, {-1e6, 0.0, 0.1}};
  FreezeBondEstimate e = freeze_bond_estimate(j, s);
  std::printf("freeze: u_f %.6f at joint %zu (tension), stress %.0f Pa\n", e.utilisation, e.joint, e.stress);
  EXPECT_DOUBLE_EQ(e.utilisation, 0.6);
  EXPECT_EQ(e.joint, 1u);
  EXPECT_EQ(e.mode, FreezeBondMode::Tension);
  EXPECT_DOUBLE_EQ(e.stress, 0.6 * 50e3);
  // Shear governs, its sign ignored.
  j[0].shear = -0.9 * 80e3 * 0.2;
  e = freeze_bond_estimate(j, s);
  std::printf("freeze: u_f %.6f at joint %zu (shear)\n", e.utilisation, e.joint);
  EXPECT_DOUBLE_EQ(e.utilisation, 0.9);
  EXPECT_EQ(e.joint, 0u);
  EXPECT_EQ(e.mode, FreezeBondMode::Shear);
  // Compression only: nothing can break.
  const std::vector<FreezeJointSample> comp{{-5e5, 0.0, 0.3}};
  e = freeze_bond_estimate(comp, s);
  EXPECT_EQ(e.utilisation, 0.0);
  EXPECT_EQ(e.mode, FreezeBondMode::None);
  EXPECT_EQ(e.joint, FreezeBondEstimate::kNoJoint);
  // Exactly at the strength (RigidWorld's breaking load: T > sigma_t A breaks): u = 1 exactly.
  const double A = 0.37;
  const std::vector<FreezeJointSample> at{{A * s.tensile, 0.0, A}};
  const std::vector<FreezeJointSample> at_shear{{0.0, A * s.shear, A}};
  EXPECT_EQ(freeze_bond_estimate(at, s).utilisation, 1.0);
  EXPECT_EQ(freeze_bond_estimate(at_shear, s).utilisation, 1.0);
  EXPECT_EQ(freeze_bond_estimate({}, s).utilisation, 0.0);
  EXPECT_THROW(freeze_bond_estimate(std::vector<FreezeJointSample>{{1.0, 0.0, 0.0}}, s), InputError);
  EXPECT_THROW(freeze_bond_estimate(at, FreezeBondStrength{0.0, 1.0}), InputError);
}

// ---- combined estimate and the rule ----

TEST(BlockStress, ConversionRuleAndSafetyFactor) {
  EXPECT_FALSE(converts(0.55, 1.0));
  EXPECT_FALSE(converts(0.55, 1.8));  // 0.99
  EXPECT_TRUE(converts(0.55, 2.0));   // 1.1: SF > 1 converts earlier
  EXPECT_TRUE(converts(1.0, 1.0));    // at the limit
  EXPECT_FALSE(converts(1.2, 0.8));   // 0.96: SF < 1 converts later
  EXPECT_THROW(converts(1.0, 0.0), InputError);
  EXPECT_THROW(converts(1.0, NAN), InputError);
}

// ---- the conversion criteria (conversion_criteria.h) ----

// The criteria list gives the same utilisations as the estimates called by hand, the larger
// governs (ties: the earlier criterion), and the block-particle bonds count in the freeze-bond
// criterion only when they exceed the joints.
TEST(BlockStress, CriteriaListMatchesTheEstimates) {
  const auto criteria = conversion_criteria();
  ASSERT_EQ(criteria.size(), 3u);
  EXPECT_STREQ(criteria[kFreezeBondCriterion].name, "freeze_bond");
  EXPECT_STREQ(criteria[kFlexureCriterion].name, "flexure");
  EXPECT_STREQ(criteria[kCrushingCriterion].name, "crushing");
  BlockLoads b;
  b.box = slab();
  b.loads = random_loads(b.box, 6, 7);
  ConversionStrengths s;
  s.freeze = {60e3, 40e3};
  s.flexural_strength = kSigmaF;
  const double A = 0.2;
  b.joints = {{0.3 * A * s.freeze.tensile, 0.1 * A * s.freeze.shear, A}};  // u_f = 0.3
  const double u_b = flexure_estimate(b.box, b.loads, kSigmaF).utilisation;
  ASSERT_GT(u_b, 0.0);
  EXPECT_EQ(criteria[kFreezeBondCriterion].utilisation(b, s), freeze_bond_estimate(b.joints, s.freeze).utilisation);
  EXPECT_EQ(criteria[kFlexureCriterion].utilisation(b, s), u_b);
  // Flexure governs when larger; the joint when its load is raised above it.
  ConversionDecision d = evaluate_criteria(b, s);
  const double u_f = freeze_bond_estimate(b.joints, s.freeze).utilisation;
  EXPECT_EQ(d.utilisation, std::max(u_f, u_b));
  EXPECT_EQ(d.governing, u_b > u_f ? static_cast<int>(kFlexureCriterion) : static_cast<int>(kFreezeBondCriterion));
  b.joints[0].tension = 2.0 * u_b * A * s.freeze.tensile;  // u_f = 2 u_b
  d = evaluate_criteria(b, s);
  EXPECT_EQ(d.governing, static_cast<int>(kFreezeBondCriterion));
  EXPECT_EQ(d.utilisation, 2.0 * u_b);
  // A block-particle bond above the joints governs the freeze-bond criterion; below, it does not.
  b.bond_u_shear = 3.0 * u_b;
  EXPECT_EQ(freeze_bond_utilisation(b, s), 3.0 * u_b);
  b.bond_u_shear = 0.5 * u_b;
  EXPECT_EQ(freeze_bond_utilisation(b, s), 2.0 * u_b);
  // A tie goes to the earlier criterion; nothing loaded: no criterion governs.
  b.joints.clear();
  b.bond_u_shear = 0.0;
  b.bond_u_tension = u_b;  // u_f = u_b exactly
  d = evaluate_criteria(b, s);
  EXPECT_EQ(d.governing, static_cast<int>(kFreezeBondCriterion));
  EXPECT_EQ(d.utilisation, u_b);
  // Crushing: the largest particle contact force over the crushing force; none while that is
  // infinite (the default: bonds that do not crush).
  b.particle_contact_force = 900.0;
  EXPECT_EQ(criteria[kCrushingCriterion].utilisation(b, s), 0.0);
  s.contact_crushing_force = 300.0;
  EXPECT_EQ(criteria[kCrushingCriterion].utilisation(b, s), 3.0);
  for (const double bad : {0.0, -300.0, std::nan("")}) {
    ConversionStrengths w = s;
    w.contact_crushing_force = bad;
    EXPECT_THROW(criteria[kCrushingCriterion].utilisation(b, w), InputError) << bad;
  }
  d = evaluate_criteria(b, s);
  EXPECT_EQ(d.governing, 3.0 > u_b ? static_cast<int>(kCrushingCriterion) : static_cast<int>(kFreezeBondCriterion));
  BlockLoads none;
  none.box = slab();
  d = evaluate_criteria(none, s);
  EXPECT_EQ(d.governing, -1);
  EXPECT_EQ(d.utilisation, 0.0);
}

// ---- conversion region ----

TEST(BlockStress, RegionMovesWithTheStructure) {
  ConversionRegion box;
  box.shape = ConversionRegion::Shape::Box;
  box.offset = Vec3(-5.0, 0.0, -2.0);
  box.half_extents = Vec3(15.0, 10.0, 8.0);
  ConversionRegion cyl;
  cyl.radius = 12.0;
  cyl.z_min = -10.0;
  cyl.z_max = 3.0;
  box.validate();
  cyl.validate();
  const Vec3 he(1.5, 1.0, 0.5);  // bounding radius 1.871 m
  const Vec3 s0(0.0, 0.0, 0.0), shift(37.2, -4.1, 0.0);
  std::mt19937 gen(3);
  std::uniform_real_distribution<double> u(-30.0, 30.0);
  int in = 0;
  for (int n = 0; n < 2000; ++n) {
    const Vec3 c(u(gen), u(gen), 0.5 * u(gen));
    for (const ConversionRegion* r : {&box, &cyl}) {
      const bool a = r->contains_block(s0, c, he), b = r->contains_block(s0 + shift, c + shift, he);
      EXPECT_EQ(a, b);
      EXPECT_NEAR(r->distance(s0, c), r->distance(s0 + shift, c + shift), 1e-12);
      in += a;
    }
  }
  std::printf("region: 2 x 2000 random blocks, %d inside, identical after moving structure and block by (%.1f, %.1f, %.1f) m\n",
              in, shift.x(), shift.y(), shift.z());
  EXPECT_GT(in, 100);
  EXPECT_LT(in, 3900);
}

TEST(BlockStress, RegionInsideOutsideAndStraddling) {
  const Vec3 structure(100.0, 20.0, 0.0);
  const Vec3 he(2.0, 1.0, 0.5);
  const double rb = he.norm();  // 2.2913 m
  ConversionRegion box;
  box.shape = ConversionRegion::Shape::Box;
  box.offset = Vec3(-5.0, 0.0, 0.0);
  box.half_extents = Vec3(10.0, 6.0, 4.0);  // x in [85, 105], y in [14, 26], z in [-4, 4]
  EXPECT_TRUE(box.contains_block(structure, Vec3(95.0, 20.0, 0.0), he));           // centre inside
  EXPECT_TRUE(box.contains_block(structure, Vec3(105.0 + 0.99 * rb, 20.0, 0.0), he));  // straddling +x face
  EXPECT_FALSE(box.contains_block(structure, Vec3(105.0 + 1.01 * rb, 20.0, 0.0), he)); // clear of it
  // Off a corner: the distance is Euclidean to the corner, not per axis.
  const Vec3 corner(105.0, 26.0, 4.0), diag = Vec3(1, 1, 1).normalized();
  EXPECT_TRUE(box.contains_block(structure, corner + 0.99 * rb * diag, he));
  EXPECT_FALSE(box.contains_block(structure, corner + 1.01 * rb * diag, he));
  EXPECT_NEAR(box.distance(structure, corner + 3.0 * diag), 3.0, 1e-12);
  EXPECT_TRUE(box.contains_point(structure, Vec3(85.0, 14.0, -4.0)));  // closed region

  ConversionRegion cyl;
  cyl.offset = Vec3(0.0, 0.0, 0.0);
  cyl.radius = 10.0;
  cyl.z_min = -8.0;
  cyl.z_max = 2.0;
  const Vec3 radial = Vec3(3.0, -4.0, 0.0).normalized();
  EXPECT_TRUE(cyl.contains_block(structure, structure + 5.0 * radial, he));
  EXPECT_TRUE(cyl.contains_block(structure, structure + (10.0 + 0.99 * rb) * radial, he));
  EXPECT_FALSE(cyl.contains_block(structure, structure + (10.0 + 1.01 * rb) * radial, he));
  EXPECT_TRUE(cyl.contains_block(structure, structure + Vec3(0, 0, 2.0 + 0.99 * rb), he));   // above the top
  EXPECT_FALSE(cyl.contains_block(structure, structure + Vec3(0, 0, 2.0 + 1.01 * rb), he));
  EXPECT_FALSE(cyl.contains_block(structure, structure + Vec3(0, 0, -8.0 - 1.01 * rb), he)); // below the bottom
  // Off the rim: distance to the circle edge.
  const Vec3 rim = structure + 10.0 * radial + Vec3(0, 0, 2.0);
  const Vec3 out = (radial + Vec3::UnitZ()).normalized();
  EXPECT_NEAR(cyl.distance(structure, rim + 1.7 * out), 1.7, 1e-12);
  EXPECT_TRUE(cyl.contains_block(structure, rim + 0.99 * rb * out, he));
  EXPECT_FALSE(cyl.contains_block(structure, rim + 1.01 * rb * out, he));
  // A box region's corner would hold this point; the cylinder does not.
  EXPECT_FALSE(cyl.contains_point(structure, structure + Vec3(9.0, 9.0, 0.0)));

  ConversionRegion bad = cyl;
  bad.z_max = bad.z_min;
  EXPECT_THROW(bad.validate(), InputError);
  bad = box;
  bad.half_extents.y() = 0.0;
  EXPECT_THROW(bad.validate(), InputError);
}
