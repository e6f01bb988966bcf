// Block-particle freeze bonds under MPI (docs/bridge.md, "MPI rule"): the replicated bond list,
// evaluated by each particle's owner, impulses summed over ranks, breaks synchronised at the
// rigid step, while the particles migrate across the cuts. Compared with the same system on
// one rank (par::serial()) inside the same mpirun.
#include "bridge/block_bonds.h"
#include "bonded/hcp_lattice.h"
#include "common/ice_formulas.h"
#include "parallel/comm.h"

#include <gtest/gtest.h>

#include <cstdio>

namespace hs {
const par::Comm& test_world();  // test_parallel_engine.cpp
namespace {

using namespace hs::bonded;
using hs::bridge::BlockBody;
using hs::bridge::BlockParticleBonds;

TEST(ParallelBlockBonds, OwnerEvaluatesImpulsesSumAndBreaksAgreeWithOneRank) {
  const par::Comm& comm = test_world();
  constexpr double D = 0.25, r = 0.5 * D, E = 1e7, rho = 920.0;
  const double k = eq1_contact_stiffness(E, D), m = rho * hcp_cell_volume(D), I = 0.4 * m * r * r;
  EngineDef d;
  d.gravity = Vec3::Zero();
  d.youngs_modulus = E;
  d.density = rho;
  d.contact.kn = d.contact.kt = k;
  d.bond[1] = ParallelBondParams::from_stiffness(k, k, 0.5 * r, 20e3, 20e3, 0.0, 0.5 * m, 0.5 * I);
  // A long block sliding along x at 1 m/s drags 45 frozen particles across the ranks' cuts; the
  // faster-bouncing ones break loose.
  BlockBody b0;
  b0.half_extents = Vec3(4.0, 1.0, 0.5);
  b0.velocity = Vec3(1.0, 0.0, 0.0);
  auto build = [&](Engine& e, BlockParticleBonds& src) {
    for (int n = 0; n < 45; ++n) {
      ParticleInit p;
      p.x = Vec3((n % 15) * 2 * D - 3.5, (n / 15) * 2 * D - 0.5, 0.5 + r);
      p.v = Vec3(1.0, 0.0, 0.03 * (n % 7));
      p.radius = r;
      p.mass = m;
      e.add_particle(p);
    }
    src.set_block(0, b0);
    EXPECT_EQ(src.bond_touching(e.particles(), 0), 45u);
    e.add_force_source(&src);
  };
  Engine es(d), ed(d);
  BlockParticleBonds ss, sd;
  build(es, ss);
  build(ed, sd);
  ParallelDef pd;
  pd.balance_interval = 300;
  ed.distribute(comm, pd);
  const int K = 5;  // rigid step
  Vec3 Js = Vec3::Zero(), Jd = Vec3::Zero(), Hs = Vec3::Zero(), Hd = Vec3::Zero();
  std::vector<Vec3> lin, ang;
  const std::uint64_t steps = static_cast<std::uint64_t>(std::ceil(1.0 / es.dt()));
  for (std::uint64_t n = 1; n <= steps; ++n) {
    BlockBody b = b0;
    b.position = b0.position + b0.velocity * (static_cast<double>(n) * es.dt());
    ss.set_block(0, b);
    sd.set_block(0, b);
    es.step();
    ed.step();
    if (n % K != 0) continue;
    ss.take_impulses(lin, ang);
    ss.sync_broken(par::serial());
    Js += lin[0];
    Hs += ang[0];
    sd.take_impulses(lin, ang);
    comm.sum(lin[0].data(), 3);
    comm.sum(ang[0].data(), 3);
    sd.sync_broken(comm);
    Jd += lin[0];
    Hd += ang[0];
  }
  // Positions by global id against the one-rank run.
  double dx = 0.0;
  const auto& a = ed.particles();
  for (std::size_t i = 0; i < a.owned(); ++i)
    dx = std::max(dx, (a.x[i] - es.particles().x[es.particles().local(a.gid[i])]).cwiseAbs().maxCoeff());
  dx = comm.max(dx);
  const double dJ = (Jd - Js).norm() / Js.norm(), dH = (Hd - Hs).norm() / Hs.norm();
  const std::int64_t broken = comm.sum(static_cast<std::int64_t>(sd.stats().broken));
  const std::int64_t migrated = comm.sum(static_cast<std::int64_t>(ed.parallel_stats().migrated));
  if (comm.rank() == 0)
    std::printf("block-particle bonds (%d ranks): %llu steps, %lld migrations; intact %zu (one rank %zu), "
                "broken %lld (one rank %llu); impulse vs one rank %.1e, moment %.1e; max |dx| %.1e m\n",
                comm.size(), static_cast<unsigned long long>(steps), static_cast<long long>(migrated), sd.size(),
                ss.size(), static_cast<long long>(broken), static_cast<unsigned long long>(ss.stats().broken), dJ,
                dH, dx);
  EXPECT_GT(ss.stats().broken, 5u);
  EXPECT_LT(ss.size(), 40u);
  EXPECT_EQ(sd.size(), ss.size());
  EXPECT_EQ(broken, static_cast<std::int64_t>(ss.stats().broken));
  // Measured (2; 3 ranks): impulse 2.3e-15, 2.6e-15; moment 9.9e-16, 3.1e-15; dx 0.
  EXPECT_LT(dJ, 3e-14);
  EXPECT_LT(dH, 3e-14);
  EXPECT_LT(dx, 1e-15);
  if (comm.size() > 1) {
    EXPECT_GT(migrated, 0);
  }
}

}  // namespace
}  // namespace hs
