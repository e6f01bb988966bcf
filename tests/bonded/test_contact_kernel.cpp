// The contact kernel's bookkeeping (src/bonded/contact_kernel.cpp): plane walls test only
// their candidate particles, contact history can be read and set by name, and the spatial sort
// reorders arrays in place as a copy would.
#include "fixtures.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <random>

using namespace hs;
using namespace hs::bonded;

TEST(PlaneWall, MovingWallFindsParticlesOutsideItsFirstCandidateList) {
  // A wall sweeps 15 skins towards a resting sphere (no gravity). The sphere never moves
  // before it is touched, so there is no neighbour rebuild after the first: only the wall's
  // own candidate refresh (every half skin it travels) can bring the sphere into its list.
  // At every step the wall must push exactly when the geometry overlaps (without the refresh
  // it never pushes: the first check fails at the step of first overlap).
  test::Ice ice;
  EngineDef d = test::no_field_def(ice);
  d.contact.mu = 0.3;
  d.contact.zeta_n = d.contact.zeta_t = 0.3;
  Engine e(d);
  e.add_particle(test::sphere_at(ice, Vec3(1.0, 0.0, 0.0)));
  e.add_wall({"pusher", Vec3(0, 0, 0), Vec3::UnitX(), Vec3(5.0, 0, 0), 0.3});
  int touching_steps = 0, mismatches = 0;
  std::uint64_t rebuilds_at_first_touch = 0;
  e.on_step = [&](const Engine& en) {
    const auto& p = en.particles();
    const PlaneWall& w = en.walls()[0];
    const bool overlap = (p.x[0] - w.point).dot(w.normal) < p.radius[0];
    const bool pushed = en.wall_force(0).squaredNorm() > 0.0;
    if (overlap && touching_steps == 0) rebuilds_at_first_touch = en.stats().neighbor_rebuilds;
    touching_steps += overlap;
    mismatches += overlap != pushed;
  };
  e.run(4000);
  std::printf("moving wall: %d steps in contact, %d mismatches, %llu neighbour rebuilds, v = %.3f m/s\n",
              touching_steps, mismatches, (unsigned long long)e.stats().neighbor_rebuilds, e.particles().v[0].x());
  EXPECT_EQ(rebuilds_at_first_touch, 1u);  // (the wall alone brought the sphere in)
  EXPECT_GT(touching_steps, 10);
  EXPECT_EQ(mismatches, 0);
  EXPECT_GT(e.particles().v[0].x(), 5.0);  // knocked away faster than the wall moves
}

namespace {

// A frictional pile of 4 x 4 x 3 spheres dropped on a floor, settled for a while.
Engine pile(const test::Ice& ice) {
  EngineDef d = test::no_field_def(ice);
  d.gravity = Vec3(0, 0, -9.81);
  d.contact.mu = 0.5;
  d.contact.zeta_n = d.contact.zeta_t = 0.3;
  Engine e(d);
  for (int k = 0; k < 3; ++k)
    for (int j = 0; j < 4; ++j)
      for (int i = 0; i < 4; ++i)
        e.add_particle(test::sphere_at(ice, Vec3(0.51 * i + 0.02 * k, 0.51 * j + 0.01 * k, 0.26 + 0.5 * k)));
  e.add_wall({"floor", Vec3(0, 0, 0), Vec3::UnitZ(), Vec3(0, 0, 0), 0.5});
  return e;
}

// A copy of `a` made from its state and, if asked, its springs read by name.
Engine copy_of(const Engine& a, const test::Ice& ice, bool springs) {
  Engine b(a.def());
  b.add_wall(a.walls()[0]);
  const auto& p = a.particles();
  std::vector<std::uint32_t> by_gid(p.owned());
  for (std::size_t i = 0; i < p.owned(); ++i) by_gid[p.gid[i]] = static_cast<std::uint32_t>(i);
  for (std::size_t g = 0; g < by_gid.size(); ++g) {
    const std::uint32_t i = by_gid[g];
    auto s = test::sphere_at(ice, p.x[i]);
    s.v = p.v[i];
    s.omega = p.omega[i];
    s.q = p.q[i];
    b.add_particle(s);
    if (springs) b.set_wall_history(0, g, a.wall_history(0, i));
  }
  if (springs) b.set_contact_history(a.contact_history());
  return b;
}

double max_gap(const Engine& a, const Engine& b) {
  double m = 0;
  for (std::size_t i = 0; i < a.particles().owned(); ++i) {
    const std::uint32_t j = b.particles().local(a.particles().gid[i]);
    m = std::max(m, (a.particles().x[i] - b.particles().x[j]).norm());
  }
  return m;
}

}  // namespace

TEST(ContactHistory, ReadAndSetByNameTheRunContinues) {
  // The springs of a settling frictional pile, read by pair ids (and per wall and particle)
  // and set into a fresh engine with the same state, continue the run: after 1000 more steps
  // the copy follows the original to round-off (its pair list is built anew, in another
  // order). A copy without the springs drifts far more.
  test::Ice ice;
  Engine a = pile(ice);
  a.run(4000);
  const auto hist = a.contact_history();
  ASSERT_GT(hist.size(), 20u);
  for (const auto& h : hist) EXPECT_LT(h.a, h.b);
  Engine with = copy_of(a, ice, true), without = copy_of(a, ice, false);
  EXPECT_EQ(with.contact_history().size(), hist.size());  // pending ones are listed too
  a.run(1000);
  with.run(1000);
  without.run(1000);
  const double g_with = max_gap(a, with), g_without = max_gap(a, without);
  std::printf("springs by name: %zu pairs; after 1000 steps the copy is %.3e m off (%.3e m without springs)\n",
              hist.size(), g_with, g_without);
  // Measured 6.2e-15 m with the springs, 1.2e-7 m without (GCC 12 -O3 -march=native).
  EXPECT_LT(g_with, 1e-13);
  EXPECT_GT(g_without, 1e-9);
}

TEST(PermuteInPlace, MatchesACopyForRandomAndNearIdentityOrders) {
  // permute_in_place (particle_store.h; the spatial sort's reorder) against the copy it replaced,
  // new[k] = old[order[k]], with elements past order.size() (ghosts) left where they are: a random
  // permutation (long cycles) and a near-identity one (a few swaps and a 3-cycle, as after a
  // rebuild where few particles changed cells).
  std::mt19937 rng(7);
  for (int trial = 0; trial < 2; ++trial) {
    const std::size_t n = 1000, ghosts = 5;
    std::vector<std::uint32_t> order(n);
    for (std::uint32_t k = 0; k < n; ++k) order[k] = k;
    if (trial == 0) {
      std::shuffle(order.begin(), order.end(), rng);
    } else {
      std::swap(order[3], order[500]);
      std::swap(order[10], order[11]);
      const std::uint32_t a = order[20];  // 20 <- 21 <- 22 <- 20
      order[20] = order[21];
      order[21] = order[22];
      order[22] = a;
    }
    std::vector<Vec3> a(n + ghosts);
    for (std::size_t k = 0; k < a.size(); ++k) a[k] = Vec3(double(k), -double(k), 0.5 * double(k));
    std::vector<Vec3> expect(a);
    for (std::size_t k = 0; k < n; ++k) expect[k] = a[order[k]];
    std::vector<char> done;
    permute_in_place(a, order, done);
    int wrong = 0;
    for (std::size_t k = 0; k < a.size(); ++k) wrong += a[k] != expect[k];
    EXPECT_EQ(wrong, 0) << (trial == 0 ? "random" : "near-identity") << " order";
  }
}
