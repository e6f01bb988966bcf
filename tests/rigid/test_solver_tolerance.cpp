// The early exit of the block solver (RigidWorldDef::solver_tolerance, docs/rigid.md "Solver
// iterations and their early exit"): a solve stops once no row changes its velocity by more than
// the tolerance in an iteration. Jointed floating blocks at the keel scene's rigid step and
// iteration cap, with the tolerance against every iteration: the same motion to well below a
// millimetre, in a small fraction of the iterations.
#include "common/error.h"
#include "rigid/rigid_world.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <limits>
#include <string>
#include <vector>

namespace hs::rigid {
namespace {

constexpr double kRhoI = 910.0;
constexpr double kDt = 9.592e-4;  // s: the keel cone scene's rigid step (its run summary)
constexpr int kCap = 120;       // the keel scenes' blocks.solver_iterations

RigidWorldDef world_def(double tolerance) {
  RigidWorldDef d;
  d.dt = kDt;
  d.solver_iterations = kCap;
  d.solver_tolerance = tolerance;
  d.fixed_friction_directions = true;
  d.freeze_bond_strength = 40e3;  // Pa
  return d;
}

// A 1 x 1 x 0.6 m floe at its flotation draft.
BlockDef floe(double x, double z_top = 0.6 * (1.0 - kRhoI / 1025.0)) {
  BlockDef b;
  b.half_extents = Vec3(0.5, 0.5, 0.3);
  b.density = kRhoI;
  b.position = Vec3(x, 0.0, z_top - 0.3);
  return b;
}

struct Pile {
  std::vector<BlockId> blocks;
  std::vector<JointId> joints;
};

// A raft of four floes jointed side by side, two floes resting on it jointed to the floes below:
// the raft sinks under their weight, heaves and comes to rest (the water's heave damping).
Pile jointed_pile(RigidWorld& w) {
  Pile p;
  for (int i = 0; i < 4; ++i) p.blocks.push_back(w.add_block(floe(1.0 * i)));
  const double top = floe(0).position.z() + 0.3;
  for (int i = 0; i < 2; ++i) p.blocks.push_back(w.add_block(floe(0.5 + 2.0 * i, top + 0.6)));
  for (int i = 0; i < 3; ++i)
    p.joints.push_back(w.add_freeze_joint({p.blocks[i], p.blocks[i + 1], Vec3(0.5 + i, 0, top - 0.3), Vec3::UnitX(), 0.3}));
  for (int i = 0; i < 2; ++i)
    p.joints.push_back(
        w.add_freeze_joint({p.blocks[2 * i], p.blocks[4 + i], Vec3(0.5 + 2.0 * i, 0, top), Vec3::UnitZ(), 0.3}));
  return p;
}

struct PileRun {
  std::vector<Vec3> x;  // every block at the end
  RigidWorld::SolverStats stats;
  std::size_t broken = 0;
};

// The pile for `seconds`; with `push`, a steady 2 kN along +x on the first top block after 1 s
// (below the joints' strength: 40 kPa x 0.3 m^2 = 12 kN), which slides the pile through the water.
PileRun run_pile(double tolerance, double seconds, bool push) {
  RigidWorld w(world_def(tolerance));
  const Pile p = jointed_pile(w);
  while (w.time() < seconds) {
    if (push && w.time() >= 1.0) {
      w.clear_external_forces();
      w.add_force(p.blocks[4], Vec3(2e3, 0, 0), w.position(p.blocks[4]));
    }
    w.substep();
  }
  PileRun r;
  for (const BlockId id : p.blocks) r.x.push_back(w.position(id));
  r.stats = w.solver_stats();
  r.broken = w.broken_joint_count();
  return r;
}

double largest_difference(const PileRun& a, const PileRun& b) {
  double worst = 0.0;
  for (std::size_t i = 0; i < a.x.size(); ++i) worst = std::max(worst, (a.x[i] - b.x[i]).norm());
  return worst;
}

TEST(SolverTolerance, ZeroTakesEveryIteration) {
  const PileRun r = run_pile(0.0, 0.1, false);
  EXPECT_EQ(r.stats.iterations, r.stats.solves * kCap);
  EXPECT_EQ(r.stats.max_iterations, kCap);
  EXPECT_EQ(r.stats.solves, 105u);  // one per sub-step: 0.1 s / 9.592e-4 s, rounded up
}

TEST(SolverTolerance, AJointedPileSettlesAsWithEveryIteration) {
  const PileRun full = run_pile(0.0, 4.0, false);
  const PileRun early = run_pile(1e-4, 4.0, false);
  const double d = largest_difference(full, early);
  std::printf("[ solver tolerance ] pile at rest: %.2f iterations per solve (most %d), largest difference %.2e m\n",
              early.stats.mean_iterations(), early.stats.max_iterations, d);
  EXPECT_EQ(full.broken, 0u);
  EXPECT_EQ(early.broken, 0u);
  EXPECT_LT(early.stats.mean_iterations(), kCap / 4.0);  // measured 12.6 (most 57)
  EXPECT_LT(d, 1e-5);                                     // m; measured 9.9e-7
}

TEST(SolverTolerance, APushedPileMovesAsWithEveryIteration) {
  const PileRun full = run_pile(0.0, 3.0, true);
  const PileRun early = run_pile(1e-4, 3.0, true);
  const double d = largest_difference(full, early);
  const double moved = (full.x[4] - run_pile(0.0, 1.0, false).x[4]).norm();
  std::printf("[ solver tolerance ] pushed pile: moved %.3f m, %.2f iterations per solve (most %d), largest difference %.2e m\n",
              moved, early.stats.mean_iterations(), early.stats.max_iterations, d);
  EXPECT_GT(moved, 0.1);  // the push moves the pile (measured 0.472 m)
  EXPECT_EQ(full.broken, 0u);
  EXPECT_EQ(early.broken, 0u);
  // Sliding friction converges slowly: more iterations than at rest, still fewer than the cap.
  EXPECT_LT(early.stats.mean_iterations(), 100.0);  // measured 83.2 (most 120)
  EXPECT_LT(d, 1.2e-5);                              // m; measured 1.16e-6
}

TEST(SolverTolerance, ANegativeOrNonFiniteToleranceIsRefused) {
  for (const double bad : {-1e-4, std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity()}) {
    try {
      RigidWorld w(world_def(bad));
      ADD_FAILURE() << bad << " accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("solver_tolerance"), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace hs::rigid
