// Particle-block contact (docs/bridge.md, "Particle-block contact"): resting force, restitution,
// conservation in a free sphere-block collision, edge/corner/inside geometry, rotation
// invariance, Coulomb sliding, history semantics, and the broad phase against brute force.
#include "bridge/block_contact.h"
#include "common/error.h"
#include "common/ice_formulas.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>

using namespace hs;
using namespace hs::bonded;
using hs::bridge::BlockContact;
using hs::bridge::ContactBlock;

namespace {

constexpr double kG = 9.81;

struct Ice {
  double D = 0.5;      // m
  double rho = 920.0;  // kg/m^3
  double E = 1e9;      // Pa
  double r() const { return 0.5 * D; }
  double kn() const { return eq1_contact_stiffness(E, D); }  // paper Eq. 1
  double sphere_mass() const { return rho * kPi * D * D * D / 6.0; }
  double tau0() const { return D * std::sqrt(rho / E); }
};

EngineDef make_def(const Ice& ice, double restitution, ContactModel model = ContactModel::LinearSpringDashpot,
                   const Vec3& g = Vec3::Zero()) {
  EngineDef d;
  d.gravity = g;
  d.youngs_modulus = ice.E;
  d.density = ice.rho;
  d.contact_model = model;
  d.contact.kn = d.contact.kt = ice.kn();
  d.contact.zeta_n = d.contact.zeta_t = damping_ratio_from_restitution(restitution);
  d.hertz = HertzContactParams::from_material(ice.E, 0.3, restitution, 0.0);
  return d;
}

ParticleInit sphere(const Ice& ice, const Vec3& x, const Vec3& v = Vec3::Zero(), const Vec3& w = Vec3::Zero()) {
  ParticleInit p;
  p.x = x;
  p.v = v;
  p.omega = w;
  p.radius = ice.r();
  p.mass = ice.sphere_mass();
  p.buoyant_volume = kPi * ice.D * ice.D * ice.D / 6.0;
  return p;
}

// A free rigid box integrated like the engine integrates particles (velocity Verlet, kick-drift-
// kick), with the angular momentum L as the rotational state (kick: L += dt/2 T; drift: the
// orientation turns by the exact exponential of omega = I_world^-1 L). The block's drift uses
// only its own state, so it can run before Engine::step(), whose force evaluation then sees the
// block at the new pose.
struct FreeBlock {
  Vec3 half, x, v, L;
  Quat q;
  double M;
  Mat3 I_body;
  FreeBlock(const Vec3& he, double mass, const Vec3& pos, const Quat& ori, const Vec3& vel, const Vec3& omega)
      : half(he), x(pos), v(vel), q(ori.normalized()), M(mass) {
    const Vec3 s = he.cwiseProduct(he);
    I_body = Vec3(M / 3 * (s.y() + s.z()), M / 3 * (s.x() + s.z()), M / 3 * (s.x() + s.y())).asDiagonal();
    L = inertia_world() * omega;
  }
  Mat3 inertia_world() const {
    const Mat3 R = q.toRotationMatrix();
    return R * I_body * R.transpose();
  }
  Vec3 omega() const { return inertia_world().inverse() * L; }
  void kick(const Vec3& F, const Vec3& T, double hdt) {
    v += hdt * F / M;
    L += hdt * T;
  }
  void drift(double dt) {
    x += dt * v;
    const Vec3 w = omega();
    const double a = w.norm() * dt;
    if (a > 0.0) q = (Quat(Eigen::AngleAxisd(a, w.normalized())) * q).normalized();
  }
  double kinetic() const { return 0.5 * M * v.squaredNorm() + 0.5 * L.dot(omega()); }
  ContactBlock contact(std::uint64_t id, double friction) const {
    ContactBlock b;
    b.id = id;
    b.half_extents = half;
    b.position = x;
    b.orientation = q;
    b.velocity = v;
    b.angular_velocity = omega();
    b.mass = M;
    b.friction = friction;
    return b;
  }
};

// One coupled step: block kick + drift, particle step (forces at the new poses), block kick.
void coupled_step(Engine& e, BlockContact& bc, FreeBlock& b, std::size_t k) {
  const double hdt = 0.5 * e.dt();
  b.kick(bc.load(k).force, bc.load(k).torque, hdt);
  b.drift(e.dt());
  bc.set_state(k, b.x, b.q, b.v, b.omega());
  e.step();
  b.kick(bc.load(k).force, bc.load(k).torque, hdt);
}

}  // namespace

// 1. A sphere at rest on the top face of an immovable, yawed box under gravity: the contact
// carries exactly m g once the damping has taken the bounce out.
TEST(BlockContact, SphereRestingOnFixedTopFaceCarriesItsWeight) {
  Ice ice;
  Engine e(make_def(ice, 0.3, ContactModel::LinearSpringDashpot, Vec3(0, 0, -kG)));
  BlockContact bc;
  ContactBlock b;
  b.half_extents = Vec3(2.0, 1.5, 0.5);
  b.position = Vec3(1.0, 2.0, -0.5);
  b.orientation = Quat(Eigen::AngleAxisd(0.7, Vec3::UnitZ()));
  const std::size_t k = bc.add_block(b);
  e.add_force_source(&bc);
  e.add_particle(sphere(ice, Vec3(1.3, 2.2, ice.r() + 1e-3)));
  e.check_time_step();
  const int steps = static_cast<int>(0.2 / e.dt());
  e.run(steps);
  const double mg = ice.sphere_mass() * kG;
  const Vec3 F = bc.load(k).force;
  const double err = (F - Vec3(0, 0, -mg)).norm() / mg;
  std::printf("resting sphere after %d steps (%.3f s): block load (%.3e, %.3e, %.9f) N, m g = %.9f N, "
              "|F + m g e_z|/(m g) = %.2e; overlap %.6e m vs m g/kn = %.6e m\n",
              steps, e.time(), F.x(), F.y(), F.z(), mg, err, ice.r() - e.particles().x[0].z(), mg / ice.kn());
  EXPECT_EQ(bc.load(k).contacts, 1u);
  EXPECT_LT(err, 1e-6);
  EXPECT_LT(e.particles().v[0].norm(), 1e-6);
}

// 2. Head-on impact on a face: the rebound/approach ratio of the normal relative speed is the
// law's restitution, for an immovable block and for a free block of 3 particle masses (which
// needs m_eff = m M/(m + M) in the damping: with m_eff = m it would come out wrong).
namespace {
struct Rebound { double e, mass_ratio_check; };

Rebound face_impact(double restitution, ContactModel model, double block_mass) {
  Ice ice;
  Engine e(make_def(ice, restitution, model));
  BlockContact bc;
  const Quat ori(Eigen::AngleAxisd(0.9, Vec3(1, -2, 0.5).normalized()));
  const Vec3 he(1.0, 0.7, 0.4), c(0.3, -0.2, 0.1);
  const Vec3 n = ori * Vec3::UnitY();  // the +y face
  const double v0 = 0.5, gap = 1e-4;
  // Through the block centre: the impact must not spin the block (its rotational inertia would
  // then take part and e would not be the law's).
  const Vec3 x0 = c + (he.y() + ice.r() + gap) * n;
  e.add_particle(sphere(ice, x0, -v0 * n));
  e.set_dt(0.02 * ice.tau0());  // resolve the contact as the engine's restitution test does
  const bool free = std::isfinite(block_mass);
  FreeBlock fb(he, free ? block_mass : 1.0, c, ori, Vec3::Zero(), Vec3::Zero());
  ContactBlock cb = fb.contact(7, 0.3);
  cb.mass = block_mass;
  const std::size_t k = bc.add_block(cb);
  e.add_force_source(&bc);
  e.compute_forces();
  bool touched = false;
  double vrel_out = 0.0;
  for (int s = 0; s < 200000; ++s) {
    if (free) {
      coupled_step(e, bc, fb, k);
    } else {
      e.step();
    }
    const std::size_t nc = bc.load(k).contacts;
    if (nc > 0) touched = true;
    if (touched && nc == 0) {
      vrel_out = (e.particles().v[0] - (free ? fb.v : Vec3::Zero())).dot(n);
      break;
    }
  }
  // Momentum along n (free block): m v0 before, m v_p + M v_b after.
  const double p_after = free ? ice.sphere_mass() * e.particles().v[0].dot(n) + fb.M * fb.v.dot(n) : 0.0;
  return {vrel_out / v0, free ? (p_after + ice.sphere_mass() * v0) / (ice.sphere_mass() * v0) : 0.0};
}
}  // namespace

TEST(BlockContact, HeadOnImpactOnAFaceReboundsWithTheLawsRestitution) {
  const double inf = INFINITY;
  const Ice ice;
  for (double e : {0.1, 0.3, 0.5, 0.9}) {
    const Rebound fixed_lin = face_impact(e, ContactModel::LinearSpringDashpot, inf);
    const Rebound free_lin = face_impact(e, ContactModel::LinearSpringDashpot, 3.0 * ice.sphere_mass());
    const Rebound fixed_hz = face_impact(e, ContactModel::HertzMindlin, inf);
    std::printf("restitution target %.2f: linear fixed block %.5f, linear free block (M = 3 m) %.5f "
                "(momentum error %.1e), Hertz fixed block %.5f\n",
                e, fixed_lin.e, free_lin.e, free_lin.mass_ratio_check, fixed_hz.e);
    EXPECT_NEAR(fixed_lin.e, e, 0.02 * e);
    EXPECT_NEAR(free_lin.e, e, 0.02 * e);
    EXPECT_NEAR(fixed_hz.e, e, 0.02 * e);
    EXPECT_LT(std::abs(free_lin.mass_ratio_check), 1e-12);
  }
}

// 3. A free sphere and a free, spinning block collide obliquely (no gravity): total linear and
// angular momentum (particle spin included) are conserved, the accumulated impulse is the
// block's momentum change, and without damping and friction the total energy comes back.
namespace {
struct Collision {
  double dP, dL, dE_end, dE_max, dJ, block_dv;
  std::size_t contact_steps;
};

Collision oblique_collision(double restitution, double friction) {
  Ice ice;
  Engine e(make_def(ice, restitution));
  const Vec3 he(1.0, 0.6, 0.4);
  const double M = ice.rho * 8.0 * he.prod();
  FreeBlock fb(he, M, Vec3(0.1, 0.0, 0.05), Quat(Eigen::AngleAxisd(0.35, Vec3(0.3, 1.0, -0.4).normalized())),
               Vec3(-0.1, 0.02, 0.05), Vec3(0.1, 0.2, -0.1));
  BlockContact bc;
  const std::size_t k = bc.add_block(fb.contact(42, friction));
  e.add_force_source(&bc);
  e.add_particle(sphere(ice, Vec3(-2.0, 0.35, 0.2), Vec3(3.0, 0.2, -0.3), Vec3(1.0, -2.0, 5.0)));
  e.check_time_step();
  auto P = [&] { return Vec3(e.linear_momentum() + fb.M * fb.v); };
  auto Lo = [&] { return Vec3(e.angular_momentum() + fb.x.cross(fb.M * fb.v) + fb.L); };
  auto En = [&] {
    const EnergyReport r = e.energy();
    return r.kinetic_translational + r.kinetic_rotational + fb.kinetic() +
           bc.elastic_energy(e.particles(), e.particles().owned(), e.def());
  };
  e.compute_forces();
  const Vec3 P0 = P(), L0 = Lo(), v_b0 = fb.v;
  const double E0 = En();
  double dE_max = 0.0;
  std::size_t contact_steps = 0;
  bool touched = false;
  int after = 0;
  for (int s = 0; s < 40000 && after < 200; ++s) {
    coupled_step(e, bc, fb, k);
    dE_max = std::max(dE_max, std::abs(En() - E0) / E0);
    if (bc.load(k).contacts > 0) {
      touched = true;
      ++contact_steps;
    } else if (touched) {
      ++after;
    }
  }
  const Vec3 dPb = fb.M * (fb.v - v_b0);
  return {(P() - P0).norm() / P0.norm(), (Lo() - L0).norm() / L0.norm(), std::abs(En() - E0) / E0, dE_max,
          (bc.load(k).impulse - dPb).norm() / dPb.norm(), (fb.v - v_b0).norm(), contact_steps};
}
}  // namespace

TEST(BlockContact, FreeSphereAndFreeBlockConserveMomentaAndElasticEnergy) {
  const Collision damped = oblique_collision(0.5, 0.3);
  const Collision elastic = oblique_collision(1.0, 0.0);
  for (const auto* c : {&damped, &elastic})
    std::printf("%s collision: %zu contact steps, block |dv| %.4f m/s; |dP|/P = %.2e, |dL|/L = %.2e, "
                "|J - M dv_b|/|M dv_b| = %.2e, |dE|/E end %.2e, max during contact %.2e\n",
                c == &damped ? "damped (e 0.5, mu 0.3)" : "elastic (e 1, mu 0)", c->contact_steps, c->block_dv,
                c->dP, c->dL, c->dJ, c->dE_end, c->dE_max);
  for (const auto* c : {&damped, &elastic}) {
    EXPECT_GT(c->contact_steps, 10u);
    EXPECT_GT(c->block_dv, 1e-2);
    EXPECT_LT(c->dP, 1e-12);
    EXPECT_LT(c->dL, 1e-10);
    EXPECT_LT(c->dJ, 1e-12);
  }
  EXPECT_LT(elastic.dE_end, 1e-3);
  EXPECT_GT(damped.dE_end, 1e-2);  // the damped one does lose energy (the check can fail)
}

// 4. Geometry: edge and corner contacts push along the vector from the closest point; a centre
// inside the box is pushed out through the nearest face (and leaves through it).
TEST(BlockContact, EdgeCornerAndInsideContactsPushAlongTheRightNormal) {
  Ice ice;
  const double r = ice.r();
  const Quat ori(Eigen::AngleAxisd(1.1, Vec3(0.2, 0.7, -0.4).normalized()));
  const Vec3 he(1.0, 0.6, 0.4), c(0.5, -1.0, 2.0);
  const Mat3 R = ori.toRotationMatrix();
  struct Case { const char* name; Vec3 local; Vec3 n_local; double delta; };
  const Vec3 de = Vec3(0.12, 0.09, 0.0), dc = Vec3(0.08, -0.1, 0.06);
  const std::vector<Case> cases = {
      {"face", Vec3(0.3, he.y() + 0.2, 0.1), Vec3::UnitY(), r - 0.2},
      {"edge", Vec3(he.x(), he.y(), 0.1) + de, de.normalized(), r - de.norm()},
      {"corner", Vec3(he.x(), -he.y(), he.z()) + dc, dc.normalized(), r - dc.norm()},
      {"inside", Vec3(0.3, 0.1, -0.33), -Vec3::UnitZ(), r + (he.z() - 0.33)},  // nearest: -z face
  };
  for (const Case& cs : cases) {
    Engine e(make_def(ice, 0.5));
    BlockContact bc;
    ContactBlock b;
    b.half_extents = he;
    b.position = c;
    b.orientation = ori;
    const std::size_t k = bc.add_block(b);
    e.add_force_source(&bc);
    const Vec3 x = c + R * cs.local;
    e.add_particle(sphere(ice, x));
    e.compute_forces();
    const Vec3 F = e.particles().f[0];
    const Vec3 n = R * cs.n_local;
    const double dir_err = (F.normalized() - n).norm();
    const double mag_err = std::abs(F.norm() - ice.kn() * cs.delta) / (ice.kn() * cs.delta);
    const Vec3 a = -(r - 0.5 * cs.delta) * n;
    const double torque_err = (bc.load(k).torque + (x + a - c).cross(F)).norm() / (F.norm() * he.norm());
    std::printf("%-6s contact: normal error %.1e, |F| = %.6e N vs kn delta %.6e N (rel %.1e), "
                "block torque error %.1e\n",
                cs.name, dir_err, F.norm(), ice.kn() * cs.delta, mag_err, torque_err);
    EXPECT_LT(dir_err, 1e-12) << cs.name;
    EXPECT_LT(mag_err, 1e-12) << cs.name;
    EXPECT_LT((bc.load(k).force + F).norm(), 1e-12 * F.norm()) << cs.name;
    EXPECT_LT(torque_err, 1e-12) << cs.name;
  }
  // Released inside, the sphere leaves through the nearest (-z) face and ends clear of the box.
  EngineDef d = make_def(ice, 0.1);
  d.limits.max_overlap_ratio = 4.0;  // it starts 1.3 r deep on purpose
  d.limits.max_speed = 1e4;
  Engine e(d);
  BlockContact bc;
  ContactBlock b;
  b.half_extents = he;
  b.position = c;
  b.orientation = ori;
  bc.add_block(b);
  e.add_force_source(&bc);
  e.add_particle(sphere(ice, c + R * Vec3(0.3, 0.1, -0.33)));
  e.run(2000);
  const Vec3 l = R.transpose() * (e.particles().x[0] - c);
  std::printf("released inside: after %.4f s the centre is at local (%.3f, %.3f, %.3f) m (face z = %.1f m), "
              "velocity along -z %.3f m/s\n",
              e.time(), l.x(), l.y(), l.z(), -he.z(), -(R.transpose() * e.particles().v[0]).z());
  EXPECT_LT(l.z(), -he.z() - r);
  EXPECT_NEAR(l.x(), 0.3, 1e-9);
  EXPECT_NEAR(l.y(), 0.1, 1e-9);
}

// 5. Rotation invariance: the same configuration rotated by an arbitrary quaternion (gravity
// included) gives the rotated forces and torques, also after 12 steps of tangential history.
TEST(BlockContact, RotatedConfigurationGivesTheRotatedForces) {
  Ice ice;
  const Quat Q(Eigen::AngleAxisd(2.3, Vec3(-0.6, 0.3, 0.74).normalized()));
  struct Run { Vec3 f, t, F, T; };
  auto run = [&](const Quat& rot) {
    Engine e(make_def(ice, 0.4, ContactModel::LinearSpringDashpot, rot * Vec3(0, 0, -kG)));
    BlockContact bc;
    ContactBlock b;
    b.half_extents = Vec3(1.0, 0.6, 0.4);
    b.position = rot * Vec3(0.2, -0.1, 0.3);
    b.orientation = rot * Quat(Eigen::AngleAxisd(0.5, Vec3(1, 1, 0).normalized()));
    b.velocity = rot * Vec3(0.05, -0.02, 0.01);
    b.angular_velocity = rot * Vec3(0.3, -0.1, 0.2);
    b.mass = 2000.0;
    b.friction = 0.4;
    const Mat3 R = b.orientation.toRotationMatrix();
    const std::size_t k = bc.add_block(b);
    e.add_force_source(&bc);
    // Overlapping the +x/+y edge by 8 mm, moving and spinning.
    e.add_particle(sphere(ice, b.position + R * Vec3(1.0 + 0.15, 0.6 + 0.19, 0.05), rot * Vec3(0.4, -0.3, 0.2),
                          rot * Vec3(2.0, -1.0, 3.0)));
    e.run(12);  // still compressive (later the damped contact enters its tensile tail: no friction)
    return Run{e.particles().f[0], e.particles().torque[0], bc.load(k).force, bc.load(k).torque};
  };
  const Run a = run(Quat::Identity()), b = run(Q);
  const double ef = (b.f - Q * a.f).norm() / a.f.norm(), et = (b.t - Q * a.t).norm() / a.t.norm();
  const double eF = (b.F - Q * a.F).norm() / a.F.norm(), eT = (b.T - Q * a.T).norm() / a.T.norm();
  std::printf("rotation invariance after 12 steps: |F_p| = %.4e N, |T_p| = %.4e N m, block |F| = %.4e N; "
              "relative errors particle force %.1e, particle torque %.1e, block force %.1e, block torque %.1e\n",
              a.f.norm(), a.t.norm(), a.F.norm(), ef, et, eF, eT);
  EXPECT_GT(a.F.norm(), 1e3);  // in contact
  EXPECT_GT(a.t.norm(), 1e3);  // with friction at work (the torque on the sphere is r x F_t)
  EXPECT_LT(ef, 1e-12);
  EXPECT_LT(et, 1e-12);
  EXPECT_LT(eF, 1e-12);
  EXPECT_LT(eT, 1e-12);
}

// 6. Coulomb friction: a sphere launched along the (yawed) top face of a fixed block slides,
// decelerating at mu g while its spin builds up, and rolls at 5/7 of its launch speed.
TEST(BlockContact, SlidingSphereDeceleratesAtMuGAndEndsRollingAtFiveSevenths) {
  Ice ice;
  const double mu = 0.3, v0 = 2.0;
  Engine e(make_def(ice, 0.3, ContactModel::LinearSpringDashpot, Vec3(0, 0, -kG)));
  BlockContact bc;
  ContactBlock b;
  b.half_extents = Vec3(5.0, 5.0, 0.5);
  b.position = Vec3(0.0, 0.0, -0.5);
  b.orientation = Quat(Eigen::AngleAxisd(0.4, Vec3::UnitZ()));
  b.friction = mu;
  bc.add_block(b);
  e.add_force_source(&bc);
  const double m = ice.sphere_mass();
  const Vec3 dir = Vec3(1.0, 0.5, 0.0).normalized();
  e.add_particle(sphere(ice, Vec3(-3.0, -1.5, ice.r() - m * kG / ice.kn()), v0 * dir));
  e.check_time_step();
  const double t1 = 0.02, t2 = 0.14;  // sliding ends at v0/(3.5 mu g) = 0.194 s
  double v1 = 0, v2 = 0;
  const int steps = static_cast<int>(0.4 / e.dt());
  for (int s = 0; s < steps; ++s) {
    const double t = e.time();
    e.step();
    if (t < t1 && e.time() >= t1) v1 = e.particles().v[0].dot(dir);
    if (t < t2 && e.time() >= t2) v2 = e.particles().v[0].dot(dir);
  }
  const double decel = (v1 - v2) / (t2 - t1);
  const double v_end = e.particles().v[0].dot(dir);
  std::printf("sliding: deceleration %.5f m/s^2 vs mu g = %.5f (rel %.1e); final speed %.5f m/s vs 5/7 v0 = "
              "%.5f (rel %.1e)\n",
              decel, mu * kG, decel / (mu * kG) - 1.0, v_end, 5.0 / 7.0 * v0, v_end / (5.0 / 7.0 * v0) - 1.0);
  EXPECT_NEAR(decel, mu * kG, 0.02 * mu * kG);
  EXPECT_NEAR(v_end, 5.0 / 7.0 * v0, 0.02 * 5.0 / 7.0 * v0);
}

// 7. The block's top face behaves exactly like the engine's own plane wall (same law, same
// history semantics): a sphere dragged along by a moving face and by a moving PlaneWall follow
// the same trajectory, also with compute_forces() calls in between, which must not advance the
// tangential spring (two calls give the same bits). Impulses accumulate only in steps.
TEST(BlockContact, TopFaceActsLikeTheEnginesPlaneWallAndComputeForcesAdvancesNothing) {
  Ice ice;
  const Vec3 g(0, 0, -kG), vwall(0.3, 0.1, 0.0);
  const double mu = 0.5;
  const ParticleInit p = sphere(ice, Vec3(0, 0, ice.r() - ice.sphere_mass() * kG / ice.kn()), Vec3(0, 0, -0.01),
                                Vec3(0.5, 0, 0));
  Engine ew(make_def(ice, 0.3, ContactModel::LinearSpringDashpot, g)),
      eb(make_def(ice, 0.3, ContactModel::LinearSpringDashpot, g));
  ew.add_wall(PlaneWall{"floor", Vec3::Zero(), Vec3::UnitZ(), vwall, mu});
  BlockContact bc;
  ContactBlock b;
  b.half_extents = Vec3(3.0, 3.0, 0.5);
  b.position = Vec3(0, 0, -0.5);
  b.velocity = vwall;  // a kinematic block sliding in its own plane: the face stays put
  b.friction = mu;
  bc.add_block(b);
  eb.add_force_source(&bc);
  ew.add_particle(p);
  eb.add_particle(p);
  double worst = 0.0, worst_f = 0.0, ft_max = 0.0;
  bool idempotent = true;
  for (int s = 0; s < 400; ++s) {
    ew.step();
    eb.step();
    if (s % 50 == 25) {
      ew.compute_forces();
      eb.compute_forces();
      const Vec3 f1 = eb.particles().f[0], J1 = bc.load(0).impulse;
      eb.compute_forces();
      idempotent = idempotent && f1 == eb.particles().f[0] && J1 == bc.load(0).impulse;
    }
    const auto& a = ew.particles();
    const auto& c = eb.particles();
    worst = std::max({worst, (a.x[0] - c.x[0]).norm(), (a.v[0] - c.v[0]).norm(), (a.omega[0] - c.omega[0]).norm()});
    worst_f = std::max(worst_f, (ew.wall_force(0) - bc.load(0).force).norm() / (ice.sphere_mass() * kG));
    ft_max = std::max(ft_max, bc.load(0).force.head<2>().norm());
  }
  std::printf("top face vs plane wall over 400 steps (8 with compute_forces): largest |dx|, |dv|, |dw| %.1e, "
              "largest |F_block - F_wall|/(m g) %.1e; largest tangential load %.3f N (mu m g = %.3f N); "
              "sphere speed %.5f m/s (face %.4f m/s; rolling on it: %.5f)\n",
              worst, worst_f, ft_max, mu * ice.sphere_mass() * kG, eb.particles().v[0].norm(), vwall.norm(),
              2.0 / 7.0 * vwall.norm());
  EXPECT_TRUE(idempotent) << "compute_forces() changed the forces or the impulse on a second call";
  EXPECT_LT(worst, 1e-12);
  // The overlap (4.5 um) is r - dist with dist ~ r: its round-off, 1e-11 of it, differs between the
  // block's rotated frame and the wall's dot product.
  EXPECT_LT(worst_f, 1e-9);
  EXPECT_GT(ft_max, 0.5 * mu * ice.sphere_mass() * kG);  // friction is at work
  EXPECT_GT(bc.load(0).impulse.norm(), 0.0);
  bc.clear_impulses();
  EXPECT_EQ(bc.load(0).impulse, Vec3::Zero());
  EXPECT_EQ(bc.load(0).angular_impulse, Vec3::Zero());
}

// Bad input is refused with the field named; removal keeps the order.
TEST(BlockContact, BadBlocksAreRefusedAndRemovalKeepsOrder) {
  BlockContact bad;
  ContactBlock cb;
  cb.half_extents = Vec3(1, 0, 1);
  EXPECT_THROW(bad.add_block(cb), InputError);
  cb = ContactBlock{};
  cb.mass = -1;
  EXPECT_THROW(bad.add_block(cb), InputError);
  cb = ContactBlock{};
  cb.friction = NAN;
  EXPECT_THROW(bad.add_block(cb), InputError);
  cb = ContactBlock{};
  cb.orientation = Quat(0, 0, 0, 0);
  EXPECT_THROW(bad.add_block(cb), InputError);
  cb = ContactBlock{};
  bad.add_block(cb);
  try {
    bad.add_block(cb);
    ADD_FAILURE() << "duplicate id accepted";
  } catch (const InputError& err) {
    std::printf("refused: %s\n", err.what());
  }
  EXPECT_EQ(bad.size(), 1u);
  // Removing a block keeps the others, in order.
  cb.id = 9;
  bad.add_block(cb);
  bad.remove_block(0);
  ASSERT_EQ(bad.size(), 1u);
  EXPECT_EQ(bad.block(0).id, 9u);
}

// 8. Broad phase: the per-call block grid finds exactly the contacts that a brute-force loop over
// every particle and block finds; its cost per call is printed next to an engine step.
TEST(BlockContact, BroadPhaseFindsEveryContactAndItsCostIsPrinted) {
  Ice ice;
  Engine e(make_def(ice, 0.5));
  std::mt19937_64 rng(12345);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  // A 60 x 60 x 8 simple-cubic block of particles (28800), spaced D, with 200 random blocks
  // (0.3-1.5 m half extents) sprinkled through and around it.
  for (int z = 0; z < 8; ++z)
    for (int y = 0; y < 60; ++y)
      for (int x = 0; x < 60; ++x) e.add_particle(sphere(ice, Vec3(x, y, z) * ice.D * 1.0001));
  BlockContact bc;
  for (int k = 0; k < 200; ++k) {
    ContactBlock b;
    b.id = 1000 + k;
    b.half_extents = Vec3(0.3 + 1.2 * u(rng), 0.3 + 1.2 * u(rng), 0.3 + 0.6 * u(rng));
    b.position = Vec3(-3 + 36 * u(rng), -3 + 36 * u(rng), -2 + 8 * u(rng));
    b.orientation = Quat(Eigen::AngleAxisd(kPi * u(rng), Vec3(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5).normalized()));
    bc.add_block(b);
  }
  e.compute_forces();
  const auto t0 = std::chrono::steady_clock::now();
  e.compute_forces();
  const double t_engine_nosrc = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  e.add_force_source(&bc);
  e.compute_forces();
  const auto& ps = e.particles();
  // Brute force: every particle against every block.
  std::size_t brute = 0, found = 0;
  for (std::size_t k = 0; k < bc.size(); ++k) {
    const ContactBlock& b = bc.block(k);
    const Mat3 R = b.orientation.toRotationMatrix();
    for (std::size_t i = 0; i < ps.owned(); ++i) {
      const Vec3 l = R.transpose() * (ps.x[i] - b.position);
      const Vec3 q = l.cwiseMax(-b.half_extents).cwiseMin(b.half_extents);
      brute += (l - q).squaredNorm() < ps.radius[i] * ps.radius[i];
    }
    found += bc.load(k).contacts;
  }
  double best = INFINITY;
  for (int rep = 0; rep < 5; ++rep) {
    e.compute_forces();
    best = std::min(best, bc.stats().seconds);
  }
  std::printf("broad phase: %zu particles, %zu blocks, %zu grid cells, %zu pairs tested, %zu candidates, %zu contacts "
              "(brute force %zu); block contact %.3f ms per call (%.1f ns per particle), engine force "
              "evaluation without it %.3f ms\n",
              ps.owned(), bc.size(), bc.stats().grid_cells, bc.stats().tests, bc.stats().candidates, found, brute, 1e3 * best,
              1e9 * best / static_cast<double>(ps.owned()), 1e3 * t_engine_nosrc);
  EXPECT_GT(brute, 100u);
  EXPECT_EQ(found, brute);
}
