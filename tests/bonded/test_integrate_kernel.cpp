// The integrator's passes (integrate_kernel.h) against the Vec3 loops they replaced, bit for bit:
// 37 particles (four vector blocks of eight and a tail of five where the target has AVX-512),
// random state; the returned maxima too, and their NaN rules. The orientation update likewise
// (blocks of four), and against a constant spin's exact rotation.
#include "bonded/integrate_kernel.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

namespace hs::bonded {
namespace {

struct State {
  std::vector<Vec3> x, v, w, f, t, xb;
  std::vector<double> im, ii, m;
};

State random_state(std::size_t n, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  auto vec = [&](double s) { return Vec3(s * u(rng), s * u(rng), s * u(rng)); };
  State s;
  for (std::size_t i = 0; i < n; ++i) {
    s.x.push_back(vec(10.0));
    s.xb.push_back(s.x.back() + vec(0.01));
    s.v.push_back(vec(0.5));
    s.w.push_back(vec(2.0));
    s.f.push_back(vec(1e4));
    s.t.push_back(vec(1e3));
    s.m.push_back(50.0 + 10.0 * u(rng));
    s.im.push_back(i % 11 == 3 ? 0.0 : 1.0 / s.m.back());  // some immovable ones
    s.ii.push_back(1.0 / (0.4 * s.m.back() * 0.0625));
  }
  return s;
}

bool same_bits(const std::vector<Vec3>& a, const std::vector<Vec3>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(Vec3)) == 0;
}

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// |a|^2 as Eigen's squaredNorm of a Vec3 computes it with nothing fused (the build's
// -ffp-contract=off): (x x + y y) + z z.
double squared_norm_as_compiled(const Vec3& a) { return (a.x() * a.x() + a.y() * a.y()) + a.z() * a.z(); }

constexpr double kDt = 4.8e-5, kHdt = 0.5 * kDt;
const Vec3 kG(0.0, 0.0, -9.81);

TEST(IntegrateKernel, KickDriftIsTheVec3LoopBitForBit) {
  for (unsigned seed = 1; seed <= 50; ++seed) {
  State a = random_state(37, seed), b = a;
  const double got = kick_drift(a.x.size(), kDt, kHdt, a.x.data(), a.v.data(), a.w.data(), a.f.data(), a.t.data(),
                                a.im.data(), a.ii.data(), a.m.data(), a.xb.data(), kG);
  double want = 0.0;  // the loop of Engine::step before integrate_kernel
  for (std::size_t i = 0; i < b.x.size(); ++i) {
    b.v[i] += kHdt * b.im[i] * b.f[i];
    b.w[i] += kHdt * b.ii[i] * b.t[i];
    b.x[i] += kDt * b.v[i];
    want = std::max(want, squared_norm_as_compiled(b.x[i] - b.xb[i]));
    b.f[i] = b.m[i] * kG;
    b.t[i].setZero();
  }
  ASSERT_TRUE(same_bits(a.x, b.x)) << "seed " << seed;
  ASSERT_TRUE(same_bits(a.v, b.v)) << "seed " << seed;
  ASSERT_TRUE(same_bits(a.w, b.w)) << "seed " << seed;
  ASSERT_TRUE(same_bits(a.f, b.f)) << "seed " << seed;
  ASSERT_TRUE(same_bits(a.t, b.t)) << "seed " << seed;
  ASSERT_TRUE(same_bits(got, want)) << "seed " << seed << ": " << got << " vs " << want;
  }
}

TEST(IntegrateKernel, KickIsTheVec3LoopBitForBit) {
  // Many seeds: a squared length summed in another order differs in the last bit for some of them.
  for (unsigned seed = 1; seed <= 50; ++seed) {
    State a = random_state(37, seed), b = a;
    const double got = kick(a.v.size(), kHdt, a.v.data(), a.w.data(), a.f.data(), a.t.data(), a.im.data(), a.ii.data());
    double want = 0.0;
    for (std::size_t i = 0; i < b.v.size(); ++i) {
      b.v[i] += kHdt * b.im[i] * b.f[i];
      b.w[i] += kHdt * b.ii[i] * b.t[i];
      want = std::max(want, squared_norm_as_compiled(b.v[i]));
    }
    ASSERT_TRUE(same_bits(a.v, b.v)) << "seed " << seed;
    ASSERT_TRUE(same_bits(a.w, b.w)) << "seed " << seed;
    ASSERT_TRUE(same_bits(got, want)) << "seed " << seed << ": " << got << " vs " << want;
  }
}

TEST(IntegrateKernel, NaNIsReportedByKickAndIgnoredByTheDisplacement) {
  for (std::size_t bad : {std::size_t{0}, std::size_t{13}, std::size_t{35}}) {  // in a block, and in the tail
    State a = random_state(37, 7);
    a.v[bad].x() = std::numeric_limits<double>::quiet_NaN();
    State b = a;
    EXPECT_TRUE(std::isnan(kick(a.v.size(), kHdt, a.v.data(), a.w.data(), a.f.data(), a.t.data(), a.im.data(), a.ii.data())))
        << "particle " << bad;
    // The displacement's largest value leaves the NaN out (std::max(disp2, NaN) keeps disp2).
    const double d2 = kick_drift(b.x.size(), kDt, kHdt, b.x.data(), b.v.data(), b.w.data(), b.f.data(), b.t.data(),
                                 b.im.data(), b.ii.data(), b.m.data(), b.xb.data(), kG);
    EXPECT_FALSE(std::isnan(d2)) << "particle " << bad;
    EXPECT_GT(d2, 0.0);
  }
}

// The orientation update (orientation_kernel.cpp) against the scalar update it replaced, bit for
// bit: spins of up to 350 rad/s (|w| dt / 2 < 0.0083: the series; spins this fast make the
// rotation's products large enough to reach the last bit: with one Hamilton-product term fused
// this test fails; a regrouped |w|^2 moves h2 by one bit only, which seldom shows), none
// (unchanged), and 1000 rad/s (|w| dt / 2 = 0.024: cos and sin, the scalar fallback), in blocks of
// four and the tail.
std::vector<Vec3> spins(std::size_t n, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Vec3> w;
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 r(u(rng), u(rng), u(rng));
    w.push_back(i % 7 == 0 ? Vec3::Zero() : i % 9 == 4 ? Vec3(1000.0 * r.normalized()) : Vec3(200.0 * r));
  }
  return w;
}

std::vector<Quat> orientations(std::size_t n, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Quat> q;
  for (std::size_t i = 0; i < n; ++i) q.push_back(Quat(u(rng), u(rng), u(rng), u(rng)).normalized());
  return q;
}

bool same_bits(const std::vector<Quat>& a, const std::vector<Quat>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(Quat)) == 0;
}

TEST(IntegrateKernel, OrientationUpdateIsTheScalarUpdateBitForBit) {
  for (unsigned seed = 1; seed <= 50; ++seed) {
    std::mt19937_64 rng(seed);
    const std::vector<Vec3> w = spins(37, rng);
    const std::vector<Quat> q0 = orientations(37, rng);
    std::vector<Quat> a = q0, b = q0;
    rotate_orientations(a.size(), a.data(), w.data(), kDt);
    for (std::size_t i = 0; i < b.size(); ++i) rotate_orientation(b[i], w[i], kDt);
    ASSERT_TRUE(same_bits(a, b)) << "seed " << seed;
    for (std::size_t i = 0; i < a.size(); i += 7) ASSERT_EQ(a[i].coeffs(), q0[i].coeffs()) << "w = 0 leaves q";
  }
}

// A particle's update does not depend on its place in the array (lane, tail): every shift of the
// arrays gives each particle the same bits. This is what keeps the rank count out of the results,
// with any compiler.
TEST(IntegrateKernel, OrientationUpdateDoesNotDependOnTheParticlesPlace) {
  std::mt19937_64 rng(4);
  const std::vector<Vec3> w = spins(23, rng);
  const std::vector<Quat> q0 = orientations(23, rng);
  std::vector<Quat> ref = q0;
  rotate_orientations(ref.size(), ref.data(), w.data(), kDt);
  for (std::size_t shift = 1; shift < 8; ++shift) {
    std::vector<Vec3> ws(w.size());
    std::vector<Quat> qs(q0.size());
    for (std::size_t i = 0; i < w.size(); ++i) {
      ws[(i + shift) % w.size()] = w[i];
      qs[(i + shift) % w.size()] = q0[i];
    }
    rotate_orientations(qs.size(), qs.data(), ws.data(), kDt);
    for (std::size_t i = 0; i < w.size(); ++i)
      ASSERT_EQ(qs[(i + shift) % w.size()].coeffs(), ref[i].coeffs()) << "shift " << shift << " particle " << i;
  }
}

// A constant spin turns the orientation by |w| t about w: 10,000 steps of 1e-4 s at 3 rad/s, five
// particles (a block and a tail of one), against the rotation exp(w t) q0. Measured: at most
// 2.5e-14 (the quaternions' largest component difference; 8e-15 to 2.5e-14 over the five).
TEST(IntegrateKernel, OrientationUpdateFollowsAConstantSpin) {
  std::mt19937_64 rng(8);
  const std::vector<Quat> q0 = orientations(5, rng);
  std::vector<Vec3> w;
  for (std::size_t i = 0; i < 5; ++i) w.push_back(3.0 * Vec3(1.0, -2.0 + i, 0.5 * i).normalized());
  std::vector<Quat> q = q0;
  const double dt = 1e-4;
  const int steps = 10000;
  for (int s = 0; s < steps; ++s) rotate_orientations(q.size(), q.data(), w.data(), dt);
  for (std::size_t i = 0; i < q.size(); ++i) {
    const Quat want = Quat(Eigen::AngleAxisd(3.0 * steps * dt, w[i].normalized())) * q0[i];
    const double err = std::min((q[i].coeffs() - want.coeffs()).cwiseAbs().maxCoeff(),
                                (q[i].coeffs() + want.coeffs()).cwiseAbs().maxCoeff());
    EXPECT_LT(err, 3e-13) << "particle " << i;
    EXPECT_NEAR(q[i].norm(), 1.0, 1e-15) << "particle " << i;
  }
}

}  // namespace
}  // namespace hs::bonded
