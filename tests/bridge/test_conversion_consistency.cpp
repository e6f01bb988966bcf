// Conversion consistency (issue 6): a block dropped onto the cone gives the structure the same
// impulse whether it stays rigid, is particles from the start, or converts on contact (at two
// cone frictions); a block converted inside a settled pile injects < 1 % of m g h (with and
// without sites dropped); a beam loaded in three-point bending converts under load and breaks at
// the load an all-particle beam breaks at, within 0.6 %.
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
DropResult drop_on_cone(ConversionMode mode, double friction = 0.1) {
  Engine e(ice_def(0.05));
  add_spectator(e);
  HybridDef d = dry_hybrid(mode);
  const int wall = add_cone(e, d, friction);
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

// The impulse of drop_on_cone() split along the cone's outward normal n (the normal impulse,
// < 0: the ice pushes the cone inwards), along the slope t (downhill, in the xz plane: the
// friction the sliding block drags the cone with) and across it (y).
struct ConeImpulse {
  Vec3 J;
  double normal, slope, lateral;
};
ConeImpulse split(const Vec3& J) {
  const double ang = mesh::PierParams{}.cone_angle_deg * kPi / 180.0;
  const Vec3 n(std::sin(ang), 0.0, std::cos(ang)), t(std::cos(ang), 0.0, -std::sin(ang));
  return {J, J.dot(n), J.dot(t), J.y()};
}

TEST(ConversionConsistency, BlockDroppedOnConeGivesTheSameImpulse) {
  // Two cone frictions (mesh wall and structure alike; 0.1 and 0.3 < tan 52 deg: the block
  // slides down the slope throughout). The impulse is dominated by the normal part (weight x
  // cos 52 deg x time); friction is in the along-slope part, which Coulomb sliding makes
  // exactly mu x |normal impulse|, and which moves the impulse vector by 10 % of |J| from
  // friction 0 to 0.1 and by 19 % from 0.1 to 0.3 (measured, rigid): twice the 5 % limit on
  // the vector below, so a mode that lost its friction fails it.
  const ConversionMode modes[3] = {ConversionMode::Never, ConversionMode::AllAtStart, ConversionMode::Hybrid};
  const char* names[3] = {"rigid", "at start", "on contact"};
  // Measured |J_mode - J_rigid| / |J_rigid|: friction 0.1: 2.87 %, 2.97 %; 0.3: 3.4 %, 2.9 %
  // (mostly the particle block's sideways impulse, -27 to -38 N s, where the symmetric rigid
  // block gives 0: the HCP lattice is not mirror-symmetric in y). Limit 5 %.
  // Measured slope / (mu |normal|): rigid 1.0000 (to 5e-6), particles 1.016-1.022. Limits
  // 1e-4 and 5 %.
  Vec3 J01[3];
  for (const double mu : {0.1, 0.3}) {
    ConeImpulse c[3];
    for (int m = 0; m < 3; ++m) {
      const DropResult r = drop_on_cone(modes[m], mu);
      c[m] = split(r.impulse);
      if (mu == 0.1) J01[m] = r.impulse;
      EXPECT_EQ(r.conversions, m == 0 ? 0u : 1u) << names[m];
      if (m == 2) {
        EXPECT_GT(r.first_conversion_time, 0.0);
      }
      std::printf("[ consistency ] cone friction %.1f, %s: impulse (%.1f, %.1f, %.1f) N s: normal %.2f, along the "
                  "slope %.2f (= %.6f mu |normal|), across %.2f; %.2f %% of |rigid| from rigid%s\n",
                  mu, names[m], c[m].J.x(), c[m].J.y(), c[m].J.z(), c[m].normal, c[m].slope,
                  c[m].slope / (mu * std::abs(c[m].normal)), c[m].lateral,
                  100.0 * (c[m].J - c[0].J).norm() / c[0].J.norm(),
                  m == 2 ? (" (converted at t = " + std::to_string(r.first_conversion_time) + " s)").c_str() : "");
    }
    ASSERT_LT(c[0].normal, -100.0) << "the block must have hit the cone";
    EXPECT_NEAR(c[0].slope / (mu * std::abs(c[0].normal)), 1.0, 1e-4);
    for (int m = 1; m < 3; ++m) {
      EXPECT_LT((c[m].J - c[0].J).norm() / c[0].J.norm(), 0.05) << names[m] << ", friction " << mu;
      EXPECT_NEAR(c[m].slope / (mu * std::abs(c[m].normal)), 1.0, 0.05) << names[m] << ", friction " << mu;
    }
  }
  // The control: friction changes the impulse by more than the limit (measured 9.95 % of |J|
  // from 0 to 0.1).
  const ConeImpulse none = split(drop_on_cone(ConversionMode::Never, 0.0).impulse);
  std::printf("[ consistency ] cone friction 0, rigid: along the slope %.3e N s; friction 0.1 moves the impulse by "
              "%.2f %% of |J|\n", none.slope, 100.0 * (J01[0] - none.J).norm() / J01[0].norm());
  EXPECT_NEAR(none.slope, 0.0, 1e-9 * std::abs(none.normal));
  EXPECT_GT((J01[0] - none.J).norm() / J01[0].norm(), 1.5 * 0.05);
}


// A fixed floor and three 1.0 x 0.6 x 0.4 m blocks stacked crosswise (pile_blocks()); with
// `post`, a fourth block (0.6 x 0.4 x 1.0 m) stands on the floor 2 mm from the middle block's
// +y end face. Settle 1.5 s as rigid blocks, convert the middle one, follow 0.5 s. Injected
// energy = the largest rise of the total energy (rigid KE + PE, particle energy, contact and bond
// elastic energy) above its value just before the conversion; h = height of the block's centre
// above the floor. With the post, the lattice sites within D/2 of it (the row at the middle
// block's +y end, 5 cm from its face) are dropped: the converter's overlap path.
struct PileInjection {
  double mgh = 0.0, ke_before = 0.0, jump = 0.0, injected = 0.0;
  double centroid_rise = 0.0, mass = 0.0;  // of the new particles' centre above the block's, m; kg
  std::size_t created = 0, dropped = 0;
};

PileInjection convert_in_pile(bool post) {
  Engine e(ice_def(0.05));
  add_spectator(e);
  e.set_dt(ice_dt());
  HybridDef d = dry_hybrid(ConversionMode::Never);
  d.world.linear_drag = 0.0;
  std::vector<BlockInit> blocks = pile_blocks();
  if (post) {
    BlockInit p;
    p.def.half_extents = Vec3(0.3, 0.2, 0.5);
    p.def.position = Vec3(0.04, 0.5 + 0.002 + 0.2, 0.501);
    p.def.density = kRhoI;
    blocks.push_back(p);
  }
  HybridSystem h(e, d, blocks);
  const auto steps = [&](double t) { return static_cast<std::uint64_t>(std::llround(t / e.dt())); };
  for (std::uint64_t k = 0, n = steps(1.5); k < n; ++k) h.step();
  const std::vector<rigid::BlockId> ids = h.world()->blocks();
  const rigid::BlockId middle = ids.at(2);
  PileInjection out;
  const double m = h.world()->mass(middle), hgt = h.world()->position(middle).z();
  out.mgh = m * kG * hgt;
  out.ke_before = h.world()->kinetic_energy();
  const double E0 = total_energy(e, h);
  const auto rep = h.convert(middle);
  const double E_after = total_energy(e, h);
  double zc = 0.0;
  for (std::size_t i = rep.first; i < rep.first + rep.particles_created; ++i) zc += e.particles().x[i].z();
  out.centroid_rise = zc / static_cast<double>(rep.particles_created) - hgt;
  out.mass = m;
  double E_max = E_after;
  for (std::uint64_t k = 0, n = steps(0.5); k < n; ++k) {
    h.step();
    E_max = std::max(E_max, total_energy(e, h));
  }
  out.jump = E_after - E0;
  out.injected = E_max - E0;
  out.created = rep.particles_created;
  out.dropped = rep.particles_dropped;
  std::printf("[ consistency ] pile%s: rigid KE before %.3e J; middle block (%.1f kg, h = %.3f m, m g h = %.1f J) -> "
              "%zu particles (%zu sites dropped, their centre %.3e m above the block's: M g dz = %.4e J); energy jump at "
              "conversion %.4e J, largest rise in 0.5 s %.4e J = %.2e of m g h; energy at the end %.1f J below\n",
              post ? " with a post" : "", out.ke_before, m, hgt, out.mgh, out.created, out.dropped, out.centroid_rise,
              m * kG * out.centroid_rise, out.jump, out.injected, out.injected / out.mgh, E0 - total_energy(e, h));
  return out;
}

TEST(ConversionConsistency, BlockConvertedInASettledPileInjectsLessThanOnePercentOfMgh) {
  const PileInjection a = convert_in_pile(false), b = convert_in_pile(true);
  EXPECT_LT(a.ke_before, 1e-3 * a.mgh) << "the pile must have settled";
  EXPECT_LT(b.ke_before, 1e-3 * b.mgh) << "the pile must have settled";
  EXPECT_EQ(a.dropped, 0u);
  EXPECT_GT(b.dropped, 0u) << "the post must make the converter drop sites";
  EXPECT_EQ(b.created + b.dropped, a.created);
  // Without drops the lattice's centre is the block's and nothing is injected: measured
  // 1.8e-9 J (1.4e-12 of m g h), limit 2e-8 J.
  EXPECT_LT(a.injected, 2e-8);
  // With drops the converter keeps the block's mass on fewer sites and does not re-centre
  // them: 3 sites dropped, 2 from one layer and 1 from the other, lift the centre of mass by
  // 3.0 mm, and that potential energy is the whole jump (measured 6.550 J = 5.0e-3 of m g h;
  // nothing more in the 0.5 s after). The jump against M g dz: measured 8.1e-9 J, limit 1e-7 J;
  // the rise after it 1.5e-11 J, limit 2e-10 J.
  EXPECT_NEAR(b.jump, b.mass * kG * b.centroid_rise, 1e-7);
  EXPECT_LT(b.injected - b.jump, 2e-10);
  EXPECT_LT(b.injected, 1e-2 * b.mgh);
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
