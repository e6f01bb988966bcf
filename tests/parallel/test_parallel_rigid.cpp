// The decomposition's geometry and balance, and the replicated rigid world under MPI: every rank
// steps its own copy; impulses found on different ranks are summed and applied identically.
#include "bridge/coupling.h"
#include "parallel/comm.h"
#include "parallel/decomposition.h"
#include "rigid/rigid_world.h"

#include <gtest/gtest.h>

#include <cstdio>

namespace hs {
const par::Comm& test_world();  // mpi_main.cpp
namespace {

TEST(Decomposition, CutsSitAtEqualCostQuantilesAndEveryPointHasOneOwner) {
  par::Decomposition d({4, 1, 1});
  // Cost piled up at one end: bins 0..9 over x in [0, 10), weights 1, 1, ..., 1, 31 (total 40).
  std::array<std::vector<double>, 3> h;
  h[0].assign(10, 1.0);
  h[0][9] = 31.0;
  h[1].assign(10, 1.0);
  h[2].assign(10, 1.0);
  d.balance(h, Vec3(0, 0, 0), Vec3(10, 1, 1));
  // Quantiles 10, 20, 30: the first cut after 9 unit bins + 1/31 of the last; then 11/31, 21/31.
  EXPECT_NEAR(d.cuts(0)[1], 9.0 + 1.0 / 31.0, 1e-12);
  EXPECT_NEAR(d.cuts(0)[2], 9.0 + 11.0 / 31.0, 1e-12);
  EXPECT_NEAR(d.cuts(0)[3], 9.0 + 21.0 / 31.0, 1e-12);
  // Every point belongs to exactly the box rank_of names.
  for (double x : {-1e9, 0.0, 5.0, 9.2, 9.5, 9.99, 1e9}) {
    const Vec3 p(x, 0.3, -7.0);
    int owners = 0;
    for (int r = 0; r < d.size(); ++r) owners += d.box(r).contains(p);
    EXPECT_EQ(owners, 1) << x;
    EXPECT_TRUE(d.box(d.rank_of(p)).contains(p));
  }
  // Least cut area: a 24 m x 10 m x 0.6 m sheet is cut across its long side; 8 ranks make a 2-D grid.
  EXPECT_EQ(par::Decomposition::choose_dims(2, Vec3(24, 10, 0.6)), (std::array<int, 3>{2, 1, 1}));
  EXPECT_EQ(par::Decomposition::choose_dims(2, Vec3(10, 24, 0.6)), (std::array<int, 3>{1, 2, 1}));
  EXPECT_EQ(par::Decomposition::choose_dims(8, Vec3(100, 100, 1)), (std::array<int, 3>{4, 2, 1}));
}

TEST(ParallelRigid, ReplicatedWorldsStayBitIdenticalWithImpulsesSummedOverRanks) {
  const par::Comm& comm = test_world();
  auto make = [](rigid::RigidWorld& w, std::vector<rigid::BlockId>& ids) {
    for (int k = 0; k < 6; ++k) {
      rigid::BlockDef b;
      b.half_extents = Vec3(1.0 + 0.2 * k, 0.8, 0.3);
      b.position = Vec3(3.0 * k, 0.1 * k, -0.02 * k);
      b.orientation = Quat(Eigen::AngleAxisd(0.1 * k, Vec3::UnitY()));
      ids.push_back(w.add_block(b));
    }
  };
  rigid::RigidWorld dist, serial;
  std::vector<rigid::BlockId> ids, ids_s;
  make(dist, ids);
  make(serial, ids_s);
  bridge::ImpulseCoupler cd, cs;
  cd.reset(ids);
  cs.reset(ids_s);
  const int n = comm.size(), me = comm.rank();
  for (int step = 0; step < 120; ++step) {
    // "Particle" impulses on each block: the total is fixed; rank r finds the share (r+1)/sum.
    const double share = (me + 1.0) / (0.5 * n * (n + 1.0));
    for (std::size_t k = 0; k < ids.size(); ++k) {
      const Vec3 j(50.0 * std::sin(0.1 * step + k), 30.0 * std::cos(0.07 * step), 20.0 * (k % 2 ? 1 : -1));
      const Vec3 p = dist.position(ids[k]) + Vec3(0.5, -0.3, 0.2);
      cd.add(k, share * j, p, dist.position(ids[k]));
      cs.add(k, j, serial.position(ids_s[k]) + Vec3(0.5, -0.3, 0.2), serial.position(ids_s[k]));
    }
    cd.sum_and_apply(comm, dist);
    cs.sum_and_apply(par::serial(), serial);
    dist.step(dist.def().dt);
    serial.step(serial.def().dt);
  }
  double spread = 0.0, vs_serial = 0.0;
  for (std::size_t k = 0; k < ids.size(); ++k) {
    const Vec3 x = dist.position(ids[k]);
    for (int a = 0; a < 3; ++a) spread = std::max(spread, comm.max(x[a]) + comm.max(-x[a]));
    vs_serial = std::max(vs_serial, (x - serial.position(ids_s[k])).cwiseAbs().maxCoeff());
  }
  vs_serial = comm.max(vs_serial);
  if (comm.rank() == 0)
    std::printf("replicated rigid world (%d ranks): spread of block positions over ranks %.3e m, "
                "vs one world given the total impulses %.3e m, after 120 steps\n",
                n, spread, vs_serial);
  EXPECT_EQ(spread, 0.0) << "the replicated copies must be bit-identical";
  EXPECT_LT(vs_serial, 1e-9);
  EXPECT_GT((dist.position(ids[0]) - Vec3(0, 0, 0)).norm(), 0.01) << "the impulses must move the blocks";
}

}  // namespace
}  // namespace hs
