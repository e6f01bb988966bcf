// Block -> particle converter: conservation of mass, volume, momenta; free flight, floating
// at rest and overlap with existing particles (docs/bridge.md).
#include "bridge/converter.h"
#include "converter_fixtures.h"
#include "common/error.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

using namespace hs;
using namespace hs::bonded;
using hs::bridge::BlockState;
using hs::bridge::ConversionReport;
using hs::bridge::IceMaterial;

using namespace hs::test::converter;

// 1. Free flight: exact momenta, small KE change, COM on its straight line for 1 s.
TEST(Converter, FreeFlightConservesMomentaAndKeepsTheCentreOfMassOnItsLine) {
  Material mat;
  Engine e(free_flight_def(mat));
  const FreeFlightConversion c = convert_free_flight(e, mat);
  const ConversionReport& r = c.r;
  const auto& p = e.particles();
  ASSERT_EQ(r.particles_created, p.size());
  EXPECT_EQ(r.particles_dropped, 0u);
  // Every lattice-neighbour pair (centres D apart) is bonded, and nothing else.
  std::size_t touching = 0;
  for (std::size_t i = 0; i < p.size(); ++i)
    for (std::size_t j = i + 1; j < p.size(); ++j) touching += (p.x[i] - p.x[j]).norm() < mat.D * (1 + 1e-6);
  EXPECT_EQ(r.bonds_created, touching);
  EXPECT_EQ(e.bonds().size(), touching);

  // Mass and displaced volume are the block's.
  EXPECT_NEAR(c.msum, c.M, 1e-12 * c.M);
  EXPECT_NEAR(c.vsum, c.V, 1e-12 * c.V);
  EXPECT_LT(r.lattice_shift.norm(), mat.D);
  EXPECT_LT(r.com_shift.norm(), 1e-12);

  // Momenta measured by the engine against the block's (independent of the report).
  std::printf("[free flight] %zu particles, %zu bonds, D = %.3f m; |dP|/P = %.2e, |dL|/L = %.2e (about the "
              "centre %.2e); KE %.6f -> %.6f J (%+.4f %%), rotational part %.6f J\n",
              r.particles_created, r.bonds_created, mat.D, c.dP, c.dL, c.dLc, c.ke0, c.ke1,
              100.0 * (c.ke1 / c.ke0 - 1.0), c.ke_rot0);
  EXPECT_LT(c.dP, 1e-12);
  EXPECT_LT(c.dL, 1e-10);
  EXPECT_LT(c.dLc, 1e-10);
  // Report against engine: measured 0 (before) and 1.1e-15 x KE (after) -> 1e-14 (10x).
  EXPECT_NEAR(r.kinetic_energy_before, c.ke0, 1e-14 * c.ke0);
  EXPECT_NEAR(r.kinetic_energy_after, c.ke1, 1e-14 * c.ke0);
  EXPECT_LT(std::abs(c.ke1 / c.ke0 - 1.0), 0.01);
  EXPECT_LT((r.linear_momentum_after - r.linear_momentum_before).norm(), 1e-12 * c.P0.norm());
  EXPECT_LT((r.angular_momentum_after - r.angular_momentum_before).norm(), 1e-10 * c.L0.norm());

  // 1 s of free flight, gravity off: the centre of mass moves on x0 + v t.
  const FreeFlightRun f = fly(e, c);
  std::printf("[free flight] after %.3f s (%llu steps): COM off its line by %.2e m, |dL|/L = %.2e, bonds intact %lld\n",
              f.t, static_cast<unsigned long long>(f.steps), f.path_err, f.dL_run, static_cast<long long>(f.bonds));
  EXPECT_GE(f.t, 1.0);
  EXPECT_LT(f.path_err, 1e-6);
  EXPECT_LT(f.dL_run, 3e-14);  // measured 2.9e-15 after 4171 steps
  EXPECT_EQ(f.bonds, static_cast<std::int64_t>(r.bonds_created));
}

// 2. A block floating at rest, converted: its draft stays within 2 % of the freeboard and the
//    particles come to rest. The thickness is a whole number of HCP layers, so the lattice's
//    buoyancy column is as tall as the block (docs/bridge.md, "Floating").
TEST(Converter, FloatingBlockKeepsItsDraftAndComesToRest) {
  Material mat;
  Engine e(floating_def(mat));
  const FloatingRun f = float_block(e, mat);
  EXPECT_GT(f.r.sites_trimmed, 0u) << "the test must exercise layer balancing";
  std::printf("[floating] %zu particles (%zu sites trimmed), %d layers, h = %.4f m, freeboard %.4f m; COM z %.6f -> %.6f m after %.3f s: "
              "draft change %.2e m = %.3f %% of the freeboard; max speed %.2e m/s\n",
              f.r.particles_created, f.r.sites_trimmed, kFloatingLayers, f.h, f.freeboard, f.z0, f.z1, f.t,
              f.z0 - f.z1, 100.0 * (f.z0 - f.z1) / f.freeboard, f.vmax);
  // Measured: draft change -0.081 % of the freeboard, largest speed 4.86e-4 m/s after 1 s, with
  // critical heave damping on the bottom face (converter_fixtures.h); the per-particle drag
  // before the water was one for blocks and particles gave -0.109 % and 2.44e-4 m/s.
  EXPECT_LT(std::abs(f.z1 - f.z0), 0.02 * f.freeboard);
  EXPECT_LT(f.vmax, 1e-3);
}

// 3. Conversion next to existing particles injects no energy.
TEST(Converter, ConversionNextToExistingParticlesInjectsNoEnergy) {
  Material mat;
  Engine e(engine_def(mat, 0.1, 0.5));
  // A wall of loose spheres centred on the block's +x face: they reach D/2 into the block.
  BlockState b;
  b.half_extents = Vec3(0.75, 0.75, 0.5);
  b.velocity = Vec3(0.2, 0.02, 0.0);
  b.angular_velocity = Vec3(0.0, 0.0, 0.05);
  b.density = kRhoI;
  const double m_sphere = kRhoI * kPi * std::pow(mat.D, 3) / 6.0;
  for (int iy = -3; iy <= 3; ++iy)
    for (int iz = -2; iz <= 2; ++iz) {
      ParticleInit pi;
      pi.x = Vec3(0.75, iy * mat.D, iz * mat.D);
      pi.radius = 0.5 * mat.D;
      pi.mass = m_sphere;
      pi.buoyant_volume = kPi * std::pow(mat.D, 3) / 6.0;
      e.add_particle(pi);
    }
  const std::size_t n_old = e.particles().size();
  const auto before_block = e.energy();
  IceMaterial im;
  im.diameter = mat.D;
  const ConversionReport r = bridge::convert_block(e, b, im);
  // The contact energy the dropped sites would have stored: a bound on what dropping prevents.
  double would_inject = 0;
  {
    const auto lattice = hcp_fill_box(b.half_extents, b.pose, mat.D);
    for (const auto& x : lattice)
      for (std::size_t j = 0; j < n_old; ++j) {
        const double overlap = mat.D - ((x + r.lattice_shift) - e.particles().x[j]).norm();
        if (overlap > 0) would_inject += 0.5 * mat.kn() * overlap * overlap;
      }
  }
  e.compute_forces();  // builds the contact pairs, so energy() sees any overlap
  const auto en0 = e.energy();
  const double E0 = en0.total();
  // Momentum of the new particles is the block's.
  const Vec3 P_new = e.linear_momentum();
  EXPECT_LT((P_new - r.linear_momentum_before).norm(), 1e-12 * r.linear_momentum_before.norm());
  e.check_time_step();
  double E_max = E0;
  std::size_t contact_steps = 0;
  e.on_step = [&](const Engine& en) {
    E_max = std::max(E_max, en.energy().total());
    const auto& ps = en.particles();
    for (const auto& c : en.contact_pairs())  // block particle against an existing sphere
      contact_steps += (ps.gid[c.i] < n_old) != (ps.gid[c.j] < n_old) && (ps.x[c.j] - ps.x[c.i]).norm() < mat.D;
  };
  e.run(static_cast<std::uint64_t>(std::ceil(0.5 / e.dt())));
  e.on_step = nullptr;
  const double E1 = e.energy().total();
  const double tol = 1e-6 * (r.kinetic_energy_after + before_block.total());
  std::printf("[overlap] %zu existing spheres; %zu sites dropped, %zu particles made (mass renormalised, COM shift "
              "%.4f m); contact energy at conversion %.3e J (undropped sites would have stored %.3e J); total energy "
              "%.6e J -> max %.6e J, end %.6e J over %.2f s (%zu contact-steps)\n",
              n_old, r.particles_dropped, r.particles_created, r.com_shift.norm(), en0.contact_elastic, would_inject,
              E0, E_max, E1, e.time(), contact_steps);
  EXPECT_GT(r.particles_dropped, 0u) << "the test must exercise dropping";
  EXPECT_GT(would_inject, 100.0 * r.kinetic_energy_after) << "the dropped sites must matter";
  EXPECT_EQ(en0.contact_elastic, 0.0);
  EXPECT_NEAR(E0, before_block.total() + r.kinetic_energy_after, 1e-9 * E0);
  EXPECT_GT(contact_steps, 0u) << "the block must touch the spheres during the run";
  EXPECT_LE(E_max, E0 + tol);
  EXPECT_LE(E1, E0 + tol);
}

TEST(Converter, SameInputsGiveSameIdsAndState) {
  Material mat;
  auto build = [&](Engine& e) {
    ParticleInit pi;
    pi.x = Vec3(5, 5, 5); pi.radius = 0.5 * mat.D; pi.mass = 1.0;
    e.add_particle(pi);
    BlockState b;
    b.half_extents = Vec3(0.6, 0.5, 0.4);
    b.pose.orientation = Quat(Eigen::AngleAxisd(0.7, Vec3(0, 1, 1).normalized()));
    b.velocity = Vec3(1, 0, 0);
    b.angular_velocity = Vec3(0, 0.3, 0);
    b.mass = 800.0;
    IceMaterial im;
    im.diameter = mat.D;
    return bridge::convert_block(e, b, im);
  };
  Engine a(engine_def(mat, 0.0, 1.0)), c(engine_def(mat, 0.0, 1.0));
  const auto ra = build(a), rc = build(c);
  EXPECT_EQ(ra.first_gid, 1u);
  ASSERT_EQ(a.particles().size(), c.particles().size());
  for (std::size_t i = 0; i < a.particles().size(); ++i) {
    EXPECT_EQ(a.particles().gid[i], c.particles().gid[i]);
    EXPECT_EQ(a.particles().x[i], c.particles().x[i]);
    EXPECT_EQ(a.particles().v[i], c.particles().v[i]);
  }
  EXPECT_EQ(ra.bonds_created, rc.bonds_created);
  EXPECT_NEAR(ra.mass, 800.0, 0.0);
}

// lattice_sites and lattice_fits (the lattice stage's batch plans with them before converting,
// HybridSystem::plan_lattice_batch): the sites are those convert_block inserts when nothing
// overlaps, bit for bit, and lattice_fits says false exactly where convert_block refuses the shape.
TEST(Converter, LatticeSitesAreTheSitesTheConversionMakes) {
  Material mat;
  Engine e(free_flight_def(mat));
  BlockState b = free_flight_block();
  b.pose.orientation.coeffs() *= 3.0;  // not normalised: both normalise alike
  const std::vector<Vec3> sites = bridge::lattice_sites(b, mat.D);
  const ConversionReport r = bridge::convert_block(e, b, ice_material(mat));
  ASSERT_EQ(r.particles_dropped, 0u);
  ASSERT_EQ(r.sites.size(), sites.size());
  for (std::size_t k = 0; k < sites.size(); ++k) EXPECT_EQ(r.sites[k], sites[k]) << "site " << k;
  EXPECT_TRUE(bridge::lattice_fits(b.half_extents, mat.D));
  for (const Vec3& he : {Vec3(1.0, 0.75, 0.12), Vec3(0.124, 1.0, 1.0), Vec3(1.0, 1.0, -0.5)}) {
    Engine f(free_flight_def(mat));
    BlockState t = b;
    t.half_extents = he;
    EXPECT_FALSE(bridge::lattice_fits(he, mat.D)) << he.transpose();
    EXPECT_THROW(bridge::convert_block(f, t, ice_material(mat)), InputError) << he.transpose();
  }
}

// IceMaterial::world_lattice (blocks.lattice = "world", all_at_start's reference keel): blocks
// converted on one lattice fixed in the world fill their union as that lattice would. Two boxes,
// turned differently about z, one resting on the other: every point of the world lattice inside
// either box becomes exactly one particle, the particles across the shared face touch at one
// spacing and none overlaps. (Their own face-aligned lattices, the default, meet with gaps where
// the second block's face sites were dropped for overlapping the first's.)
TEST(Converter, WorldLatticeBlocksFillTheirUnionLikeOneLattice) {
  Material mat;
  BlockState a, b;
  a.half_extents = Vec3(1.0, 0.75, 0.3);
  a.pose.position = Vec3(0.02, -0.03, -0.3);
  a.pose.orientation = Quat(Eigen::AngleAxisd(0.17, Vec3::UnitZ()));
  b.half_extents = Vec3(0.8, 0.9, 0.3);
  b.pose.position = Vec3(0.1, 0.05, 0.3);  // its bottom face on a's top face, z = 0
  b.pose.orientation = Quat(Eigen::AngleAxisd(-0.44, Vec3::UnitZ()));
  a.density = b.density = kRhoI;
  struct Result {
    std::size_t particles = 0, dropped_b = 0, union_points = 0, missing = 0, across_touching = 0;
    std::size_t most_neighbours = 0, with_12 = 0;  // neighbours at one spacing, over all particles
    double min_across = 1e30, min_all = 1e30, mass = 0.0;
  };
  auto convert_pair = [&](bool world) {
    IceMaterial im = ice_material(mat);
    im.world_lattice = world;
    Engine e(free_flight_def(mat));
    const ConversionReport ra = bridge::convert_block(e, a, im);
    const ConversionReport rb = bridge::convert_block(e, b, im);
    Result out;
    out.particles = e.particles().size();
    out.dropped_b = rb.particles_dropped;
    const auto& x = e.particles().x;
    for (std::size_t i = 0; i < x.size(); ++i) {
      out.mass += e.particles().mass[i];
      std::size_t nb = 0;
      for (std::size_t j = 0; j < x.size(); ++j)
        if (j != i) {
          const double d = (x[i] - x[j]).norm();
          out.min_all = std::min(out.min_all, d);
          nb += std::abs(d - mat.D) < 1e-9 * mat.D;
        }
      out.most_neighbours = std::max(out.most_neighbours, nb);
      out.with_12 += nb == 12;
    }
    for (const Vec3& p : ra.sites)
      for (const Vec3& q : rb.sites) {
        const double d = (p - q).norm();
        out.min_across = std::min(out.min_across, d);
        out.across_touching += std::abs(d - mat.D) < 1e-9 * mat.D;
      }
    // The world lattice's points inside a or b (the union, each point once), and how many of
    // them no particle sits on.
    IceMaterial w = ice_material(mat);
    w.world_lattice = true;
    std::vector<Vec3> pts = bridge::lattice_sites(a, w);
    for (const Vec3& q : bridge::lattice_sites(b, w)) {
      bool dup = false;
      for (const Vec3& p : pts) dup = dup || (p - q).norm() < 1e-9;
      if (!dup) pts.push_back(q);
    }
    out.union_points = pts.size();
    for (const Vec3& p : pts) {
      bool on = false;
      for (std::size_t i = 0; i < e.particles().size() && !on; ++i) on = (e.particles().x[i] - p).norm() < 1e-9;
      out.missing += !on;
    }
    return out;
  };
  const Result w = convert_pair(true), f = convert_pair(false);
  const double M = kRhoI * 8.0 * (a.half_extents.prod() + b.half_extents.prod());
  std::printf("[world lattice] world: %zu particles on the %zu lattice points of the union (%zu missing), %zu of the "
              "second block's sites dropped, closest pair across the face %.6f D, %zu pairs at one spacing; own "
              "lattices: %zu particles, %zu missing, %zu dropped, closest pair %.4f D, %zu pairs at one spacing; "
              "world lattice: closest pair overall %.6f D, at most %zu neighbours, %zu particles with 12\n",
              w.particles, w.union_points, w.missing, w.dropped_b, w.min_across / mat.D, w.across_touching, f.particles,
              f.missing, f.dropped_b, f.min_across / mat.D, f.across_touching, w.min_all / mat.D, w.most_neighbours,
              w.with_12);
  EXPECT_EQ(w.missing, 0u);
  EXPECT_EQ(w.particles, w.union_points);
  // And that lattice is close packed: no two particles closer than one spacing anywhere, at most
  // 12 neighbours at one spacing, 12 inside (measured: 1.000000 D, 12, 83 particles with 12).
  EXPECT_GT(w.min_all, mat.D * (1.0 - 1e-9));
  EXPECT_EQ(w.most_neighbours, 12u);
  EXPECT_GT(w.with_12, 20u);
  EXPECT_GT(w.min_across, mat.D * (1.0 - 1e-9));  // none overlaps
  EXPECT_GT(w.across_touching, 20u);              // the two meet over the face
  EXPECT_NEAR(w.mass, M, 1e-12 * M);              // M/n per block, as with its own lattice
  // Measured: 278 particles on 278 points, 45 dropped (b's sites on the shared face, a's already),
  // closest pair 1.000000 D, 145 pairs at one spacing. The default, printed for contrast: 270
  // particles, 42 of b's sites dropped (its bottom layer, where a's reaches past the face), the
  // closest pair 1.0164 D apart: the two lattices meet at a few points with gaps between.
  EXPECT_GT(f.min_across, mat.D * 1.001);
}

TEST(Converter, BadInputIsRefusedWithAClearMessage) {
  Material mat;
  Engine e(engine_def(mat, 0.0, 1.0));
  IceMaterial im;
  im.diameter = mat.D;
  // Each refusal names the field (err.path()) and says what is wrong or what to do.
  auto expect_error = [&](BlockState b, IceMaterial m, const char* what, const char* path, const char* says) {
    try {
      bridge::convert_block(e, b, m);
      ADD_FAILURE() << "accepted: " << what;
    } catch (const InputError& err) {
      std::printf("[bad input] %s -> %s\n", what, err.what());
      EXPECT_EQ(err.path(), path) << what;
      EXPECT_NE(std::string(err.what()).find(says), std::string::npos) << what << ": " << err.what();
    }
  };
  BlockState ok;
  ok.density = kRhoI;
  BlockState b = ok;
  b.half_extents = Vec3(1, -1, 1);
  expect_error(b, im, "negative half extent", "block/half_extents", "half extents must be positive and finite");
  b = ok;
  b.half_extents = Vec3(1, 1, 0.1);
  expect_error(b, im, "block thinner than a particle", "block/half_extents",
               "use a smaller particle diameter or keep the block rigid");
  b = ok;
  b.density = 0;
  expect_error(b, im, "no mass or density", "block", "give a positive mass (kg) or density (kg/m^3)");
  b = ok;
  b.mass = 5.0;
  expect_error(b, im, "mass and density disagree", "block", "disagree; give one of them");
  b = ok;
  b.pose.orientation = Quat(0, 0, 0, 0);
  expect_error(b, im, "zero quaternion", "block/orientation", "must be finite and non-zero");
  IceMaterial bad = im;
  bad.diameter = 0;
  expect_error(ok, bad, "zero diameter", "material/diameter", "particle diameter must be positive and finite");
  EXPECT_EQ(e.particles().size(), 0u) << "a refused conversion must not leave particles behind";
}
