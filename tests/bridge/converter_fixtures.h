// Shared set-ups of the converter tests (tests/bridge/test_converter.cpp and the MPI tests in
// tests/parallel): the particle material, the block converted in free flight and the block
// converted while floating at rest, and the runs that measure them. Every figure is computed over
// all ranks of the engine's communicator (a serial engine's is par::serial(): no MPI call), so a
// serial engine and a distributed one go through the same code; with a distributed engine every
// function here is collective.
#pragma once

#include "bonded/engine.h"
#include "bonded/hcp_lattice.h"
#include "bridge/converter.h"
#include "common/ice_formulas.h"

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace hs::test::converter {

inline constexpr double kRhoI = 920.0, kRhoW = 1025.0, kG = 9.81;

struct Material {
  double D = 0.25;
  double E = 1e7;  // modest E: dt = 0.1 D sqrt(rho/E) ~ 7.6e-5 s, runs in seconds
  double kn() const { return eq1_contact_stiffness(E, D); }
  double cell_mass() const { return kRhoI * bonded::hcp_cell_volume(D); }
};

inline bonded::EngineDef engine_def(const Material& mat, double bond_zeta, double contact_restitution) {
  bonded::EngineDef d;
  d.gravity = Vec3::Zero();
  d.youngs_modulus = mat.E;
  d.density = kRhoI;
  d.contact.kn = d.contact.kt = mat.kn();
  if (contact_restitution < 1.0)
    d.contact.zeta_n = d.contact.zeta_t = bonded::damping_ratio_from_restitution(contact_restitution);
  const double m = mat.cell_mass(), I = 0.4 * m * 0.25 * mat.D * mat.D;
  d.bond[0] = bonded::ParallelBondParams::from_stiffness(mat.kn(), mat.kn(), 0.5 * mat.D, INFINITY, INFINITY,
                                                         bond_zeta, 0.5 * m, 0.5 * I);
  return d;
}

inline bridge::IceMaterial ice_material(const Material& mat) {
  bridge::IceMaterial im;
  im.diameter = mat.D;
  return im;
}

/// Centre of mass of the particles with global ids in [from, to), all ranks.
inline Vec3 centre_of_mass(const bonded::Engine& e, GlobalId from, GlobalId to) {
  const auto& p = e.particles();
  double s[4] = {0.0, 0.0, 0.0, 0.0};  // m x, m
  for (std::size_t i = 0; i < p.owned(); ++i) {
    if (p.gid[i] < from || p.gid[i] >= to) continue;
    for (int a = 0; a < 3; ++a) s[a] += p.mass[i] * p.x[i][a];
    s[3] += p.mass[i];
  }
  e.comm().sum(s, 4);
  return Vec3(s[0], s[1], s[2]) / s[3];
}

/// Largest speed of the particles with global ids in [from, to), all ranks.
inline double max_speed(const bonded::Engine& e, GlobalId from, GlobalId to) {
  const auto& p = e.particles();
  double v = 0.0;
  for (std::size_t i = 0; i < p.owned(); ++i)
    if (p.gid[i] >= from && p.gid[i] < to) v = std::max(v, p.v[i].norm());
  return e.comm().max(v);
}

// ---- 1. Free flight: no gravity, no water, undamped bonds ----

inline bonded::EngineDef free_flight_def(const Material& mat) { return engine_def(mat, 0.0, 1.0); }

/// A 2.0 x 1.5 x 1.0 m block, tilted, moving and spinning.
inline bridge::BlockState free_flight_block() {
  bridge::BlockState b;
  b.half_extents = Vec3(1.0, 0.75, 0.5);
  b.pose.position = Vec3(3.0, -2.0, 1.0);
  b.pose.orientation = Quat(Eigen::AngleAxisd(0.4, Vec3(1, 2, 3).normalized()));
  b.velocity = Vec3(0.4, -0.3, 0.2);
  b.angular_velocity = Vec3(0.1, -0.2, 0.15);
  b.density = kRhoI;
  return b;
}

/// The free-flight block converted, measured against the block: momenta by the engine (all
/// ranks, so they include any particle the engine held before), mass and displaced volume of
/// the new particles.
struct FreeFlightConversion {
  bridge::BlockState block;
  bridge::ConversionReport r;
  double M = 0.0, V = 0.0;        // the block's mass and volume
  double msum = 0.0, vsum = 0.0;  // the new particles' mass and buoyant volume
  Vec3 P0 = Vec3::Zero(), L0 = Vec3::Zero();  // the block's momenta (L about the origin)
  Mat3 Ib = Mat3::Zero();                     // its inertia about its centre, world frame
  double dP = 0.0, dL = 0.0, dLc = 0.0;       // relative momentum errors of the engine (dLc: about the centre)
  double ke0 = 0.0, ke1 = 0.0, ke_rot0 = 0.0; // block KE, particles' KE, block's rotational part
  GlobalId first_gid = 0, end_gid = 0;        // the new particles' ids: [first_gid, end_gid)
};

inline FreeFlightConversion convert_free_flight(bonded::Engine& e, const Material& mat) {
  FreeFlightConversion c;
  const bridge::BlockState& b = c.block = free_flight_block();
  c.r = bridge::convert_block(e, b, ice_material(mat));
  c.first_gid = c.r.first_gid;
  c.end_gid = c.r.first_gid + c.r.particles_created;
  const auto& p = e.particles();
  double s[2] = {0.0, 0.0};
  for (std::size_t i = 0; i < p.owned(); ++i)
    if (p.gid[i] >= c.first_gid && p.gid[i] < c.end_gid) {
      s[0] += p.mass[i];
      s[1] += p.buoyant_volume[i];
    }
  e.comm().sum(s, 2);
  c.msum = s[0];
  c.vsum = s[1];
  c.V = 8.0 * b.half_extents.prod();
  c.M = kRhoI * c.V;
  c.P0 = c.M * b.velocity;
  c.Ib = bridge::box_inertia_world(b.half_extents, b.pose.orientation, c.M);
  c.L0 = c.Ib * b.angular_velocity + b.pose.position.cross(c.P0);
  c.dP = (e.linear_momentum() - c.P0).norm() / c.P0.norm();
  c.dL = (e.angular_momentum() - c.L0).norm() / c.L0.norm();
  c.dLc = (e.angular_momentum(b.pose.position) - c.Ib * b.angular_velocity).norm() /
          (c.Ib * b.angular_velocity).norm();
  c.ke_rot0 = 0.5 * b.angular_velocity.dot(c.Ib * b.angular_velocity);
  c.ke0 = 0.5 * c.M * b.velocity.squaredNorm() + c.ke_rot0;
  const auto en = e.energy();
  c.ke1 = en.kinetic_translational + en.kinetic_rotational;
  return c;
}

/// 1 s of free flight: the centre of mass must move on x0 + v t.
struct FreeFlightRun {
  std::uint64_t steps = 0;
  double t = 0.0;
  double path_err = 0.0;  // |COM - (x0 + v t)|, m
  double dL_run = 0.0;    // relative angular momentum error at the end
  std::int64_t bonds = 0; // intact at the end, all ranks
};

inline FreeFlightRun fly(bonded::Engine& e, const FreeFlightConversion& c) {
  e.check_time_step();
  FreeFlightRun out;
  const Vec3 x0 = centre_of_mass(e, c.first_gid, c.end_gid);
  out.steps = static_cast<std::uint64_t>(std::ceil(1.0 / e.dt()));
  e.run(out.steps);
  out.t = e.time();
  out.path_err = (centre_of_mass(e, c.first_gid, c.end_gid) - (x0 + c.block.velocity * out.t)).norm();
  out.dL_run = (e.angular_momentum() - c.L0).norm() / c.L0.norm();
  out.bonds = e.global_bond_count();
  return out;
}

// ---- 2. Floating at rest: gravity, Column buoyancy, heave damped ----

inline constexpr int kFloatingLayers = 2;

/// Block thickness: a whole number of HCP layers, so the lattice's buoyancy column is as tall
/// as the block (docs/bridge.md, "Floating").
inline double floating_thickness(const Material& mat) { return kFloatingLayers * bonded::hcp_layer_spacing(mat.D); }

inline bonded::EngineDef floating_def(const Material& mat) {
  bonded::EngineDef d = engine_def(mat, 0.3, 0.5);
  d.gravity = Vec3(0, 0, -kG);
  d.water.enabled = true;
  d.water.density = kRhoW;
  d.water.model = bonded::BuoyancyModel::Column;
  // Heave of the block critically damped: c_lin = 2 sqrt(rho_w g rho_i h) on its bottom face
  // (box_water.h (5a); docs/engine.md "Water drag").
  const double h = floating_thickness(mat);
  d.water.linear_drag_per_area = 2.0 * std::sqrt(kRhoW * kG * kRhoI * h);
  return d;
}

/// 3 m x 3 m, turned 0.3 rad about z, at its own floating equilibrium, at rest. Cut from the box
/// its A and B layers hold 168 and 156 sites (D = 0.25 m); the converter trims them to equal
/// counts, without which the draft moved by 5 % of the freeboard.
inline bridge::BlockState floating_block(const Material& mat) {
  const double h = floating_thickness(mat), draft = flotation_draft(h, kRhoI, kRhoW);
  bridge::BlockState b;
  b.half_extents = Vec3(1.5, 1.5, 0.5 * h);
  b.pose.position = Vec3(0.0, 0.0, 0.5 * h - draft);
  b.pose.orientation = Quat(Eigen::AngleAxisd(0.3, Vec3::UnitZ()));
  b.density = kRhoI;
  return b;
}

struct FloatingRun {
  bridge::ConversionReport r;
  double h = 0.0, freeboard = 0.0;
  double z0 = 0.0, z1 = 0.0;  // centre of mass height after the conversion and after 1 s, m
  double vmax = 0.0;          // largest particle speed after 1 s, m/s
  double t = 0.0;
  GlobalId first_gid = 0, end_gid = 0;
};

/// Converts the floating block into e and runs 1 s.
inline FloatingRun float_block(bonded::Engine& e, const Material& mat) {
  FloatingRun out;
  out.h = floating_thickness(mat);
  out.freeboard = out.h - flotation_draft(out.h, kRhoI, kRhoW);
  out.r = bridge::convert_block(e, floating_block(mat), ice_material(mat));
  out.first_gid = out.r.first_gid;
  out.end_gid = out.r.first_gid + out.r.particles_created;
  e.check_time_step();
  out.z0 = centre_of_mass(e, out.first_gid, out.end_gid).z();
  e.run(static_cast<std::uint64_t>(std::ceil(1.0 / e.dt())));
  out.t = e.time();
  out.z1 = centre_of_mass(e, out.first_gid, out.end_gid).z();
  out.vmax = max_speed(e, out.first_gid, out.end_gid);
  return out;
}

}  // namespace hs::test::converter
