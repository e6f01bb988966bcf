// Block -> particle conversion under MPI (docs/parallel.md, "Conversion under MPI"): every rank
// converts the same block into a running, distributed engine and keeps its share. Each rank also
// converts it into a serial copy of the same system; the two are compared by global id: ids,
// positions, velocities and bonds right after the conversion, then positions 700-950 steps later.
// Run by ctest at 1, 2 and 3 ranks.
#include "mpi_fixtures.h"
#include "bridge/converter.h"
#include "common/error.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <utility>
#include <vector>

namespace hs::bonded {
namespace {

using test::world;

using test::compare_state;
using test::gathered_bonds;
using test::sorted_bonds;
using test::spread;
using test::StateDiff;

double rel(const Vec3& a, const Vec3& b) { return (a - b).norm() / b.norm(); }

/// How far the block's particle centres reach from its centre along the unit vector u: the
/// block converted alone into an empty engine, max over the sites of u . (x - c).
double reach(const bridge::BlockState& b, const bridge::IceMaterial& im, const EngineDef& d, const Vec3& u) {
  Engine e(d);
  bridge::convert_block(e, b, im);
  double r = -INFINITY;
  for (std::size_t i = 0; i < e.particles().size(); ++i) r = std::max(r, u.dot(e.particles().x[i] - b.pose.position));
  return r;
}

TEST(ParallelConversion, BlocksConvertedAcrossCutsMatchSerial) {
  // A bonded slab 6 m x 2 m spans the cuts (grid P x 1 x 1) and vibrates. At step 50 a 4 m block
  // above it, falling onto it, is converted; at step 300 a second block beside it, moving into
  // it. Both blocks straddle the cuts, so each rank inserts part of each and some new bonds join
  // particles on different ranks.
  test::Ice ice;
  EngineDef d = test::ice_def(INFINITY);
  double slab_top = -INFINITY, slab_side = -INFINITY;
  auto build = [&](Engine& e) {
    for (const auto& c : hcp_fill_box(Vec3(3.0, 1.0, 0.41), Pose{}, ice.D)) {
      auto p = test::sphere_at(ice, c, true);
      p.v = Vec3(0.0, 0.05 * std::cos(c.x()), 0.2 * std::sin(kPi * c.x() / 6.0));
      p.omega = Vec3(0.3 * c.x(), 0.0, 0.0);
      e.add_particle(p);
      slab_top = std::max(slab_top, c.z());
      slab_side = std::max(slab_side, c.y());
    }
    e.bond_touching(0, e.particles().size(), BondKind::Lattice);
  };
  ParallelDef pd;
  pd.grid = {world().size(), 1, 1};
  test::EnginePair p = test::make_pair_of(d, build, pd);
  bridge::IceMaterial im;
  im.diameter = ice.D;

  // Each block starts 1 cm clear of the slab (its particles' reach measured by a trial
  // conversion) and closes the gap within ~100 steps (dt = 1.5e-5 s).
  bridge::BlockState falling;
  falling.half_extents = Vec3(2.0, 0.75, 0.5);
  falling.pose.orientation = Quat(Eigen::AngleAxisd(0.05, Vec3(0.3, 1.0, 0.2).normalized()));
  falling.velocity = Vec3(0.1, -0.05, -3.0);
  falling.angular_velocity = Vec3(0.2, -0.3, 0.4);
  falling.density = ice.rho;
  falling.pose.position = Vec3(0.1, 0.2, slab_top + ice.D + 0.01 + reach(falling, im, d, -Vec3::UnitZ()));
  bridge::BlockState sliding;
  sliding.half_extents = Vec3(1.75, 0.5, 0.5);
  sliding.pose.orientation = Quat(Eigen::AngleAxisd(-0.1, Vec3::UnitZ()));
  sliding.velocity = Vec3(0.0, -2.5, 0.05);
  sliding.angular_velocity = Vec3(0.0, 0.1, -0.5);
  sliding.density = ice.rho;
  sliding.pose.position = Vec3(-0.2, slab_side + ice.D + 0.01 + reach(sliding, im, d, -Vec3::UnitY()), 0.0);

  const std::int64_t bonds0 = p.dist->global_bond_count();
  double worst_x = 0.0;
  std::int64_t bonds_made = 0;
  int block = 0;
  GlobalId first_new = 0;
  std::size_t contact_steps = 0;  // (converted particle, slab particle) contacts, summed over steps
  p.serial->on_step = [&](const Engine& e) {
    const auto& s = e.particles();
    for (const auto& c : e.contact_pairs())
      contact_steps += (s.gid[c.i] < first_new) != (s.gid[c.j] < first_new) &&
                       (s.x[c.j] - s.x[c.i]).norm() < s.radius[c.i] + s.radius[c.j];
  };
  for (int k = 0; k < 1000; ++k) {
    if (k == 50 || k == 300) {
      const bridge::BlockState& b = k == 50 ? falling : sliding;
      const Vec3 P0 = p.dist->linear_momentum(), L0 = p.dist->angular_momentum();
      const bridge::ConversionReport rs = bridge::convert_block(*p.serial, b, im);
      const bridge::ConversionReport rd = bridge::convert_block(*p.dist, b, im);
      const GlobalId to = rd.first_gid + rd.particles_created;
      // (a) the same particles with the same ids, positions, velocities and bonds as serial.
      EXPECT_EQ(rd.first_gid, rs.first_gid);
      EXPECT_EQ(rd.particles_created, rs.particles_created);
      EXPECT_EQ(rd.particles_dropped, rs.particles_dropped);
      EXPECT_EQ(rd.bonds_created, rs.bonds_created);
      EXPECT_EQ(rd.first, world().size() > 1 ? bridge::ConversionReport::kNoIndex : rs.first);
      if (block == 0) first_new = rd.first_gid;
      const StateDiff fresh = compare_state(*p.dist, *p.serial, rd.first_gid, to);
      EXPECT_EQ(fresh.count, static_cast<std::int64_t>(rs.particles_created));
      EXPECT_EQ(fresh.x, 0.0);  // made from the same sites by the same arithmetic
      EXPECT_EQ(fresh.v, 0.0);
      EXPECT_EQ(fresh.w, 0.0);
      EXPECT_EQ(p.dist->global_particle_count(), static_cast<std::int64_t>(p.serial->particles().size()));
      bonds_made += static_cast<std::int64_t>(rd.bonds_created);
      EXPECT_EQ(p.dist->global_bond_count(), bonds0 + bonds_made) << "a bond was lost or doubled";
      const auto all = gathered_bonds(*p.dist);
      if (world().rank() == 0) {
        EXPECT_TRUE(all == sorted_bonds(*p.serial)) << "bond sets differ";
        EXPECT_TRUE(std::adjacent_find(all.begin(), all.end()) == all.end()) << "a bond is held twice";
      }
      // (b) the particles carry the block's momenta; the engine's totals grew by them.
      const double dP = rel(rd.linear_momentum_after, rd.linear_momentum_before);
      const double dL = rel(rd.angular_momentum_after, rd.angular_momentum_before);
      const double dP_engine = rel(p.dist->linear_momentum() - P0, rd.linear_momentum_before);
      const double dL_engine = rel(p.dist->angular_momentum() - L0, rd.angular_momentum_before);
      // Measured (2; 3 ranks, both blocks): |dP|/P <= 5.7e-17, |dL|/L <= 7.2e-16; engine totals
      // <= 2.3e-16, <= 3.5e-15.
      EXPECT_LT(dP, 1e-15);
      EXPECT_LT(dL, 1e-14);
      EXPECT_LT(dP_engine, 3e-15);
      EXPECT_LT(dL_engine, 4e-14);
      EXPECT_NEAR(rd.kinetic_energy_after, rs.kinetic_energy_after, 1e-12 * rs.kinetic_energy_after);
      const auto [ranks, across] = spread(*p.dist, rd.first_gid, to);
      if (world().size() > 1) {
        EXPECT_GE(ranks, 2) << "the block must straddle a cut";
        EXPECT_GT(across, 0) << "some new bonds must join particles on different ranks";
      }
      if (world().rank() == 0)
        std::printf("block %d at step %d (%d ranks): ids %llu..%llu (serial from %llu), %zu particles on %lld ranks, "
                    "%zu bonds (%lld across ranks), %zu sites dropped; |x|,|v|,|w| - serial = %.1e, %.1e, %.1e; "
                    "|dP|/P = %.2e, |dL|/L = %.2e (engine totals: %.2e, %.2e); KE %.4f -> %.4f J (%+.3f %%)\n",
                    ++block, k, world().size(), (unsigned long long)rd.first_gid, (unsigned long long)(to - 1),
                    (unsigned long long)rs.first_gid, rd.particles_created, (long long)ranks, rd.bonds_created,
                    (long long)across, rd.particles_dropped, fresh.x, fresh.v, fresh.w, dP, dL, dP_engine, dL_engine,
                    rd.kinetic_energy_before, rd.kinetic_energy_after,
                    100.0 * (rd.kinetic_energy_after / rd.kinetic_energy_before - 1.0));
    }
    p.serial->step();
    p.dist->step();
    if (k % 50 == 49) worst_x = std::max(worst_x, test::max_position_difference(*p.dist, *p.serial));
  }
  // (c) 950 steps after the first conversion (700 after the second), positions as serial.
  worst_x = std::max(worst_x, test::max_position_difference(*p.dist, *p.serial));
  const auto all = gathered_bonds(*p.dist);
  const std::int64_t bonds_end = p.dist->global_bond_count();  // (collective: not inside a rank-0 branch)
  if (world().rank() == 0)
    std::printf("after 1000 steps (%d ranks): max |x - x_serial| = %.3e m; %lld bonds (serial %zu); %zu block-slab "
                "contact-steps\n",
                world().size(), worst_x, (long long)bonds_end, p.serial->bonds().size(), contact_steps);
  EXPECT_LT(worst_x, 3e-14);  // m; measured 1.3e-15 (2 ranks), 2.3e-15 (3 ranks)
  EXPECT_EQ(bonds_end, bonds0 + bonds_made);
  if (world().rank() == 0) {
    EXPECT_TRUE(all == sorted_bonds(*p.serial));
  }
  EXPECT_GT(contact_steps, 0u) << "the blocks must hit the slab during the run";
}

TEST(ParallelConversion, OverlapDropsTheSameSitesAsSerial) {
  // A row of loose particles along x crosses every cut; a lattice, then a block, placed over it:
  // the sites it overlaps are found by the ranks that own the row's particles (at least two of
  // them), and every rank drops exactly the sites the serial copy drops.
  test::Ice ice;
  EngineDef d = test::ice_def(INFINITY);
  auto build = [&](Engine& e) {
    for (int k = -5; k <= 5; ++k) e.add_particle(test::sphere_at(ice, Vec3(0.6 * k, 0.0, 0.0)));
  };
  ParallelDef pd;
  pd.grid = {world().size(), 1, 1};
  test::EnginePair p = test::make_pair_of(d, build, pd);
  p.serial->run(20);
  p.dist->run(20);

  // 1. The engine's own insertion: sites and bonds given, overlapping sites dropped.
  LatticeInsert lat;
  std::vector<Vec3> xs;
  for (const auto& c : hcp_fill_box(Vec3(3.2, 0.6, 0.45), Pose{Vec3(0.05, 0.1, 0.0), Quat::Identity()}, ice.D)) {
    auto s = test::sphere_at(ice, c, true);
    s.v = Vec3(0.0, 0.0, 0.1);
    lat.sites.push_back(s);
    xs.push_back(c);
  }
  lat.bonds = touching_pairs(xs, std::vector<double>(xs.size(), 0.5 * ice.D));
  const LatticeInsertReport rs = p.serial->insert_lattice(lat);
  // Which sites this rank's own particles overlap (before the insertion, as the engine tests).
  std::int64_t hits_here = 0;
  {
    const auto& ps = p.dist->particles();
    for (const Vec3& x : xs)
      for (std::size_t j = 0; j < ps.owned(); ++j)
        if ((ps.x[j] - x).norm() < ps.radius[j] + 0.5 * ice.D) {
          ++hits_here;
          break;
        }
  }
  const std::int64_t ranks_hit = world().sum(static_cast<std::int64_t>(hits_here > 0));
  const LatticeInsertReport rd = p.dist->insert_lattice(lat);
  EXPECT_GT(rs.particles_dropped, 0u);
  EXPECT_EQ(rd.gid, rs.gid) << "a different site kept, dropped or numbered";
  EXPECT_EQ(rd.first_gid, rs.first_gid);
  EXPECT_EQ(rd.particles_dropped, rs.particles_dropped);
  EXPECT_EQ(rd.bonds_created, rs.bonds_created);
  EXPECT_EQ(p.dist->global_bond_count(), static_cast<std::int64_t>(p.serial->bonds().size()));
  const StateDiff made = compare_state(*p.dist, *p.serial, rd.first_gid, rd.first_gid + rd.particles_created);
  EXPECT_EQ(made.count, static_cast<std::int64_t>(rs.particles_created));
  EXPECT_EQ(made.x, 0.0);
  EXPECT_EQ(made.v, 0.0);
  if (world().size() > 1) {
    EXPECT_GE(ranks_hit, 2) << "the dropped sites must be found on two ranks";
  }
  if (world().rank() == 0)
    std::printf("lattice over the row (%d ranks): %zu sites, %zu dropped (found by %lld ranks), %zu kept as ids "
                "%llu.., %zu bonds; kept set and ids equal to serial: %s\n",
                world().size(), lat.sites.size(), rd.particles_dropped, (long long)ranks_hit, rd.particles_created,
                (unsigned long long)rd.first_gid, rd.bonds_created, rd.gid == rs.gid ? "yes" : "NO");

  // 2. A block converted over the middle of the row (and the lattice just made).
  bridge::BlockState b;
  b.half_extents = Vec3(1.5, 0.75, 0.5);
  b.pose.position = Vec3(0.1, -0.45, 0.3);
  b.velocity = Vec3(0.3, 0.0, 0.0);
  b.angular_velocity = Vec3(0.0, 0.0, 0.2);
  b.density = ice.rho;
  bridge::IceMaterial im;
  im.diameter = ice.D;
  std::int64_t block_hits_here = 0;  // its sites (a trial conversion alone) this rank's particles overlap
  {
    Engine trial(d);
    bridge::convert_block(trial, b, im);
    const auto& ps = p.dist->particles();
    for (std::size_t i = 0; i < trial.particles().size(); ++i)
      for (std::size_t j = 0; j < ps.owned(); ++j)
        if ((ps.x[j] - trial.particles().x[i]).norm() < ps.radius[j] + 0.5 * ice.D) {
          ++block_hits_here;
          break;
        }
  }
  const std::int64_t block_ranks_hit = world().sum(static_cast<std::int64_t>(block_hits_here > 0));
  const bridge::ConversionReport cs = bridge::convert_block(*p.serial, b, im);
  const bridge::ConversionReport cd = bridge::convert_block(*p.dist, b, im);
  const StateDiff diff = compare_state(*p.dist, *p.serial, cd.first_gid, cd.first_gid + cd.particles_created);
  EXPECT_GT(cs.particles_dropped, 0u);
  EXPECT_EQ(cd.particles_dropped, cs.particles_dropped);
  if (world().size() > 1) {
    EXPECT_GE(block_ranks_hit, 2) << "the block's dropped sites must be found on two ranks";
  }
  EXPECT_EQ(cd.particles_created, cs.particles_created);
  EXPECT_EQ(cd.first_gid, cs.first_gid);
  EXPECT_EQ(diff.count, static_cast<std::int64_t>(cs.particles_created));
  EXPECT_EQ(diff.x, 0.0);
  EXPECT_EQ(diff.v, 0.0);
  EXPECT_LT(rel(cd.linear_momentum_after, cd.linear_momentum_before), 1e-12);
  EXPECT_LT(rel(cd.angular_momentum_after, cd.angular_momentum_before), 1e-10);
  const auto all = gathered_bonds(*p.dist);
  if (world().rank() == 0) {
    EXPECT_TRUE(all == sorted_bonds(*p.serial));
  }
  // No new contact starts compressed: the first force evaluation finds no overlap anywhere.
  p.serial->compute_forces();
  p.dist->compute_forces();
  const double contact_energy = p.dist->energy().contact_elastic;
  double worst = 0.0;
  for (int k = 0; k < 200; ++k) {
    p.serial->step();
    p.dist->step();
  }
  worst = test::max_position_difference(*p.dist, *p.serial);
  if (world().rank() == 0)
    std::printf("block over the row (%d ranks): %zu sites dropped (serial %zu; found by %lld ranks), %zu particles, "
                "ids %llu..; contact energy after conversion %.1e J; after 200 steps max |x - x_serial| = %.3e m\n",
                world().size(), cd.particles_dropped, cs.particles_dropped, (long long)block_ranks_hit,
                cd.particles_created,
                (unsigned long long)cd.first_gid, contact_energy, worst);
  EXPECT_EQ(contact_energy, 0.0);
  EXPECT_LT(worst, 1e-15);  // m; measured 0 (2 and 3 ranks)
}

TEST(ParallelConversion, RefusedInputLeavesEveryRankUnchanged) {
  // Bad input is refused on every rank alike (none is left waiting in a collective), and
  // nothing is added anywhere.
  test::Ice ice;
  EngineDef d = test::ice_def(INFINITY);
  auto build = [&](Engine& e) {
    for (int k = -3; k <= 3; ++k) e.add_particle(test::sphere_at(ice, Vec3(0.6 * k, 0.0, 0.0)));
  };
  ParallelDef pd;
  pd.grid = {world().size(), 1, 1};
  test::EnginePair p = test::make_pair_of(d, build, pd);
  const std::int64_t n0 = p.dist->global_particle_count();
  LatticeInsert lat;
  lat.sites.push_back(test::sphere_at(ice, Vec3(0, 2, 0)));
  lat.sites.push_back(test::sphere_at(ice, Vec3(0.5, 2, 0)));
  lat.bonds = {{0, 1}, {1, 0}};
  EXPECT_THROW(p.dist->insert_lattice(lat), std::invalid_argument);
  lat.bonds = {{0, 2}};
  EXPECT_THROW(p.dist->insert_lattice(lat), std::invalid_argument);
  bridge::BlockState b;
  b.pose.position = Vec3(0.0, 0.0, 0.0);  // every site on the row
  b.half_extents = Vec3(0.25, 0.25, 0.25);
  b.density = ice.rho;
  bridge::IceMaterial im;
  im.diameter = ice.D;
  EXPECT_THROW(bridge::convert_block(*p.dist, b, im), InputError);
  EXPECT_EQ(p.dist->global_particle_count(), n0);
  p.dist->run(10);  // the ranks are still in step
  EXPECT_EQ(p.dist->global_particle_count(), n0);
}

}  // namespace
}  // namespace hs::bonded
