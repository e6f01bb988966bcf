// The vectorised bond kernel (bond_kernel.h) against the scalar law (parallel_bond): the same
// forces, moments and breaks to round-off, for both bond kinds mixed in one batch, with damping,
// and for rotations beyond the series' range (scalar fallback); and a bond's result does not
// depend on its place in the batch (lane, padding of the last batch), bit for bit. Also the
// copy's upkeep: erasing broken bonds, and the bond order of a rebuild.
#include "bonded/bond_kernel.h"
#include "bonded/engine.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <random>
#include <string>

using namespace hs;
using namespace hs::bonded;

namespace {

Quat rotation(const Vec3& phi) {
  const double a = phi.norm();
  if (a == 0.0) return Quat::Identity();
  return Quat(Eigen::AngleAxisd(a, phi / a));
}

/// Particles in pairs (2k, 2k+1), each pair bonded, deformed by up to `trans` m and `rot` rad.
struct Scene {
  std::vector<Vec3> x, v, w, f, t;
  std::vector<Quat> q;
  std::vector<Bond> bonds;

  /// Bond kinds: kMixed (every third bond kind 1: batches mix kinds), kRuns (runs of five of one
  /// kind: some batches of one kind, some mixed), kSingle (all kind 0: the kernel's one-kind path).
  enum Kinds { kMixed, kRuns, kSingle };
  Scene(int n_bonds, double trans, double rot, std::uint64_t seed, Kinds kinds = kMixed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    auto rnd = [&] { return Vec3(u(rng), u(rng), u(rng)); };
    for (int b = 0; b < n_bonds; ++b) {
      const Vec3 xi = 10.0 * rnd(), xj = xi + 0.5 * rnd().normalized();
      const Quat qi = rotation(rnd()), qj = rotation(rnd());
      Bond bd{};
      bd.i = static_cast<std::uint32_t>(x.size());
      bd.j = bd.i + 1;
      bd.gi = bd.i;
      bd.gj = bd.j;
      const int kind = kinds == kMixed ? (b % 3 == 2 ? 1 : 0) : kinds == kRuns ? (b / 5) % 2 : 0;
      bd.kind = static_cast<BondKind>(kind);
      bd.ref = BondRef::at_rest(xi, qi, 0.25, xj, qj, 0.25);
      bonds.push_back(bd);
      x.push_back(xi + trans * rnd());
      x.push_back(xj + trans * rnd());
      q.push_back(rotation(rot * rnd()) * qi);
      q.push_back(rotation(rot * rnd()) * qj);
      for (int k = 0; k < 2; ++k) {
        v.push_back(0.3 * rnd());
        w.push_back(2.0 * rnd());
      }
    }
    f.assign(x.size(), Vec3::Zero());
    t.assign(x.size(), Vec3::Zero());
  }
  BondKernelIo io() { return {x.data(), q.data(), v.data(), w.data(), f.data(), t.data()}; }
};

void params(ParallelBondParams p[2], double strength) {
  // Anisotropic (k_s != k_n, k_t != k_b) and damped, two different kinds.
  p[0] = ParallelBondParams::from_stiffness(1.3e8, 0.6e8, 0.25, strength, strength, 0.1, 60.0, 1.0);
  p[0].kt *= 0.7;
  p[0].finalize();
  p[1] = ParallelBondParams::from_stiffness(0.9e8, 0.9e8, 0.2, strength, 0.8 * strength, 0.05, 60.0, 1.0);
}

}  // namespace

TEST(BondKernel, MatchesTheScalarLawForBothKindsWithDamping) {
  ParallelBondParams p[2];
  params(p, INFINITY);
  // Small rotations (series lanes, the hot path) and large ones (up to 0.3 rad: scalar fallback);
  // kinds mixed in every batch, and one kind throughout (the path of a one-material run).
  for (auto kinds : {Scene::kMixed, Scene::kSingle})
  for (double rot : {2e-3, 0.3}) {
    Scene s(203, 0.01, rot, 11, kinds);  // 203: the last batch is padded
    BondBatch bb;
    bb.pack(s.bonds);
    std::vector<BrokenBond> broken;
    bond_kernel(bb, p, 2, s.io(), broken);
    EXPECT_TRUE(broken.empty());
    double worst_f = 0.0, worst_t = 0.0;
    for (const Bond& b : s.bonds) {
      const BondResult r = parallel_bond(p[static_cast<int>(b.kind)], b.ref,
                                         {s.x[b.i], s.x[b.j], s.q[b.i], s.q[b.j], s.v[b.i], s.v[b.j], s.w[b.i], s.w[b.j]});
      // One bond per particle: f[j] = F_j, f[i] = -F_j.
      const double fs = r.fj.norm(), ts = std::max(r.ti.norm(), r.tj.norm());
      worst_f = std::max({worst_f, (s.f[b.j] - r.fj).norm() / fs, (s.f[b.i] + r.fj).norm() / fs});
      worst_t = std::max({worst_t, (s.t[b.i] - r.ti).norm() / ts, (s.t[b.j] - r.tj).norm() / ts});
    }
    std::printf("kinds %d, max rotation %.0e rad: kernel vs scalar law, force %.2e, moment %.2e (relative)\n",
                static_cast<int>(kinds), rot, worst_f, worst_t);
    // Measured 2.1e-14 / 4.9e-14 at 2e-3 rad (the gap u = d + a_j - a_i is ~50x smaller than its
    // terms, so both laws lose the same ~2 digits, differently rounded); 0 / 0 at 0.3 rad, where
    // every bond leaves the series' range and takes the scalar law.
    EXPECT_LT(worst_f, 2e-13);
    EXPECT_LT(worst_t, 5e-13);
  }
}

TEST(BondKernel, BreaksTheBondsTheScalarLawBreaks) {
  ParallelBondParams p[2];
  params(p, 2e6);  // a strength that about half the deformed bonds exceed
  p[0].sigma_cc = 2e6;  // and in compression (kind 0 only; kind 1 never fails in compression)
  Scene s(203, 0.004, 5e-3, 5);
  BondBatch bb;
  bb.pack(s.bonds);
  std::vector<BrokenBond> broken;
  bond_kernel(bb, p, 2, s.io(), broken);
  std::vector<BrokenBond> expected;
  std::size_t crushed = 0;
  for (std::size_t k = 0; k < s.bonds.size(); ++k) {
    const Bond& b = s.bonds[k];
    const ParallelBondParams& pk = p[static_cast<int>(b.kind)];
    const BondResult r =
        parallel_bond(pk, b.ref, {s.x[b.i], s.x[b.j], s.q[b.i], s.q[b.j], s.v[b.i], s.v[b.j], s.w[b.i], s.w[b.j]});
    const BondFailure mode = bond_failure(pk, r.sigma, r.tau, r.crush);
    if (mode != BondFailure::None) {
      expected.push_back({static_cast<std::uint32_t>(k), mode});
      crushed += mode == BondFailure::Compression;
      // A broken bond adds nothing.
      EXPECT_EQ(s.f[b.i], Vec3::Zero());
      EXPECT_EQ(s.t[b.j], Vec3::Zero());
    } else {
      EXPECT_NE(s.f[b.i], Vec3::Zero());
    }
  }
  std::printf("%zu of %zu bonds broken, %zu in compression\n", expected.size(), s.bonds.size(), crushed);
  ASSERT_GT(crushed, 5u);
  ASSERT_GT(expected.size(), 20u);
  ASSERT_LT(expected.size(), s.bonds.size() - 20);
  ASSERT_EQ(broken.size(), expected.size());
  for (std::size_t k = 0; k < broken.size(); ++k) {
    EXPECT_EQ(broken[k].index, expected[k].index);
    EXPECT_EQ(broken[k].mode, expected[k].mode);
  }
}

TEST(BondKernel, ABondsResultDoesNotDependOnItsPlaceInTheBatch) {
  ParallelBondParams p[2];
  params(p, INFINITY);
  Scene s(37, 0.01, 0.02, 3);  // 0.02 rad: both series and scalar lanes
  BondBatch bb;
  bb.pack(s.bonds);
  std::vector<BrokenBond> broken;
  bond_kernel(bb, p, 2, s.io(), broken);
  const std::vector<Vec3> f0 = s.f, t0 = s.t;
  // Rotate the bond list by every shift: each bond visits every lane and the padded tail.
  for (std::size_t shift = 1; shift < 2 * BondBatch::kLanes; ++shift) {
    std::vector<Bond> rotated(s.bonds.size());
    for (std::size_t k = 0; k < s.bonds.size(); ++k) rotated[(k + shift) % s.bonds.size()] = s.bonds[k];
    BondBatch rb;
    rb.pack(rotated);
    std::fill(s.f.begin(), s.f.end(), Vec3::Zero());
    std::fill(s.t.begin(), s.t.end(), Vec3::Zero());
    bond_kernel(rb, p, 2, s.io(), broken);
    for (std::size_t i = 0; i < s.x.size(); ++i) {
      ASSERT_EQ(s.f[i], f0[i]) << "shift " << shift << " particle " << i;
      ASSERT_EQ(s.t[i], t0[i]) << "shift " << shift << " particle " << i;
    }
  }
}

namespace {

void expect_same_batch(const BondBatch& a, const BondBatch& b, const std::string& what) {
  ASSERT_EQ(a.size(), b.size()) << what;
  ASSERT_EQ(a.padded(), b.padded()) << what;
  EXPECT_EQ(a.i, b.i) << what;
  EXPECT_EQ(a.j, b.j) << what;
  EXPECT_EQ(a.kind, b.kind) << what;
  EXPECT_EQ(a.batch_kind, b.batch_kind) << what;
  for (auto m : {&BondBatch::rix, &BondBatch::riy, &BondBatch::riz, &BondBatch::rjx, &BondBatch::rjy, &BondBatch::rjz,
                 &BondBatch::cw, &BondBatch::cx, &BondBatch::cy, &BondBatch::cz})
    EXPECT_EQ(a.*m, b.*m) << what;
}

}  // namespace

// Erasing broken bonds from the kernel's copy (Engine::bond_forces, at every step with a break)
// gives the copy that packing the remaining bonds gives: the same arrays, padding lanes and batch
// kinds, for erasures at the start, in runs, across batches, at the end, of every bond, and down
// to one bond; with kinds mixed in every batch and in runs (batches of one kind and mixed ones).
TEST(BondBatch, EraseIsThePackOfTheRemainingBonds) {
  std::vector<std::uint32_t> all(203);
  for (std::uint32_t k = 0; k < all.size(); ++k) all[k] = k;
  const std::vector<std::vector<std::uint32_t>> cases = {
      {0}, {202}, {1, 2, 3, 4, 5}, {3, 4, 9, 77, 78, 150, 201, 202}, {0, 1, 2}, {7, 8, 9, 10, 11, 12, 13, 14}, {4}, all};
  for (auto kinds : {Scene::kMixed, Scene::kRuns})
  for (const auto& gone_idx : cases) {
    const Scene s(203, 0.01, 2e-3, 5, kinds);
    BondBatch bb;
    bb.pack(s.bonds);
    std::vector<BrokenBond> gone;
    std::vector<Bond> rest;
    for (std::uint32_t k = 0, g = 0; k < s.bonds.size(); ++k) {
      if (g < gone_idx.size() && gone_idx[g] == k) {
        gone.push_back({k, BondFailure::Tension});
        ++g;
      } else {
        rest.push_back(s.bonds[k]);
      }
    }
    bb.erase(gone);
    BondBatch packed;
    packed.pack(rest);
    expect_same_batch(bb, packed, "kinds " + std::to_string(kinds) + ", erased " + std::to_string(gone.size()) + " from " +
                                      std::to_string(gone_idx.front()));
    EXPECT_TRUE(bb.valid_for(rest.size()));
  }
  {
    BondBatch bb;  // every bond erased
    bb.pack(Scene(203, 0.01, 2e-3, 5).bonds);
    std::vector<BrokenBond> gone;
    for (std::uint32_t k : all) gone.push_back({k, BondFailure::Tension});
    bb.erase(gone);
    EXPECT_EQ(bb.size(), 0u);
    EXPECT_EQ(bb.padded(), 0u);
    EXPECT_TRUE(bb.batch_kind.empty());
    EXPECT_TRUE(bb.valid_for(0));
  }
  // Repeated erasures down to a single bond.
  const Scene s(203, 0.01, 2e-3, 5, Scene::kRuns);
  BondBatch bb;
  bb.pack(s.bonds);
  std::vector<Bond> rest = s.bonds;
  while (rest.size() > 1) {
    std::vector<BrokenBond> gone;
    std::vector<Bond> keep;
    for (std::uint32_t k = 0; k < rest.size(); ++k)
      if (k % 3 == 1 || (rest.size() < 4 && k == 0)) gone.push_back({k, BondFailure::Shear});
      else keep.push_back(rest[k]);
    bb.erase(gone);
    rest = keep;
    BondBatch packed;
    packed.pack(rest);
    expect_same_batch(bb, packed, "down to " + std::to_string(rest.size()));
  }
}

// The bond order of a rebuild: by (lower index, higher index), whichever end a bond lists first;
// the same order a comparison sort gives, for a random set of unique pairs.
TEST(BondSort, OrdersByLowerThenHigherIndex) {
  std::mt19937_64 rng(9);
  const std::uint32_t n = 500;
  std::uniform_int_distribution<std::uint32_t> u(0, n - 1);
  std::vector<Bond> bonds;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> seen;
  while (bonds.size() < 3000) {
    const std::uint32_t a = u(rng), b = u(rng);
    const auto key = std::make_pair(std::min(a, b), std::max(a, b));
    if (a == b || std::find(seen.begin(), seen.end(), key) != seen.end()) continue;
    seen.push_back(key);
    Bond bd{};
    bd.i = a;
    bd.j = b;
    bd.gi = bonds.size();  // identifies the bond
    bonds.push_back(bd);
  }
  std::vector<Bond> expected = bonds;
  std::sort(expected.begin(), expected.end(), [](const Bond& x, const Bond& y) {
    return std::make_pair(std::min(x.i, x.j), std::max(x.i, x.j)) < std::make_pair(std::min(y.i, y.j), std::max(y.i, y.j));
  });
  BondSortScratch scratch;
  for (int pass = 0; pass < 2; ++pass) {  // the second pass: already sorted, scratch reused
    sort_bonds_by_particle(bonds, n, scratch);
    ASSERT_EQ(bonds.size(), expected.size());
    for (std::size_t k = 0; k < bonds.size(); ++k) {
      ASSERT_EQ(bonds[k].gi, expected[k].gi) << "pass " << pass << " position " << k;
      ASSERT_EQ(bonds[k].i, expected[k].i);
    }
  }
}
