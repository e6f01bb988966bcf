// Parallel bond law: force and moment are minus the derivative of the bond energy
// (central finite differences), swapping the particles changes nothing, and the bond
// breaks exactly at its strength.
#include "bonded/bond_parallel.h"

#include <gtest/gtest.h>

#include <random>

using namespace hs;
using namespace hs::bonded;

namespace {

ParallelBondParams anisotropic_params() {
  // k_s != k_n and k_t != k_b on purpose, to exercise the n-dependent terms.
  ParallelBondParams p = ParallelBondParams::from_stiffness(1.3e8, 0.6e8, 0.25, INFINITY, INFINITY, 0.0, 1.0, 1.0);
  p.kt *= 0.7;
  return p.finalize();
}

Quat small_rotation(const Vec3& phi) {
  const double a = phi.norm();
  if (a == 0.0) return Quat::Identity();
  return Quat(Eigen::AngleAxisd(a, phi / a));
}

struct Config {
  Vec3 xi, xj;
  Quat qi, qj;
};

double energy(const ParallelBondParams& p, const BondRef& ref, const Config& c) {
  const Vec3 z = Vec3::Zero();
  return parallel_bond(p, ref, {c.xi, c.xj, c.qi, c.qj, z, z, z, z}).energy;
}

}  // namespace

TEST(ParallelBond, ForceAndMomentAreMinusEnergyGradient) {
  const ParallelBondParams p = anisotropic_params();
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    // Reference: two touching spheres (D = 0.5) in a random direction and orientations.
    Config c0;
    c0.xi = Vec3(u(rng), u(rng), u(rng));
    const Vec3 dir = Vec3(u(rng), u(rng), u(rng)).normalized();
    c0.xj = c0.xi + 0.5 * dir;
    c0.qi = small_rotation(Vec3(u(rng), u(rng), u(rng)));
    c0.qj = small_rotation(Vec3(u(rng), u(rng), u(rng)));
    const BondRef ref = BondRef::at_rest(c0.xi, c0.qi, 0.25, c0.xj, c0.qj, 0.25);
    // Deformed state: finite translation (mm-cm) and rotation (up to 0.3 rad).
    Config c = c0;
    c.xj += 0.02 * Vec3(u(rng), u(rng), u(rng));
    c.xi += 0.02 * Vec3(u(rng), u(rng), u(rng));
    c.qi = small_rotation(0.3 * Vec3(u(rng), u(rng), u(rng))) * c.qi;
    c.qj = small_rotation(0.3 * Vec3(u(rng), u(rng), u(rng))) * c.qj;
    const Vec3 z = Vec3::Zero();
    const BondResult r = parallel_bond(p, ref, {c.xi, c.xj, c.qi, c.qj, z, z, z, z});

    const double h = 1e-6;
    Vec3 fj_num, fi_num, tj_num, ti_num;
    for (int k = 0; k < 3; ++k) {
      const Vec3 e = Vec3::Unit(k) * h;
      Config a = c, b = c;
      a.xj += e; b.xj -= e;
      fj_num[k] = -(energy(p, ref, a) - energy(p, ref, b)) / (2 * h);
      a = c; b = c;
      a.xi += e; b.xi -= e;
      fi_num[k] = -(energy(p, ref, a) - energy(p, ref, b)) / (2 * h);
      a = c; b = c;
      a.qj = small_rotation(e) * c.qj; b.qj = small_rotation(-e) * c.qj;
      tj_num[k] = -(energy(p, ref, a) - energy(p, ref, b)) / (2 * h);
      a = c; b = c;
      a.qi = small_rotation(e) * c.qi; b.qi = small_rotation(-e) * c.qi;
      ti_num[k] = -(energy(p, ref, a) - energy(p, ref, b)) / (2 * h);
    }
    // Central differences: truncation O(h^2 E''') and round-off O(eps E / h); the scale
    // is the largest force/torque component. 1e-6 relative is ~100x above both.
    const double fs = std::max(1.0, r.fj.cwiseAbs().maxCoeff());
    const double ts = std::max(1.0, std::max(r.ti.cwiseAbs().maxCoeff(), r.tj.cwiseAbs().maxCoeff()));
    EXPECT_LT((r.fj - fj_num).cwiseAbs().maxCoeff(), 1e-6 * fs) << "trial " << trial;
    EXPECT_LT((-r.fj - fi_num).cwiseAbs().maxCoeff(), 1e-6 * fs) << "trial " << trial;
    EXPECT_LT((r.tj - tj_num).cwiseAbs().maxCoeff(), 1e-6 * ts) << "trial " << trial;
    EXPECT_LT((r.ti - ti_num).cwiseAbs().maxCoeff(), 1e-6 * ts) << "trial " << trial;
    // Rigid-motion invariance => total force and total moment about the origin vanish.
    const Vec3 moment = c.xi.cross(-r.fj) + c.xj.cross(r.fj) + r.ti + r.tj;
    EXPECT_LT(moment.norm(), 1e-9 * (fs + ts));
  }
}

TEST(ParallelBond, SwappingParticlesChangesNothing) {
  ParallelBondParams p = anisotropic_params();
  p.gamma_n = 1e5; p.gamma_s = 2e5; p.gamma_b = 3e3; p.gamma_t = 1e3;  // damping too
  Config c;
  c.xi = Vec3(0.1, 0.2, 0.3);
  c.xj = c.xi + Vec3(0.3, 0.4, 0.0);
  c.qi = small_rotation(Vec3(0.1, 0.0, 0.2));
  c.qj = small_rotation(Vec3(-0.2, 0.1, 0.0));
  const BondRef rij = BondRef::at_rest(c.xi, c.qi, 0.25, c.xj, c.qj, 0.25);
  const BondRef rji = BondRef::at_rest(c.xj, c.qj, 0.25, c.xi, c.qi, 0.25);
  c.xj += Vec3(0.004, -0.002, 0.003);
  c.qi = small_rotation(Vec3(0.01, 0.02, -0.03)) * c.qi;
  c.qj = small_rotation(Vec3(-0.02, 0.01, 0.02)) * c.qj;
  const Vec3 vi(0.1, 0.0, -0.2), vj(-0.3, 0.1, 0.0), wi(0.5, 0.1, 0.0), wj(0.0, -0.4, 0.2);
  const BondResult a = parallel_bond(p, rij, {c.xi, c.xj, c.qi, c.qj, vi, vj, wi, wj});
  const BondResult b = parallel_bond(p, rji, {c.xj, c.xi, c.qj, c.qi, vj, vi, wj, wi});
  const double fs = a.fj.norm(), ts = a.ti.norm() + a.tj.norm();
  EXPECT_LT((a.fj + b.fj).norm(), 1e-12 * fs);  // force on j == minus force on i
  EXPECT_LT((a.ti - b.tj).norm(), 1e-12 * ts);
  EXPECT_LT((a.tj - b.ti).norm(), 1e-12 * ts);
  EXPECT_NEAR(a.sigma, b.sigma, 1e-12 * std::abs(a.sigma));
  EXPECT_NEAR(a.tau, b.tau, 1e-12 * std::abs(a.tau));
  EXPECT_NEAR(a.energy, b.energy, 1e-12 * a.energy);
}

TEST(ParallelBond, StressesFollowBeamFormulas) {
  // Pure axial stretch: sigma = k_n du / A.  Pure bending: sigma = k_b theta R / I.
  const ParallelBondParams p = ParallelBondParams::from_stiffness(1e8, 1e8, 0.25, 1e6, 1e6, 0, 1, 1);
  const Vec3 xi = Vec3::Zero(), xj(0.5, 0, 0), z = Vec3::Zero();
  const Quat I = Quat::Identity();
  const BondRef ref = BondRef::at_rest(xi, I, 0.25, xj, I, 0.25);
  const Vec3 xs(0.501, 0, 0);
  const BondResult s = parallel_bond(p, ref, {xi, xs, I, I, z, z, z, z});
  EXPECT_NEAR(s.sigma, 1e8 * 0.001 / p.area(), 1e-9 * s.sigma);
  EXPECT_NEAR(s.fj.x(), -1e8 * 0.001, 1e-6);
  const Quat qb = small_rotation(Vec3(0, 0, 0.002));
  const Quat qa = small_rotation(Vec3(0, 0, -0.002));
  // Opposite rotations of i and j about z: bending by 0.004 rad, no shear at the centre.
  // Finite rotations also open the gap by R(1 - cos phi) = O(phi^2) (1e-6 m here), which
  // adds ~1e-3 relative to the stress and the moment: the tolerance is set to 2e-3.
  const BondResult bnd = parallel_bond(p, ref, {xi, xj, qa, qb, z, z, z, z});
  EXPECT_NEAR(bnd.sigma, p.kb * 0.004 * 0.25 / p.inertia(), 2e-3 * bnd.sigma);
  EXPECT_NEAR(bnd.tj.z(), -p.kb * 0.004, 2e-3 * p.kb * 0.004);
  // Twist by 0.004 rad about the bond axis: tau = k_t theta R / J.
  const BondResult tw = parallel_bond(p, ref, {xi, xj, small_rotation(Vec3(-0.002, 0, 0)), small_rotation(Vec3(0.002, 0, 0)), z, z, z, z});
  EXPECT_NEAR(tw.tau, p.kt * 0.004 * 0.25 / p.polar(), 1e-6 * tw.tau);
  EXPECT_NEAR(tw.sigma, 0.0, 1e-9);
}
