// The hybrid system under MPI (run at 1, 2 and 3 ranks): a rigid block dropped onto a bonded
// particle slab that lies across the rank boundary, once staying rigid and once converting on
// contact. Every rank also runs a serial copy; the distributed run must match it: the same
// conversions, the block's rigid state, the particles by global id, the structure-free momentum.
#include "bridge/hybrid.h"
#include "bonded/hcp_lattice.h"
#include "mpi_fixtures.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

namespace hs::test {
namespace {

using bridge::BlockInit;
using bridge::ConversionMode;
using bridge::HybridDef;
using bridge::HybridSystem;

constexpr double kRhoI = 920.0, kD = 0.2, kE = 1e8, kG = 9.81;

bonded::EngineDef slab_def() {
  bonded::EngineDef d;
  d.gravity = Vec3(0, 0, -kG);
  d.youngs_modulus = kE;
  d.density = kRhoI;
  d.contact.kn = d.contact.kt = kPi * kE * kD / 12.0;
  d.contact.zeta_n = d.contact.zeta_t = bonded::damping_ratio_from_restitution(0.1);
  d.contact.mu = 0.3;
  const double m = kRhoI * bonded::hcp_cell_volume(kD), I = 0.4 * m * 0.25 * kD * kD;
  d.bond[0] = bonded::ParallelBondParams::from_stiffness(d.contact.kn, d.contact.kn, 0.5 * kD, INFINITY, INFINITY,
                                                         0.3, 0.5 * m, 0.5 * I);
  d.bond[1] = d.bond[0];
  d.dt = 0.1 * kD * std::sqrt(kRhoI / kE);
  return d;
}

// A 4 m x 2 m x 2-layer bonded slab centred on x = 0 (the 2-rank cut), resting on a fixed floor
// block, and a 1.0 x 0.6 x 0.4 m block tilted a little, 3 cm above the slab, straddling x = 0.
struct Setup {
  std::unique_ptr<bonded::Engine> engine;
  std::unique_ptr<HybridSystem> hyb;
};

Setup make(ConversionMode mode, bool distribute) {
  Setup s;
  s.engine = std::make_unique<bonded::Engine>(slab_def());
  bonded::Engine& e = *s.engine;
  const double c = bonded::hcp_layer_spacing(kD);
  const Vec3 half(2.0, 1.0, c);
  const bonded::Pose pose{Vec3(0, 0, half.z()), Quat::Identity()};
  for (const Vec3& x : bonded::hcp_fill_box(half, pose, kD)) {
    bonded::ParticleInit p;
    p.x = x;
    p.radius = 0.5 * kD;
    p.mass = kRhoI * bonded::hcp_cell_volume(kD);
    e.add_particle(p);
  }
  e.bond_touching(0, e.particles().size(), bonded::BondKind::Lattice);
  double z_bottom = INFINITY, z_top = -INFINITY;
  for (std::size_t i = 0; i < e.particles().size(); ++i) {
    z_bottom = std::min(z_bottom, e.particles().x[i].z() - 0.5 * kD);
    z_top = std::max(z_top, e.particles().x[i].z() + 0.5 * kD);
  }
  HybridDef d;
  d.mode = mode;
  d.world.water = false;
  d.world.friction = 0.3;
  d.ice.diameter = kD;
  d.block_density = kRhoI;
  d.block_friction = 0.3;
  d.stress_time_constant = 0.0;
  d.flexural_strength = 2e3;  // converts as soon as the slab pushes back
  d.region.shape = bridge::ConversionRegion::Shape::Box;
  d.region.half_extents = Vec3(10, 10, 10);
  std::vector<BlockInit> blocks(2);
  blocks[0].def.half_extents = Vec3(4, 3, 0.5);
  blocks[0].def.position = Vec3(0, 0, z_bottom - 0.5);
  blocks[0].def.fixed = true;
  blocks[1].def.half_extents = Vec3(0.5, 0.3, 0.2);
  blocks[1].def.position = Vec3(0.05, 0.1, z_top + 0.2 + 0.03);
  blocks[1].def.orientation = Quat(Eigen::AngleAxisd(0.05, Vec3(1, 1, 0).normalized()));
  blocks[1].def.velocity = Vec3(0.1, 0, -0.5);
  blocks[1].def.density = kRhoI;
  s.hyb = std::make_unique<HybridSystem>(e, d, blocks);
  if (distribute) {
    bonded::ParallelDef pd;
    pd.grid = {world().size(), 1, 1};
    e.distribute(world(), pd);
  }
  return s;
}

void compare(ConversionMode mode, const char* label) {
  Setup ser = make(mode, false), dis = make(mode, true);
  const std::uint64_t n = static_cast<std::uint64_t>(std::llround(0.3 / ser.engine->dt()));
  for (std::uint64_t k = 0; k < n; ++k) {
    ser.hyb->step();
    dis.hyb->step();
  }
  const auto& rs = ser.hyb->report();
  const auto& rd = dis.hyb->report();
  EXPECT_EQ(rs.conversions, rd.conversions);
  EXPECT_EQ(rs.particles_created, rd.particles_created);
  EXPECT_EQ(ser.engine->particles().size(), static_cast<std::size_t>(dis.engine->global_particle_count()));
  EXPECT_EQ(static_cast<std::int64_t>(ser.engine->bonds().size()), dis.engine->global_bond_count());
  const double dx = max_position_difference(*dis.engine, *ser.engine);
  double dblock = 0.0;
  const auto bs = ser.hyb->world()->blocks(), bd = dis.hyb->world()->blocks();
  EXPECT_EQ(bs.size(), bd.size());
  for (std::size_t k = 0; k < std::min(bs.size(), bd.size()); ++k)
    dblock = std::max(dblock, (ser.hyb->world()->position(bs[k]) - dis.hyb->world()->position(bd[k])).norm());
  const Vec3 Ps = ser.engine->linear_momentum(), Pd = dis.engine->linear_momentum();
  if (world().rank() == 0)
    std::printf("[ mpi hybrid ] %s, %d ranks: %llu conversions (%llu particles), max |x - x_serial| %.2e m over "
                "%zu particles, rigid blocks %.2e m, particle momentum (%.4f, %.4f, %.4f) vs serial (%.4f, %.4f, "
                "%.4f)\n",
                label, world().size(), static_cast<unsigned long long>(rd.conversions),
                static_cast<unsigned long long>(rd.particles_created), dx, ser.engine->particles().size(), dblock,
                Pd.x(), Pd.y(), Pd.z(), Ps.x(), Ps.y(), Ps.z());
  EXPECT_LT(dx, 1e-9);
  EXPECT_LT(dblock, 1e-9);
  EXPECT_LT((Pd - Ps).norm(), 1e-9 * std::max(1.0, Ps.norm()));
}

TEST(ParallelHybrid, RigidBlockOnASlabAcrossTheCutMatchesSerial) {
  compare(ConversionMode::Never, "block stays rigid");
}

TEST(ParallelHybrid, BlockConvertingOnContactMatchesSerial) {
  compare(ConversionMode::Hybrid, "block converts on contact");
}

}  // namespace
}  // namespace hs::test
