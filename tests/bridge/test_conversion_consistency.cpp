// Conversion consistency (issue 6): a block dropped onto the cone gives the structure the same
// impulse whether it stays rigid, is particles from the start, or converts on contact; a block
// converted inside a settled pile injects < 1 % of m g h; a beam loaded in three-point bending
// converts under load and breaks at the load an all-particle beam breaks at, within 10 %.
#include "bridge/hybrid.h"
#include "hybrid_fixtures.h"
#include "common/error.h"
#include "mesh/pier.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

using namespace hs;
using namespace hs::bonded;
using hs::bridge::BlockInit;
using hs::bridge::ConversionMode;
using hs::bridge::HybridDef;
using hs::bridge::HybridSystem;

namespace {

using namespace hs::test::hybrid;

struct DropResult {
  Vec3 impulse = Vec3::Zero();  // on the structure, N s
  std::uint64_t conversions = 0;
  double first_conversion_time = -1.0;
};

// A 1.2 x 0.8 x 0.4 m block released 5 cm above the 52 deg cone's slope, its bottom face parallel
// to the slope, at rest; 0.6 s of falling, impact and sliding. Impulse = sum of the structure
// force (particles' mesh-wall load + blocks' kinematic-mesh load) x dt.
DropResult drop_on_cone(ConversionMode mode) {
  Engine e(ice_def(0.05));
  add_spectator(e);
  HybridDef d = dry_hybrid(mode);
  const int wall = add_cone(e, d);
  e.set_dt(ice_dt());
  const BlockInit b = block_above_cone();
  HybridSystem h(e, d, {b});
  DropResult out;
  const auto n_steps = static_cast<std::uint64_t>(std::llround(0.6 / e.dt()));
  for (std::uint64_t k = 0; k < n_steps; ++k) {
    h.step();
    out.impulse += (e.mesh_wall_load(wall).force + h.structure_force()) * e.dt();
    if (out.first_conversion_time < 0 && h.report().conversions > 0) out.first_conversion_time = e.time();
  }
  out.conversions = h.report().conversions;
  return out;
}

}  // namespace

TEST(ConversionConsistency, BlockDroppedOnConeGivesTheSameImpulse) {
  const DropResult rigid = drop_on_cone(ConversionMode::Never);
  const DropResult start = drop_on_cone(ConversionMode::AllAtStart);
  const DropResult contact = drop_on_cone(ConversionMode::Hybrid);
  EXPECT_EQ(rigid.conversions, 0u);
  EXPECT_EQ(start.conversions, 1u);
  EXPECT_EQ(contact.conversions, 1u);
  EXPECT_GT(contact.first_conversion_time, 0.0);
  const double ref = rigid.impulse.norm();
  ASSERT_GT(ref, 100.0) << "the block must have hit the cone";
  const double d_start = (start.impulse - rigid.impulse).norm() / ref;
  const double d_contact = (contact.impulse - rigid.impulse).norm() / ref;
  std::printf("[ consistency ] cone impulse (N s): rigid (%.1f, %.1f, %.1f), at start (%.1f, %.1f, %.1f), on "
              "contact at t = %.3f s (%.1f, %.1f, %.1f); differences %.2f %% and %.2f %% of |rigid|\n",
              rigid.impulse.x(), rigid.impulse.y(), rigid.impulse.z(), start.impulse.x(), start.impulse.y(),
              start.impulse.z(), contact.first_conversion_time, contact.impulse.x(), contact.impulse.y(),
              contact.impulse.z(), 100 * d_start, 100 * d_contact);
  EXPECT_LT(d_start, 0.10);
  EXPECT_LT(d_contact, 0.10);
}


TEST(ConversionConsistency, BlockConvertedInASettledPileInjectsLessThanOnePercentOfMgh) {
  // A fixed floor and three 1.0 x 0.6 x 0.4 m blocks stacked crosswise; settle 1.5 s as rigid
  // blocks, convert the middle one, follow 0.5 s. Injected energy = the largest rise of the
  // total energy (rigid KE + PE, particle energy, contact and bond elastic energy) above its
  // value just before the conversion; h = height of the block's centre above the floor.
  Engine e(ice_def(0.05));
  add_spectator(e);
  e.set_dt(ice_dt());
  HybridDef d = dry_hybrid(ConversionMode::Never);
  d.world.linear_drag = 0.0;
  const std::vector<BlockInit> blocks = pile_blocks();
  HybridSystem h(e, d, blocks);
  const auto steps = [&](double t) { return static_cast<std::uint64_t>(std::llround(t / e.dt())); };
  for (std::uint64_t k = 0, n = steps(1.5); k < n; ++k) h.step();
  const std::vector<rigid::BlockId> ids = h.world()->blocks();
  const rigid::BlockId middle = ids.at(2);
  const double m = h.world()->mass(middle), hgt = h.world()->position(middle).z();
  const double mgh = m * kG * hgt;
  const double ke_before = h.world()->kinetic_energy();
  const double E0 = total_energy(e, h);
  const auto rep = h.convert(middle);
  const double E_after = total_energy(e, h);
  double E_max = E_after;
  for (std::uint64_t k = 0, n = steps(0.5); k < n; ++k) {
    h.step();
    E_max = std::max(E_max, total_energy(e, h));
  }
  const double injected = E_max - E0;
  std::printf("[ consistency ] pile: rigid KE before %.3e J; middle block (%.1f kg, h = %.3f m, m g h = %.1f J) -> "
              "%zu particles (%zu sites dropped); energy jump at conversion %.3e J, largest rise in 0.5 s %.3e J = "
              "%.3f %% of m g h; energy at the end %.1f J below\n",
              ke_before, m, hgt, mgh, rep.particles_created, rep.particles_dropped, E_after - E0, injected,
              100.0 * injected / mgh, E0 - total_energy(e, h));
  EXPECT_LT(ke_before, 1e-3 * mgh) << "the pile must have settled";
  EXPECT_LT(injected, 0.01 * mgh);
}

TEST(ConversionConsistency, BlockLoadedInBendingBreaksAtTheParticleBlocksLoad) {
  // A: the full-particle reference (the beam converted before the first step).
  const BendResult a = bend(ConversionMode::AllAtStart, 0.5e6, 1.2);
  // B: hybrid. The rigid beam's flexural estimate reaches sigma_f = 0.4 MPa (0.8 sigma_c) at
  // about 40 % of A's break load: it converts while loaded, then breaks as particles.
  const BendResult b = bend(ConversionMode::Hybrid, 0.4e6, 1.2);
  // C: never converted. Run to A's break time: the rigid beam's load just grows.
  const BendResult c = bend(ConversionMode::Never, 0.4e6, a.break_time);
  const double diff = (b.peak - a.peak) / a.peak;
  const std::size_t beam_particles = a.particles - 13;  // less the pad's 12 and the spectator
  std::printf("[ consistency ] bending: all particles (%zu in the beam) break at %.1f N (t = %.4f s, %llu bonds broken at %.4f s); "
              "hybrid converts at t = %.4f s under %.1f N (%.1f %% of it, %llu sites dropped) and breaks at %.1f N "
              "(t = %.4f s): %+.3f %%; never: rigid beam at %.1f N at t = %.4f s, %llu bonds broken\n",
              beam_particles, a.peak, a.peak_time, (unsigned long long)a.bonds_broken, a.break_time, b.conversion_time,
              b.load_at_conversion, 100.0 * b.load_at_conversion / a.peak, (unsigned long long)b.sites_dropped,
              b.peak, b.peak_time, 100.0 * diff, c.final_load, a.break_time, (unsigned long long)c.bonds_broken);
  expect_bending_consistent(a, b, c);
}
