// Block–particle freeze bonds (src/bridge/block_bonds.h): strength in tension and shear, stress
// free at creation, rotation invariance, momentum and energy with a free block integrated at the
// rigid step, patch creation, and the conversion hand-over (bond counts conserved).
#include "bridge/block_bonds.h"
#include "bridge/converter.h"
#include "common/ice_formulas.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <set>

using namespace hs;
using namespace hs::bonded;
using hs::bridge::BlockBody;
using hs::bridge::BlockParticleBonds;

namespace {

constexpr double kRhoI = 920.0, kD = 0.25, kR = 0.5 * kD, kE = 1e7;
const double kK = eq1_contact_stiffness(kE, kD);  // paper Eq. 1
const double kMass = kRhoI * hcp_cell_volume(kD);
const double kInertia = 0.4 * kMass * kR * kR;

EngineDef engine_def(double sigma_c, double tau_c, double zeta) {
  EngineDef d;
  d.gravity = Vec3::Zero();
  d.youngs_modulus = kE;
  d.density = kRhoI;
  d.contact.kn = d.contact.kt = kK;
  d.bond[0] = ParallelBondParams::from_stiffness(kK, kK, 0.5 * kR, INFINITY, INFINITY, 0.0, 0.5 * kMass, 0.5 * kInertia);
  d.bond[1] = ParallelBondParams::from_stiffness(kK, kK, 0.5 * kR, sigma_c, tau_c, zeta, 0.5 * kMass, 0.5 * kInertia);
  return d;
}

ParticleInit particle(const Vec3& x, const Quat& q = Quat::Identity()) {
  ParticleInit p;
  p.x = x;
  p.q = q;
  p.radius = kR;
  p.mass = kMass;
  return p;
}

Quat quat(double w, double x, double y, double z) { return Quat(w, x, y, z).normalized(); }

// A ramped pull F(t) = rate t on one particle (the test's load).
struct Pull final : ForceSource {
  GlobalId gid = 0;
  Vec3 rate = Vec3::Zero();  // N/s
  ForceSourceResult add_forces(ParticleStore& ps, std::size_t n_owned, const ForceSourceContext& ctx) override {
    const std::uint32_t i = ps.local(gid);
    if (i < n_owned) ps.f[i] += ctx.time * rate;
    return {};
  }
};

// Particle on a fixed heavy block (rotated), pulled by a ramp along `dir_local` (block frame);
// returns the pull at the step the bond broke.
double pull_until_break(double sigma_c, double tau_c, const Vec3& dir_local, BlockParticleBonds& src) {
  Engine e(engine_def(sigma_c, tau_c, 0.5));
  BlockBody b;
  b.position = Vec3(1.3, -0.7, 0.4);
  b.orientation = quat(0.9, 0.2, -0.3, 0.1);
  b.half_extents = Vec3(1.0, 0.8, 0.4);
  src.set_block(0, b);
  const Vec3 xp = b.position + b.orientation * Vec3(0.1, -0.2, 0.4 + kR);
  e.add_particle(particle(xp, quat(0.3, 0.5, 0.1, -0.7)));
  EXPECT_EQ(src.bond_touching(e.particles(), 0), 1u);
  Pull pull;
  pull.gid = e.particles().gid[0];
  const double strength = std::min(sigma_c, tau_c) * e.def().bond[1].area();
  pull.rate = b.orientation * dir_local.normalized() * (strength / 2.0);  // breaks after ~2 s
  e.add_force_source(&pull);
  e.add_force_source(&src);
  e.check_time_step();
  while (src.size() > 0 && e.time() < 10.0) e.step();
  return pull.rate.norm() * e.time();
}

}  // namespace

TEST(BlockBonds, BreaksAtStrengthInTensionAndShear) {
  const double sigma_c = 20e3, tau_c = 20e3;
  const double A = engine_def(1, 1, 0).bond[1].area();
  {
    BlockParticleBonds src;
    const double F = pull_until_break(sigma_c, INFINITY, Vec3::UnitZ(), src);
    std::printf("[tension] bond area %.5f m^2: breaks at %.2f N, sigma_c A = %.2f N, ratio %.4f (%llu tension, %llu shear)\n",
                A, F, sigma_c * A, F / (sigma_c * A), static_cast<unsigned long long>(src.stats().broken_tension),
                static_cast<unsigned long long>(src.stats().broken_shear));
    EXPECT_NEAR(F / (sigma_c * A), 1.0, 0.02);
    EXPECT_EQ(src.stats().broken_tension, 1u);
    EXPECT_EQ(src.stats().broken_shear, 0u);
    EXPECT_EQ(src.size(), 0u);
  }
  {
    // Tangential pull; the tensile strength out of reach so the shear limit is what is tested
    // (a tangential pull at the particle centre also bends the bond: sigma = 4 r/R tau here).
    BlockParticleBonds src;
    const double F = pull_until_break(INFINITY, tau_c, Vec3(1.0, 0.5, 0.0), src);
    std::printf("[shear] breaks at %.2f N, tau_c A = %.2f N, ratio %.4f (%llu tension, %llu shear)\n", F, tau_c * A,
                F / (tau_c * A), static_cast<unsigned long long>(src.stats().broken_tension),
                static_cast<unsigned long long>(src.stats().broken_shear));
    EXPECT_NEAR(F / (tau_c * A), 1.0, 0.02);
    EXPECT_EQ(src.stats().broken_shear, 1u);
    EXPECT_EQ(src.stats().broken_tension, 0u);
  }
}

TEST(BlockBonds, StressFreeAtCreationForAnyPose) {
  // Particles against faces, an edge and a corner of a rotated, moving block, co-moving with
  // it: no force, no torque, no reaction (damping on, so relative velocity is checked too).
  const EngineDef def = engine_def(20e3, 20e3, 0.5);
  BlockBody b;
  b.position = Vec3(3.1, -2.2, 1.7);
  b.orientation = quat(0.4, -0.6, 0.2, 0.66);
  b.half_extents = Vec3(0.8, 0.6, 0.4);
  b.velocity = Vec3(0.3, -0.1, 0.2);
  b.angular_velocity = Vec3(0.2, 0.4, -0.3);
  const Vec3 locals[] = {{0.1, 0.2, 0.4 + kR},  {-0.3, 0.1, -0.4 - kR}, {0.8 + kR, -0.2, 0.1},
                         {0.2, -0.6 - kR, 0.0}, {0.8 + 0.6 * kR, 0.6 + 0.8 * kR, 0.0},
                         {-0.8 - 0.5 * kR, -0.6 - 0.5 * kR, 0.4 + std::sqrt(0.5) * kR}};
  ParticleStore ps;
  GlobalId id = 0;
  for (const Vec3& l : locals) {
    ParticleInit p = particle(b.position + b.orientation * l, quat(1.0 + id, 0.3, -0.2 * id, 0.5));
    p.v = b.velocity + b.angular_velocity.cross(p.x - b.position);
    p.omega = b.angular_velocity;
    ps.add(p, id++);
  }
  BlockParticleBonds src;
  src.set_block(0, b);
  EXPECT_EQ(src.bond_touching(ps, 0, 1e-6), 6u);
  src.add_forces(ps, ps.owned(), ForceSourceContext{def, 1.0, 0.0});
  double fmax = 0, tmax = 0;
  for (std::size_t i = 0; i < ps.size(); ++i) {
    fmax = std::max(fmax, ps.f[i].norm());
    tmax = std::max(tmax, ps.torque[i].norm());
  }
  std::vector<Vec3> J, H;
  src.take_impulses(J, H);
  const double strength = 20e3 * def.bond[1].area();
  std::printf("[stress free] 6 bonds (4 faces, edge, corner) on a rotated moving block at |c| = %.1f m: "
              "max |F| = %.2e N, max |T| = %.2e N m, reaction %.2e N, %.2e N m; |F| / (sigma_c A) = %.1e\n",
              b.position.norm(), fmax, tmax, J[0].norm(), H[0].norm(), fmax / strength);
  // Rounding: |F| ~ k eps |x| = 6.5e5 N/m x 1e-16 x 4 m ~ 3e-10 N is the floor at these
  // coordinates; asserted relative to the bond's strength.
  EXPECT_LT(fmax, 1e-12 * strength);
  EXPECT_LT(tmax, 1e-12 * strength * kR);
  EXPECT_LT(J[0].norm(), 1e-12 * strength);
}

TEST(BlockBonds, ForceIsRotationInvariant) {
  const EngineDef def = engine_def(INFINITY, INFINITY, 0.5);
  const Quat Q = quat(0.3, -0.8, 0.45, 0.2);
  struct Out { Vec3 f, t, J, H; };
  auto run = [&](const Quat& R) {
    BlockBody b;
    b.position = R * Vec3(0.3, -0.2, 0.1);
    b.orientation = R * quat(0.9, 0.1, 0.2, -0.3);
    b.half_extents = Vec3(0.5, 0.4, 0.3);
    ParticleStore ps;
    ps.add(particle(b.position + b.orientation * Vec3(0.1, 0.05, 0.3 + kR), R * quat(0.2, 0.7, -0.1, 0.4)), 7);
    BlockParticleBonds src;
    src.set_block(0, b);
    src.bond_touching(ps, 0);
    // Deform: move and spin both ends (same deformation, rotated by R).
    ps.x[0] += R * Vec3(2e-3, -1e-3, 1.5e-3);
    ps.q[0] = Quat(Eigen::AngleAxisd(0.01, (R * Vec3(1, 2, -1)).normalized())) * ps.q[0];
    ps.v[0] = R * Vec3(0.05, 0.02, -0.03);
    ps.omega[0] = R * Vec3(0.3, -0.1, 0.2);
    b.position += R * Vec3(-5e-4, 1e-3, 0.0);
    b.orientation = Quat(Eigen::AngleAxisd(0.008, (R * Vec3(-1, 0.5, 2)).normalized())) * b.orientation;
    b.velocity = R * Vec3(-0.02, 0.01, 0.04);
    b.angular_velocity = R * Vec3(0.1, 0.2, -0.05);
    src.set_block(0, b);
    src.add_forces(ps, 1, ForceSourceContext{def, 1.0, 0.0});
    Out o;
    o.f = ps.f[0];
    o.t = ps.torque[0];
    std::vector<Vec3> J, H;
    src.take_impulses(J, H);
    o.J = J[0];
    o.H = H[0];
    return o;
  };
  const Out a = run(Quat::Identity()), r = run(Q);
  const double ef = (r.f - Q * a.f).norm() / a.f.norm(), et = (r.t - Q * a.t).norm() / a.t.norm();
  const double eJ = (r.J - Q * a.J).norm() / a.J.norm(), eH = (r.H - Q * a.H).norm() / a.H.norm();
  std::printf("[rotation] |F| = %.3f N, |T| = %.4f N m; rotated vs rotated-back: F %.1e, T %.1e, reaction %.1e, "
              "moment %.1e (relative); action-reaction |F + J| / |F| = %.1e\n",
              a.f.norm(), a.t.norm(), ef, et, eJ, eH, (a.f + a.J).norm() / a.f.norm());
  EXPECT_GT(a.f.norm(), 100.0);
  EXPECT_LT(ef, 1e-12);
  EXPECT_LT(et, 1e-12);
  EXPECT_LT(eJ, 1e-12);
  EXPECT_LT(eH, 1e-12);
  EXPECT_LT((a.f + a.J).norm(), 1e-14 * a.f.norm());
}

namespace {

struct FreeBlockFigures {
  double dP = 0, dL = 0, dE = 0;  // worst relative drift at rigid steps
  double dE_up = 0, E_end = 0;    // worst gain (E - E0)/E0; E/E0 at the end
  double dP_raw = 0;              // with the particle's full-step momentum
  std::size_t bonds = 0;
};

// A free cube (isotropic inertia: constant spin is force-free motion) bonded to one particle
// that starts moving; zero damping. The block is advanced as the hybrid system does: constant
// velocity between rigid steps, accumulated impulses applied every k DEM steps.
FreeBlockFigures free_block(int k, double seconds, double zeta) {
  Engine e(engine_def(INFINITY, INFINITY, zeta));
  const double a = 0.25, M = kRhoI * 8 * a * a * a, I = M * (2 * a) * (2 * a) / 6.0;
  BlockBody b;
  b.position = Vec3(0.2, -0.1, 0.3);
  b.orientation = quat(0.8, 0.3, -0.2, 0.4);
  b.half_extents = Vec3(a, a, a);
  e.add_particle(particle(b.position + b.orientation * Vec3(0.05, -0.03, a + kR), quat(0.2, 0.1, 0.9, -0.3)));
  BlockParticleBonds src;
  src.set_block(0, b);
  FreeBlockFigures out;
  out.bonds = src.bond_touching(e.particles(), 0);
  ParticleStore& ps = e.particles();
  ps.v[0] = Vec3(0.02, -0.01, 0.03);
  ps.omega[0] = Vec3(1.0, -2.0, 0.5);
  e.add_force_source(&src);
  e.check_time_step();
  const double dt = e.dt(), m = kMass, Ip = kInertia;
  Vec3 cr = b.position, vr = Vec3::Zero(), wr = Vec3::Zero();
  Quat qr = b.orientation;
  double tr = 0.0;
  auto momenta = [&](Vec3& P, Vec3& L, bool half) {
    const double h = half ? 0.5 * dt : 0.0;  // particle at the half step the block's kick matches
    const Vec3 vp = ps.v[0] + h * ps.f[0] / m, wp = ps.omega[0] + h * ps.torque[0] / Ip;
    P = m * vp + M * vr;
    L = ps.x[0].cross(m * vp) + Ip * wp + cr.cross(M * vr) + I * wr;
  };
  auto energy = [&]() {
    return 0.5 * m * ps.v[0].squaredNorm() + 0.5 * Ip * ps.omega[0].squaredNorm() + 0.5 * M * vr.squaredNorm() +
           0.5 * I * wr.squaredNorm() + src.elastic_energy(ps, e.def());
  };
  // The engine's first half kick uses F_0 from an evaluation with history_dt = 0, which adds no
  // impulse (a boundary term dt/2 F_0, non-zero here only with damping): the reference
  // momentum includes it.
  e.compute_forces();
  Vec3 P0, L0;
  momenta(P0, L0, true);
  const double E0 = energy();
  const auto steps = static_cast<std::uint64_t>(std::ceil(seconds / dt));
  std::vector<Vec3> J, H;
  for (std::uint64_t n = 1; n <= steps; ++n) {
    const double t = static_cast<double>(n) * dt, tau = t - tr;
    b.position = cr + vr * tau;
    const double wn = wr.norm();
    b.orientation = wn > 0.0 ? Quat(Eigen::AngleAxisd(wn * tau, wr / wn)) * qr : qr;
    b.velocity = vr;
    b.angular_velocity = wr;
    src.set_block(0, b);
    e.step();
    if (n % static_cast<std::uint64_t>(k) != 0) continue;
    src.take_impulses(J, H);
    cr = b.position;
    qr = b.orientation;
    tr = t;
    vr += J[0] / M;
    wr += H[0] / I;
    Vec3 P, L, Praw, Lraw;
    momenta(P, L, true);
    momenta(Praw, Lraw, false);
    out.dP = std::max(out.dP, (P - P0).norm() / P0.norm());
    out.dP_raw = std::max(out.dP_raw, (Praw - P0).norm() / P0.norm());
    out.dL = std::max(out.dL, (L - L0).norm() / L0.norm());
    const double E = energy();
    out.dE = std::max(out.dE, std::abs(E - E0) / E0);
    out.dE_up = std::max(out.dE_up, (E - E0) / E0);
    out.E_end = E / E0;
  }
  EXPECT_EQ(src.size(), 1u);
  return out;
}

}  // namespace

TEST(BlockBonds, FreeBlockConservesMomentumAndEnergy) {
  auto show = [](const char* what, int k, double seconds, const FreeBlockFigures& f) {
    std::printf("[free block, %s, k = %2d] %.1f s: max |dP|/P = %.1e (full-step particle momentum: %.1e), "
                "|dL|/L = %.1e, max |dE|/E = %.1e, max gain %+.1e, E/E0 at the end %.4f\n",
                what, k, seconds, f.dP, f.dP_raw, f.dL, f.dE, f.dE_up, f.E_end);
  };
  // k = 1: the block is kicked every DEM step; momenta exact to rounding, energy bounded.
  const FreeBlockFigures f1 = free_block(1, 2.0, 0.0);
  show("zero damping", 1, 2.0, f1);
  EXPECT_EQ(f1.bonds, 1u);
  EXPECT_LT(f1.dP, 1e-12);
  EXPECT_LT(f1.dL, 1e-10);
  EXPECT_LT(f1.dE, 0.02);
  // k = 10, zero damping: linear momentum stays exact (every impulse reaches the block), but
  // the block's reaction lags the particle by up to k dt and the undamped bond mode gains
  // energy (negative damping of a delayed coupling, docs/bridge.md): figures only.
  for (int k : {2, 5}) show("zero damping", k, 0.5, free_block(k, 0.5, 0.0));
  const FreeBlockFigures f10 = free_block(10, 0.5, 0.0);
  show("zero damping", 10, 0.5, f10);
  EXPECT_LT(f10.dP, 1e-12);
  EXPECT_GT(f10.dE_up, 0.5);  // the limit documented: undamped k = 10 is not energy bounded
  // k = 10 with the scenes' default bond damping ratio 0.1: energy bounded (never above E0).
  const FreeBlockFigures f10d = free_block(10, 2.0, 0.1);
  show("damping 0.1", 10, 2.0, f10d);
  EXPECT_LT(f10d.dP, 1e-12);
  EXPECT_LT(f10d.dE_up, 1e-3);
  EXPECT_LT(f10d.dL, 1e-4);
}

TEST(BlockBonds, PatchBondsExactlyTheParticlesInThePatch) {
  // Two layers of particles on a square grid over the top face of a rotated block; a disc patch
  // that spills over two edges of the face.
  BlockBody b;
  b.position = Vec3(-1.0, 2.0, 0.5);
  b.orientation = quat(0.7, 0.1, 0.3, -0.2);
  b.half_extents = Vec3(1.0, 0.8, 0.4);
  ParticleStore ps;
  GlobalId id = 0;
  for (int layer = 0; layer < 2; ++layer)
    for (int ix = -7; ix <= 7; ++ix)
      for (int iy = -6; iy <= 6; ++iy) {
        const double z = 0.4 + (layer == 0 ? ((ix + iy) % 3 == 0 ? 0.95 : 1.0) * kR : kR + kD);
        ps.add(particle(b.position + b.orientation * Vec3(ix * kD + 0.01, iy * kD - 0.013, z)), id++);
      }
  const Vec3 anchor_l(0.6, -0.45, 0.4);
  const double Rp = 0.62, area = kPi * Rp * Rp, tol = 0.1;
  std::set<GlobalId> expected;
  for (std::size_t i = 0; i < ps.size(); ++i) {
    const Vec3 l = b.orientation.conjugate() * (ps.x[i] - b.position);
    const double s = l.z() - 0.4;
    const bool in = s > 0 && s <= kR * (1 + tol) && std::hypot(l.x() - anchor_l.x(), l.y() - anchor_l.y()) <= Rp &&
                    std::abs(l.x()) <= 1.0 + tol * kR && std::abs(l.y()) <= 0.8 + tol * kR;
    if (in) expected.insert(ps.gid[i]);
  }
  BlockParticleBonds src;
  src.set_block(0, b);
  const std::size_t made =
      src.bond_patch(ps, 0, b.position + b.orientation * anchor_l, b.orientation * Vec3::UnitZ(), area, tol);
  std::set<GlobalId> got;
  for (const auto& bd : src.bonds()) got.insert(bd.gid);
  std::size_t in_disc = 0;
  for (std::size_t i = 0; i < ps.size() / 2; ++i) {
    const Vec3 l = b.orientation.conjugate() * (ps.x[i] - b.position);
    in_disc += std::hypot(l.x() - anchor_l.x(), l.y() - anchor_l.y()) <= Rp;
  }
  std::printf("[patch] %zu particles in 2 layers, %zu of the first layer in the disc, %zu on the face: %zu bonds made\n",
              ps.size(), in_disc, expected.size(), made);
  EXPECT_GT(expected.size(), 5u);
  EXPECT_LT(expected.size(), in_disc);
  EXPECT_EQ(made, expected.size());
  EXPECT_EQ(got, expected);
  // ... and they start stress free.
  src.add_forces(ps, ps.owned(), ForceSourceContext{engine_def(20e3, 20e3, 0.0), 0.0, 0.0});
  double fmax = 0;
  for (std::size_t i = 0; i < ps.size(); ++i) fmax = std::max(fmax, ps.f[i].norm());
  EXPECT_LT(fmax, 1e-12 * 20e3 * engine_def(1, 1, 0).bond[1].area());
}

namespace {

std::size_t freeze_bonds(const Engine& e) {
  std::size_t n = 0;
  for (const auto& b : e.bonds()) n += b.kind == BondKind::Freeze;
  return n;
}

bridge::BlockState block_state(const BlockBody& b) {
  bridge::BlockState s;
  s.half_extents = b.half_extents;
  s.pose.position = b.position;
  s.pose.orientation = b.orientation;
  s.velocity = b.velocity;
  s.angular_velocity = b.angular_velocity;
  s.density = kRhoI;
  return s;
}

double max_force(Engine& e, BlockParticleBonds* src = nullptr) {
  if (src) e.add_force_source(src);
  e.compute_forces();
  if (src) e.remove_force_source(src);
  double f = 0;
  for (std::size_t i = 0; i < e.particles().owned(); ++i) f = std::max(f, e.particles().f[i].norm());
  return f;
}

}  // namespace

TEST(BlockBonds, ConversionHandOverConservesBonds) {
  // A block with particles frozen to its top face converts: every block-particle bond becomes
  // one particle-particle freeze bond to the nearest new particle.
  Engine e(engine_def(20e3, 20e3, 0.0));
  BlockBody b;
  b.position = Vec3(0.5, -0.3, 0.2);
  b.orientation = quat(0.95, 0.05, -0.1, 0.2);
  b.half_extents = Vec3(0.75, 0.5, 0.25);
  for (int ix = -3; ix <= 3; ++ix)
    for (int iy = -2; iy <= 2; ++iy)
      e.add_particle(particle(b.position + b.orientation * Vec3(ix * kD, iy * kD, 0.25 + kR)));
  const std::size_t n_old = e.particles().size();
  BlockParticleBonds src;
  src.set_block(0, b);
  const std::size_t made = src.bond_touching(e.particles(), 0);
  const auto released = src.release_block(0);
  std::vector<bridge::Attachment> attach;
  for (const auto& rb : released) attach.push_back({rb.gid, rb.anchor});
  bridge::IceMaterial im;
  im.diameter = kD;
  const bridge::ConversionReport r = bridge::convert_block(e, block_state(b), im, {}, attach);
  const std::size_t lattice = r.bonds_created;
  const std::size_t handed = r.bonds_attached;
  const double f = max_force(e);
  std::printf("[hand-over] %zu particles on the face, %zu block bonds, %zu released; block -> %zu particles "
              "(%zu lattice bonds); %zu freeze bonds made, engine holds %zu; max |F| after = %.1e N\n",
              n_old, made, released.size(), r.particles_created, lattice, handed, freeze_bonds(e), f);
  EXPECT_EQ(made, n_old);
  EXPECT_EQ(released.size(), made);
  EXPECT_EQ(src.size(), 0u);
  EXPECT_EQ(handed, made);
  EXPECT_EQ(freeze_bonds(e), made);
  EXPECT_EQ(e.bonds().size(), lattice + made);
  EXPECT_LT(f, 1e-12 * 20e3 * e.def().bond[1].area());
  // Each freeze bond goes from its old particle to the new particle nearest the bond's block end.
  const ParticleStore& ps = e.particles();
  for (const auto& rb : released) {
    double nearest = INFINITY;
    for (std::size_t i = 0; i < ps.size(); ++i)  // (the store was re-sorted by max_force)
      if (ps.gid[i] >= r.first_gid) nearest = std::min(nearest, (ps.x[i] - rb.anchor).norm());
    std::size_t found = 0;
    for (const auto& bd : e.bonds()) {
      if (bd.kind != BondKind::Freeze || bd.gi != rb.gid) continue;
      ++found;
      EXPECT_EQ((ps.x[ps.local(bd.gj)] - rb.anchor).norm(), nearest);
    }
    EXPECT_EQ(found, 1u);
  }
}

TEST(BlockBonds, FrozenBlockConvertsIntoBondsToTheRemainingBlock) {
  // Block A (stays rigid) and block B above it, frozen over a patch of the common face; B
  // converts: A is bonded to the first layer of B's particles inside the patch.
  Engine e(engine_def(20e3, 20e3, 0.0));
  BlockBody a, bb;
  a.orientation = bb.orientation = quat(0.9, -0.1, 0.2, 0.3);
  a.half_extents = Vec3(0.75, 0.5, 0.25);
  bb.half_extents = Vec3(0.6, 0.5, 0.375);
  a.position = Vec3(0.1, 0.2, -0.3);
  const Vec3 up = a.orientation * Vec3::UnitZ();
  bb.position = a.position + (0.25 + 0.375) * up;
  const Vec3 anchor = a.position + 0.25 * up;
  const double area = 0.4;
  BlockParticleBonds src;
  src.set_block(0, a);
  bridge::IceMaterial im;
  im.diameter = kD;
  const bridge::ConversionReport r = bridge::convert_block(e, block_state(bb), im);
  const std::size_t made = bridge::bond_joint_to_particles(src, 0, anchor, up, area, r);
  // Expected: the lowest layer of B's particles with in-plane distance <= sqrt(area/pi).
  const ParticleStore& ps = e.particles();
  double s_min = INFINITY;
  for (std::size_t i = r.first; i < r.first + r.particles_created; ++i) s_min = std::min(s_min, (ps.x[i] - anchor).dot(up));
  std::set<GlobalId> expected, got;
  for (std::size_t i = r.first; i < r.first + r.particles_created; ++i) {
    const Vec3 rel = ps.x[i] - anchor;
    const double s = rel.dot(up);
    if (s < s_min + 0.3 * kD && (rel - s * up).norm() <= std::sqrt(area / kPi)) expected.insert(ps.gid[i]);
  }
  for (const auto& bd : src.bonds()) got.insert(bd.gid);
  const double f = max_force(e, &src);
  std::printf("[joint -> bonds] B -> %zu particles, first layer %.3f m above the joint face; %zu block-particle bonds "
              "to A over %.2f m^2 (%.2f m^2 per bond); max |F| = %.1e N\n",
              r.particles_created, s_min, made, area, area / static_cast<double>(made), f);
  EXPECT_GT(made, 3u);
  EXPECT_EQ(made, expected.size());
  EXPECT_EQ(got, expected);
  EXPECT_LT(f, 1e-12 * 20e3 * e.def().bond[1].area());
}

TEST(BlockBonds, SurvivesTheEnginesReordering) {
  // 24 particles frozen to a fixed block's top face, added in scrambled order and set moving;
  // the engine's spatial sort reorders the store at its first neighbour build. Each bond must
  // keep acting on its own particle: the run matches one without sorting, particle by particle.
  auto run = [](bool sort, std::vector<GlobalId>& order) {
    EngineDef d = engine_def(INFINITY, INFINITY, 0.0);
    d.spatial_sort = sort;
    Engine e(d);
    BlockBody b;
    b.half_extents = Vec3(2.0, 2.0, 0.5);
    b.orientation = quat(0.98, 0.0, 0.0, 0.2);
    BlockParticleBonds src;
    src.set_block(0, b);
    for (int n = 0; n < 24; ++n) {
      const int k = (n * 7) % 24;  // scrambled positions
      ParticleInit p = particle(b.orientation * Vec3((k % 6) * 2 * kD - 1.2, (k / 6) * 2 * kD - 0.8, 0.5 + kR));
      p.v = Vec3(0.01 * (n % 5), -0.02 * (n % 3), 0.03 * ((n % 4) - 1.5));
      e.add_particle(p);
    }
    EXPECT_EQ(src.bond_touching(e.particles(), 0), 24u);
    e.add_force_source(&src);
    e.run(400);
    const ParticleStore& ps = e.particles();
    std::vector<Vec3> x(ps.size());
    order.assign(ps.gid.begin(), ps.gid.end());
    for (std::size_t i = 0; i < ps.size(); ++i) x[ps.gid[i]] = ps.x[i];
    return x;
  };
  std::vector<GlobalId> o_sorted, o_plain;
  const std::vector<Vec3> xs = run(true, o_sorted), xp = run(false, o_plain);
  double worst = 0, moved = 0;
  std::size_t permuted = 0;
  for (std::size_t g = 0; g < xs.size(); ++g) {
    worst = std::max(worst, (xs[g] - xp[g]).norm());
    permuted += o_sorted[g] != g;
  }
  for (std::size_t g = 0; g < xs.size(); ++g) moved = std::max(moved, std::abs(xp[g].z() - (0.5 + kR)));
  std::printf("[reordering] 24 bonded particles, %zu moved in the store by the spatial sort; largest z excursion "
              "%.2e m; sorted vs unsorted run: max |dx| = %.1e m\n",
              permuted, moved, worst);
  EXPECT_GT(permuted, 10u);
  EXPECT_GT(moved, 1e-5);
  EXPECT_LT(worst, 1e-15);
}
