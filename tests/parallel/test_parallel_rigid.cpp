// The decomposition's geometry and balance, and the replicated rigid world under MPI: every rank
// steps its own copy; impulses found on different ranks are summed and applied identically.
#include "bridge/block_contact.h"
#include "bridge/coupling.h"
#include "bonded/engine.h"
#include "common/ice_formulas.h"
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
  EXPECT_LT(vs_serial, 2e-14);  // m; measured 1.8e-15 (2 and 3 ranks)
  EXPECT_GT((dist.position(ids[0]) - Vec3(0, 0, 0)).norm(), 0.01) << "the impulses must move the blocks";
}


TEST(ParallelRigid, BlockContactOnRanksMatchesSerialWithHistoryTravellingAcrossCuts) {
  // 12 x 4 spheres rolling down the top face of an immovable block tilted 0.1 rad (static
  // friction, so the tangential springs carry 2/7 m g sin 0.1 all the time), the engine spread over
  // the ranks along x: spheres cross the cuts, and their springs must travel with them. Each
  // rank's BlockContact sees only the particles it owns; the shares, summed over the ranks
  // (ImpulseCoupler), are the serial load and move a replicated rigid block identically.
  const par::Comm& comm = test_world();
  const double D = 0.5, rho = 920.0, E = 1e9, g = 9.81, tilt = 0.1;
  const double kn = eq1_contact_stiffness(E, D), m = rho * kPi * D * D * D / 6.0;
  bonded::EngineDef d;
  d.gravity = Vec3(0, 0, -g);
  d.youngs_modulus = E;
  d.density = rho;
  d.contact.kn = d.contact.kt = kn;
  d.contact.zeta_n = d.contact.zeta_t = bonded::damping_ratio_from_restitution(0.3);
  d.contact.mu = 0.3;
  const Quat ori(Eigen::AngleAxisd(tilt, Vec3::UnitY()));  // the face descends towards +x
  const Mat3 R = ori.toRotationMatrix();
  const Vec3 centre(0.0, 0.0, -0.5), he(6.0, 2.0, 0.5);
  auto build = [&](bonded::Engine& e, bridge::BlockContact& bc) {
    bridge::ContactBlock b;
    b.id = 5;
    b.half_extents = he;
    b.position = centre;
    b.orientation = ori;
    b.friction = 0.3;
    bc.add_block(b);
    e.add_force_source(&bc);
    const Vec3 n = R.col(2);
    for (int iy = 0; iy < 4; ++iy)
      for (int ix = 0; ix < 12; ++ix) {
        bonded::ParticleInit p;
        const Vec3 local(-3.5 + 0.51 * ix, -0.75 + 0.51 * iy, he.z() + 0.5 * D - m * g * std::cos(tilt) / kn);
        p.x = centre + R * local;
        p.v = R * Vec3(3.0, 0.0, 0.0);
        p.omega = n.cross(p.v) / (0.5 * D);  // rolling
        p.radius = 0.5 * D;
        p.mass = m;
        e.add_particle(p);
      }
  };
  bonded::Engine serial(d), dist(d);
  bridge::BlockContact bs, bd;
  build(serial, bs);
  build(dist, bd);
  dist.distribute(comm);
  for (int s = 0; s < 2000; ++s) {
    serial.step();
    dist.step();
  }
  // Trajectories: every owned particle against its serial twin.
  double dx = 0.0;
  const auto& pd = dist.particles();
  const auto& ps = serial.particles();
  for (std::size_t i = 0; i < pd.owned(); ++i)
    dx = std::max(dx, (pd.x[i] - ps.x[ps.local(pd.gid[i])]).norm());
  dx = comm.max(dx);
  const double migrated = comm.sum(static_cast<double>(dist.parallel_stats().migrated));
  // Loads: the ranks' shares summed.
  const bridge::BlockLoad& ls = bs.load(0);
  const bridge::BlockLoad& ld = bd.load(0);
  double v[13] = {ld.force.x(), ld.force.y(), ld.force.z(), ld.torque.x(), ld.torque.y(), ld.torque.z(),
                  ld.impulse.x(), ld.impulse.y(), ld.impulse.z(), ld.angular_impulse.x(),
                  ld.angular_impulse.y(), ld.angular_impulse.z(), static_cast<double>(ld.contacts)};
  const double mine = v[12];
  comm.sum(v, 13);
  const Vec3 F(v[0], v[1], v[2]), T(v[3], v[4], v[5]), J(v[6], v[7], v[8]), H(v[9], v[10], v[11]);
  const double eF = (F - ls.force).norm() / ls.force.norm(), eT = (T - ls.torque).norm() / ls.torque.norm();
  const double eJ = (J - ls.impulse).norm() / ls.impulse.norm();
  const double eH = (H - ls.angular_impulse).norm() / ls.angular_impulse.norm();
  // The impulses into a replicated rigid block (free, no water, no gravity) through the coupler.
  rigid::RigidWorldDef wd;
  wd.water = false;
  wd.gravity = Vec3::Zero();
  rigid::BlockDef blk;
  blk.half_extents = he;
  blk.position = centre;
  blk.orientation = ori;
  rigid::RigidWorld wdist(wd), wser(wd);
  const rigid::BlockId idd = wdist.add_block(blk), ids = wser.add_block(blk);
  bridge::ImpulseCoupler cd, cs;
  cd.reset({idd});
  cs.reset({ids});
  cd.add_about_centre(0, ld.impulse, ld.angular_impulse);
  cs.add_about_centre(0, ls.impulse, ls.angular_impulse);
  cd.sum_and_apply(comm, wdist);
  cs.sum_and_apply(par::serial(), wser);
  wdist.substep();
  wser.substep();
  const Vec3 vd = wdist.velocity(idd), wdv = wdist.angular_velocity(idd);
  double spread = 0.0;
  for (int a = 0; a < 3; ++a)
    spread = std::max({spread, comm.max(vd[a]) + comm.max(-vd[a]), comm.max(wdv[a]) + comm.max(-wdv[a])});
  const double ev = (vd - wser.velocity(ids)).norm() / wser.velocity(ids).norm();
  const double ew = (wdv - wser.angular_velocity(ids)).norm() / wser.angular_velocity(ids).norm();
  if (comm.rank() == 0)
    std::printf("block contact over %d ranks, 2000 steps, %.0f migrations (%.0f of %.0f contacts on rank 0): "
                "max |x - x_serial| %.1e m; summed shares vs serial, relative: force %.1e, torque %.1e, impulse "
                "%.1e, angular impulse %.1e; rigid block after the coupler: velocity %.1e, angular velocity "
                "%.1e, spread over ranks %.1e\n",
                comm.size(), migrated, mine, v[12], dx, eF, eT, eJ, eH, ev, ew, spread);
  if (comm.size() > 1) {
    EXPECT_GT(migrated, 0.0) << "the test must move particles across a cut";
  }
  // Measured (2; 3 ranks): dx 0; force 5.2e-16, 3.9e-16; torque 1.7e-16, 1.8e-16; impulse
  // 1.3e-15, 2.2e-15; angular impulse 5.0e-15, 3.1e-15; velocity 1.3e-15, 2.1e-15; angular
  // velocity 4.6e-15, 2.8e-15 (relative).
  EXPECT_LT(dx, 1e-15);
  EXPECT_EQ(static_cast<std::size_t>(v[12]), ls.contacts);
  EXPECT_EQ(ls.contacts, 48u);
  EXPECT_LT(eF, 5e-14);
  EXPECT_LT(eT, 5e-14);
  EXPECT_LT(eJ, 5e-14);
  EXPECT_LT(eH, 5e-14);
  EXPECT_LT(ev, 5e-14);
  EXPECT_LT(ew, 5e-14);
  EXPECT_EQ(spread, 0.0) << "the replicated copies must be bit-identical";
}

}  // namespace
}  // namespace hs
