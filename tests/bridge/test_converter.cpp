// Block -> particle converter: conservation of mass, volume, momenta; free flight, floating
// at rest and overlap with existing particles (docs/bridge.md).
#include "bridge/converter.h"
#include "common/error.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

using namespace hs;
using namespace hs::bonded;
using hs::bridge::BlockState;
using hs::bridge::ConversionReport;
using hs::bridge::IceMaterial;

namespace {

constexpr double kRhoI = 920.0, kRhoW = 1025.0, kG = 9.81;

struct Material {
  double D = 0.25;
  double E = 1e7;  // modest E: dt = 0.1 D sqrt(rho/E) ~ 7.6e-5 s, runs in seconds
  double kn() const { return kPi * E * D / 12.0; }
  double cell_mass() const { return kRhoI * hcp_cell_volume(D); }
};

EngineDef engine_def(const Material& mat, double bond_zeta, double contact_restitution) {
  EngineDef d;
  d.gravity = Vec3::Zero();
  d.youngs_modulus = mat.E;
  d.density = kRhoI;
  d.contact.kn = d.contact.kt = mat.kn();
  if (contact_restitution < 1.0)
    d.contact.zeta_n = d.contact.zeta_t = damping_ratio_from_restitution(contact_restitution);
  const double m = mat.cell_mass(), I = 0.4 * m * 0.25 * mat.D * mat.D;
  d.bond[0] = ParallelBondParams::from_stiffness(mat.kn(), mat.kn(), 0.5 * mat.D, INFINITY, INFINITY,
                                                 bond_zeta, 0.5 * m, 0.5 * I);
  return d;
}

Vec3 centre_of_mass(const Engine& e, std::size_t first, std::size_t last) {
  const auto& p = e.particles();
  Vec3 s = Vec3::Zero();
  double m = 0;
  for (std::size_t i = first; i < last; ++i) { s += p.mass[i] * p.x[i]; m += p.mass[i]; }
  return s / m;
}

}  // namespace

// 1. Free flight: exact momenta, small KE change, COM on its straight line for 1 s.
TEST(Converter, FreeFlightConservesMomentaAndKeepsTheCentreOfMassOnItsLine) {
  Material mat;
  Engine e(engine_def(mat, 0.0, 1.0));
  BlockState b;
  b.half_extents = Vec3(1.0, 0.75, 0.5);
  b.pose.position = Vec3(3.0, -2.0, 1.0);
  b.pose.orientation = Quat(Eigen::AngleAxisd(0.4, Vec3(1, 2, 3).normalized()));
  b.velocity = Vec3(0.4, -0.3, 0.2);
  b.angular_velocity = Vec3(0.1, -0.2, 0.15);
  b.density = kRhoI;
  IceMaterial im;
  im.diameter = mat.D;
  const ConversionReport r = bridge::convert_block(e, b, im);
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
  const double M = kRhoI * 8.0 * 1.0 * 0.75 * 0.5, V = 8.0 * 1.0 * 0.75 * 0.5;
  double msum = 0, vsum = 0;
  for (std::size_t i = 0; i < p.size(); ++i) { msum += p.mass[i]; vsum += p.buoyant_volume[i]; }
  EXPECT_NEAR(msum, M, 1e-12 * M);
  EXPECT_NEAR(vsum, V, 1e-12 * V);
  EXPECT_LT(r.lattice_shift.norm(), mat.D);
  EXPECT_LT(r.com_shift.norm(), 1e-12);

  // Momenta measured by the engine against the block's (independent of the report).
  const Vec3 P0 = M * b.velocity;
  const Mat3 Ib = bridge::box_inertia_world(b.half_extents, b.pose.orientation, M);
  const Vec3 L0 = Ib * b.angular_velocity + b.pose.position.cross(P0);
  const double dP = (e.linear_momentum() - P0).norm() / P0.norm();
  const double dL = (e.angular_momentum() - L0).norm() / L0.norm();
  const double dLc = (e.angular_momentum(b.pose.position) - Ib * b.angular_velocity).norm() /
                     (Ib * b.angular_velocity).norm();
  const double ke0 = 0.5 * M * b.velocity.squaredNorm() + 0.5 * b.angular_velocity.dot(Ib * b.angular_velocity);
  const auto en = e.energy();
  const double ke1 = en.kinetic_translational + en.kinetic_rotational;
  std::printf("[free flight] %zu particles, %zu bonds, D = %.3f m; |dP|/P = %.2e, |dL|/L = %.2e (about the "
              "centre %.2e); KE %.6f -> %.6f J (%+.4f %%), rotational part %.6f J\n",
              r.particles_created, r.bonds_created, mat.D, dP, dL, dLc, ke0, ke1, 100.0 * (ke1 / ke0 - 1.0),
              0.5 * b.angular_velocity.dot(Ib * b.angular_velocity));
  EXPECT_LT(dP, 1e-12);
  EXPECT_LT(dL, 1e-10);
  EXPECT_LT(dLc, 1e-10);
  EXPECT_NEAR(r.kinetic_energy_before, ke0, 1e-12 * ke0);
  EXPECT_NEAR(r.kinetic_energy_after, ke1, 1e-12 * ke0);
  EXPECT_LT(std::abs(ke1 / ke0 - 1.0), 0.01);
  EXPECT_LT((r.linear_momentum_after - r.linear_momentum_before).norm(), 1e-12 * P0.norm());
  EXPECT_LT((r.angular_momentum_after - r.angular_momentum_before).norm(), 1e-10 * L0.norm());

  // 1 s of free flight, gravity off: the centre of mass moves on x0 + v t.
  e.check_time_step();
  const Vec3 x0 = centre_of_mass(e, 0, p.size());
  const std::uint64_t steps = static_cast<std::uint64_t>(std::ceil(1.0 / e.dt()));
  e.run(steps);
  const double t = e.time();
  const double path_err = (centre_of_mass(e, 0, p.size()) - (x0 + b.velocity * t)).norm();
  const double dL_run = (e.angular_momentum() - L0).norm() / L0.norm();
  std::printf("[free flight] after %.3f s (%llu steps): COM off its line by %.2e m, |dL|/L = %.2e, bonds intact %zu\n",
              t, static_cast<unsigned long long>(steps), path_err, dL_run, e.bonds().size());
  EXPECT_GE(t, 1.0);
  EXPECT_LT(path_err, 1e-6);
  EXPECT_EQ(e.bonds().size(), r.bonds_created);
}

// 2. A block floating at rest, converted: its draft stays within 2 % of the freeboard and the
//    particles come to rest. The thickness is a whole number of HCP layers, so the lattice's
//    buoyancy column is as tall as the block (docs/bridge.md, "Floating").
TEST(Converter, FloatingBlockKeepsItsDraftAndComesToRest) {
  Material mat;
  EngineDef d = engine_def(mat, 0.3, 0.5);
  d.gravity = Vec3(0, 0, -kG);
  d.water.enabled = true;
  d.water.density = kRhoW;
  d.water.model = BuoyancyModel::Column;
  // Heave of the block: omega = sqrt(rho_w g / (rho_i h)); c_lin = 2 m omega per particle ~ critical.
  const int layers = 2;
  const double h = layers * hcp_layer_spacing(mat.D);
  const double omega_heave = std::sqrt(kRhoW * kG / (kRhoI * h));
  d.water.linear_drag = 2.0 * mat.cell_mass() * omega_heave;
  Engine e(d);
  BlockState b;
  // 3 m x 3 m: cut from the box its A and B layers hold 168 and 156 sites (D = 0.25 m); the
  // converter trims them to equal counts, without which the draft moved by 5 % of the freeboard.
  b.half_extents = Vec3(1.5, 1.5, 0.5 * h);
  const double draft = h * kRhoI / kRhoW, freeboard = h - draft;
  b.pose.position = Vec3(0.0, 0.0, 0.5 * h - draft);  // block's own floating equilibrium
  b.pose.orientation = Quat(Eigen::AngleAxisd(0.3, Vec3::UnitZ()));
  b.density = kRhoI;
  IceMaterial im;
  im.diameter = mat.D;
  const ConversionReport r = bridge::convert_block(e, b, im);
  e.check_time_step();
  const std::size_t n = e.particles().size();
  const double z0 = centre_of_mass(e, 0, n).z();
  const std::uint64_t steps = static_cast<std::uint64_t>(std::ceil(1.0 / e.dt()));
  e.run(steps);
  const double z1 = centre_of_mass(e, 0, n).z();
  double vmax = 0;
  for (std::size_t i = 0; i < n; ++i) vmax = std::max(vmax, e.particles().v[i].norm());
  EXPECT_GT(r.sites_trimmed, 0u) << "the test must exercise layer balancing";
  std::printf("[floating] %zu particles (%zu sites trimmed), %d layers, h = %.4f m, freeboard %.4f m; COM z %.6f -> %.6f m after %.3f s: "
              "draft change %.2e m = %.3f %% of the freeboard; max speed %.2e m/s\n",
              r.particles_created, r.sites_trimmed, layers, h, freeboard, z0, z1, e.time(), z0 - z1,
              100.0 * (z0 - z1) / freeboard, vmax);
  EXPECT_LT(std::abs(z1 - z0), 0.02 * freeboard);
  EXPECT_LT(vmax, 1e-3);
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

TEST(Converter, BadInputIsRefusedWithAClearMessage) {
  Material mat;
  Engine e(engine_def(mat, 0.0, 1.0));
  IceMaterial im;
  im.diameter = mat.D;
  auto expect_error = [&](BlockState b, IceMaterial m, const char* what) {
    try {
      bridge::convert_block(e, b, m);
      ADD_FAILURE() << "accepted: " << what;
    } catch (const InputError& err) {
      std::printf("[bad input] %s -> %s\n", what, err.what());
    }
  };
  BlockState ok;
  ok.density = kRhoI;
  BlockState b = ok;
  b.half_extents = Vec3(1, -1, 1);
  expect_error(b, im, "negative half extent");
  b = ok;
  b.half_extents = Vec3(1, 1, 0.1);
  expect_error(b, im, "block thinner than a particle");
  b = ok;
  b.density = 0;
  expect_error(b, im, "no mass or density");
  b = ok;
  b.mass = 5.0;
  expect_error(b, im, "mass and density disagree");
  b = ok;
  b.pose.orientation = Quat(0, 0, 0, 0);
  expect_error(b, im, "zero quaternion");
  IceMaterial bad = im;
  bad.diameter = 0;
  expect_error(ok, bad, "zero diameter");
  EXPECT_EQ(e.particles().size(), 0u) << "a refused conversion must not leave particles behind";
}
