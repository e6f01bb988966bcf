// One water for blocks and particles (issue 13, item 3): the set-ups of the conversion-consistency
// tests in tests/bridge/test_water_consistency.cpp and their MPI twins in tests/parallel: a
// submerged block released from rest rises to its terminal velocity, and a block towed through
// still water at 0.4 m/s slows down, each as a rigid block (ConversionMode::Never) and as
// particles from the start (AllAtStart), with the same water: c_lin (Pa s/m) and C_d given once
// and handed to the rigid world and to the particle engine alike, as the scene reader does.
#pragma once

#include "hybrid_fixtures.h"
#include "common/ice_formulas.h"

#include <cmath>
#include <cstdint>
#include <vector>

namespace hs::test::water {

using namespace hs::test::hybrid;  // kRhoI, kD, kE, kG, ice_def, ice_dt
inline constexpr double kRhoW = 1025.0;

struct Drag {
  double c_lin = 1000.0;  // Pa s/m (the scenes' default)
  double cd = 1.0;
};

/// The block: 1.2 m x 1.2 m, three HCP layers thick (h = 3 D sqrt(2/3) = 0.490 m), so that the
/// lattice is exactly as thick as the block (docs/bridge.md, "Floating").
inline double block_thickness() { return 3.0 * bonded::hcp_layer_spacing(kD); }
inline Vec3 block_half() { return Vec3(0.6, 0.6, 0.5 * block_thickness()); }

/// Particle ice of hybrid_fixtures with water (Column buoyancy) of the given drag; gravity `g`.
inline bonded::EngineDef wet_ice_def(const Drag& w, const Vec3& g) {
  bonded::EngineDef d = ice_def(0.05);
  d.gravity = g;
  d.water.enabled = true;
  d.water.level = 0.0;
  d.water.density = kRhoW;
  d.water.model = bonded::BuoyancyModel::Column;
  d.water.linear_drag_per_area = w.c_lin;
  d.water.drag_coefficient = w.cd;
  return d;
}

/// The hybrid definition with the same water for the rigid world.
inline bridge::HybridDef wet_hybrid(bridge::ConversionMode mode, const Drag& w, const Vec3& g) {
  bridge::HybridDef d = dry_hybrid(mode);
  d.world.gravity = g;
  d.world.water = true;
  d.world.water_level = 0.0;
  d.world.water_density = kRhoW;
  d.world.linear_drag = w.c_lin;
  d.world.quadratic_drag_cd = w.cd;
  d.ice.buoyancy = bonded::BuoyancyModel::Column;
  return d;
}

/// Velocity of the body: the rigid block's, or the mass-weighted mean of every particle but
/// the frozen spectator (all ranks; collective under MPI).
inline Vec3 body_velocity(const bonded::Engine& e, const bridge::HybridSystem& h) {
  const rigid::RigidWorld& w = *h.world();
  if (!w.blocks().empty()) return w.velocity(w.blocks().front());
  const bonded::ParticleStore& ps = e.particles();
  double s[4] = {0, 0, 0, 0};
  for (std::size_t i = 0; i < ps.owned(); ++i) {
    if (ps.flags[i] & bonded::kFlagFrozen) continue;
    for (int k = 0; k < 3; ++k) s[k] += ps.mass[i] * ps.v[i][k];
    s[3] += ps.mass[i];
  }
  e.comm().sum(s, 4);
  return Vec3(s[0], s[1], s[2]) / s[3];
}

/// A frozen particle far away, dry (the engine needs a particle to step in Never mode).
inline void add_frozen_spectator(bonded::Engine& e) {
  bonded::ParticleInit p;
  p.x = Vec3(1000, 1000, 1000);
  p.radius = 0.5 * kD;
  p.mass = kRhoI * bonded::hcp_cell_volume(kD);
  p.flags = bonded::kFlagFrozen;
  e.add_particle(p);
}

struct Motion {
  std::vector<double> t;       // s, after each rigid step
  std::vector<Vec3> v;         // body velocity, m/s
  std::uint64_t particles = 0; // all ranks (1 = the spectator only: rigid)
  std::int64_t ranks_with_particles = 1;  // ranks owning block particles at the end
};

/// Releases the block (centre z0, velocity v0, at rest otherwise) and follows it for t_end,
/// recording its velocity after every rigid step. distribute_over: spread the engine over the
/// ranks (grid P x 1 x 1, cutting through the block) after the hybrid system is built.
inline Motion release(bridge::ConversionMode mode, const Drag& w, const Vec3& g, double z0, const Vec3& v0,
                      double t_end, const par::Comm* distribute_over = nullptr) {
  bonded::Engine e(wet_ice_def(w, g));
  add_frozen_spectator(e);
  e.set_dt(ice_dt());
  bridge::BlockInit b;
  b.def.half_extents = block_half();
  b.def.position = Vec3(0.0, 0.0, z0);
  b.def.velocity = v0;
  b.def.density = kRhoI;
  bridge::HybridSystem h(e, wet_hybrid(mode, w, g), {b});
  if (distribute_over) {
    bonded::ParallelDef pd;
    pd.grid = {distribute_over->size(), 1, 1};
    e.distribute(*distribute_over, pd);
  }
  Motion out;
  out.particles = static_cast<std::uint64_t>(e.global_particle_count());
  const std::uint64_t k = h.steps_per_rigid_step();
  const auto n = static_cast<std::uint64_t>(std::llround(t_end / e.dt() / k)) * k;
  for (std::uint64_t s = 1; s <= n; ++s) {
    h.step();
    if (s % k) continue;
    out.t.push_back(e.time());
    out.v.push_back(body_velocity(e, h));
  }
  std::int64_t mine = 0;
  for (std::size_t i = 0; i < e.particles().owned(); ++i) mine += !(e.particles().flags[i] & bonded::kFlagFrozen);
  out.ranks_with_particles = e.comm().sum(static_cast<std::int64_t>(mine > 0));
  return out;
}

/// The box law's terminal rise velocity of a block of thickness h fully submerged (top and
/// bottom faces of area A: buoyancy - weight = (rho_w - rho_i) g A h = 2 c_lin A U + 1/2 rho_w
/// C_d A U^2; side faces see no normal flow).
inline double analytic_rise_velocity(const Drag& w, double h) {
  const double a = 0.5 * kRhoW * w.cd, b = 2.0 * w.c_lin, c = -(kRhoW - kRhoI) * kG * h;
  return a > 0.0 ? (-b + std::sqrt(b * b - 4.0 * a * c)) / (2.0 * a) : -c / b;
}

/// The box law's drag on the block moving at U along a face normal whose face has area A.
inline double analytic_drag(const Drag& w, double A, double U) {
  return 2.0 * w.c_lin * A * U + 0.5 * kRhoW * w.cd * A * U * U;
}

/// Mean of v_z over the records with t in [t0, t1].
inline double mean_vz(const Motion& m, double t0, double t1) {
  double s = 0.0;
  int n = 0;
  for (std::size_t i = 0; i < m.t.size(); ++i)
    if (m.t[i] >= t0 && m.t[i] <= t1) s += m.v[i].z(), ++n;
  return s / n;
}

/// Rise: the block's centre starts at z0 = -3 m (top 2.75 m deep), released from rest, 3 s.
inline constexpr double kRiseZ0 = -3.0, kRiseTime = 3.0;
/// Tow: no gravity (no buoyancy either), centre 2 m deep, 0.4 m/s along a face normal; the drag
/// is the body's mean deceleration over the first 0.05 s times its mass.
inline constexpr double kTowSpeed = 0.4, kTowTime = 0.05;

struct Tow {
  std::int64_t ranks_with_particles = 1;
  double force = 0.0;   // N, mean drag over the first kTowTime
  double u_mean = 0.0;  // m/s, mean speed over it
  double cross = 0.0;   // m/s, largest velocity across the tow direction at the end
};

inline Tow tow(bridge::ConversionMode mode, const Drag& w, const Vec3& dir, const par::Comm* distribute_over = nullptr) {
  const double M = kRhoI * 8.0 * block_half().prod();
  const Motion m = release(mode, w, Vec3::Zero(), -2.0, kTowSpeed * dir, kTowTime, distribute_over);
  Tow out;
  const double v1 = m.v.back().dot(dir);
  out.force = M * (kTowSpeed - v1) / m.t.back();
  out.u_mean = 0.5 * (kTowSpeed + v1);
  out.cross = (m.v.back() - v1 * dir).norm();
  out.ranks_with_particles = m.ranks_with_particles;
  return out;
}

}  // namespace hs::test::water
