// The integrator's passes (integrate_kernel.h) against the Vec3 loops they replaced, bit for bit:
// 37 particles (four vector blocks of eight and a tail of five where the target has AVX-512),
// random state; the returned maxima too, and their NaN rules.
#include "bonded/integrate_kernel.h"

#include <gtest/gtest.h>

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

// |a|^2 as GCC compiles Eigen's squaredNorm of a Vec3 in the engine's loops (objdump of
// Engine::step before integrate_kernel and of its scalar tail: vmulpd (x x, y y), vaddsd, then
// vfmadd z z): (x x + y y) + z z with the last product fused. Written out with contraction off,
// so that the test's own compilation cannot regroup it.
#pragma GCC push_options
#pragma GCC optimize("fp-contract=off")
double squared_norm_as_compiled(const Vec3& a) { return std::fma(a.z(), a.z(), a.x() * a.x() + a.y() * a.y()); }
#pragma GCC pop_options

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

}  // namespace
}  // namespace hs::bonded
