// Shared set-ups of the hybrid-system tests (tests/bridge and the MPI tests in tests/parallel):
// particle ice with E = 1e8 Pa and D = 0.2 m, a dry hybrid definition, a block released above the
// cone's slope, a settled pile of three blocks, the total energy of such a system, and the
// three-point bending run of a beam block (bend()).
#pragma once

#include "bonded/contact_linear.h"
#include "bonded/engine.h"
#include "bonded/hcp_lattice.h"
#include "bridge/hybrid.h"
#include "common/ice_formulas.h"
#include "mesh/pier.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <vector>

namespace hs::test::hybrid {

inline constexpr double kRhoI = 920.0, kD = 0.2, kE = 1e8, kG = 9.81;

/// dt of paper Eq. 2 (alpha 0.1) for this ice.
inline double ice_dt() { return eq2_time_step(0.1, kD, kRhoI, kE); }

/// Particle ice as in the scenes, E = 1e8 Pa (contact overlaps under a block's weight stay small),
/// gravity on, bond damping 0.3 (lattice and freeze bonds alike). `restitution`: particle contacts
/// (Bullet's are plastic, e = 0). dt is left to the caller.
inline bonded::EngineDef ice_def(double restitution) {
  bonded::EngineDef d;
  d.gravity = Vec3(0, 0, -kG);
  d.youngs_modulus = kE;
  d.density = kRhoI;
  d.contact.kn = d.contact.kt = eq1_contact_stiffness(kE, kD);
  d.contact.zeta_n = d.contact.zeta_t = bonded::damping_ratio_from_restitution(restitution);
  d.contact.mu = 0.3;
  const double m = kRhoI * bonded::hcp_cell_volume(kD), I = 0.4 * m * 0.25 * kD * kD;
  d.bond[0] = bonded::ParallelBondParams::from_stiffness(d.contact.kn, d.contact.kn, 0.5 * kD, INFINITY, INFINITY,
                                                         0.3, 0.5 * m, 0.5 * I);
  d.bond[1] = d.bond[0];
  return d;
}

/// No water, ice-ice friction 0.3, converted blocks become this ice, no utilisation filter.
inline bridge::HybridDef dry_hybrid(bridge::ConversionMode mode) {
  bridge::HybridDef d;
  d.mode = mode;
  d.world.water = false;
  d.world.friction = 0.3;
  d.ice.diameter = kD;
  d.block_density = kRhoI;
  d.block_friction = 0.3;
  d.stress_time_constant = 0.0;
  return d;
}

/// One far-away particle, so that an engine with only blocks has something to step.
inline void add_spectator(bonded::Engine& e) {
  bonded::ParticleInit p;
  p.x = Vec3(1000, 1000, 1000);
  p.radius = 0.5 * kD;
  p.mass = kRhoI * bonded::hcp_cell_volume(kD);
  e.add_particle(p);
}

/// The parametric pier (friction 0.1 unless told) as the engine's mesh wall and as the hybrid's
/// structure, with a conversion region around it and a flexural strength so low (2 kPa) that a
/// block converts as soon as the cone pushes on it. Returns the mesh wall's index.
inline int add_cone(bonded::Engine& e, bridge::HybridDef& d, double friction = 0.1) {
  bonded::MeshWallDef md;
  md.mesh = mesh::make_pier(mesh::PierParams{});
  md.friction = friction;
  d.has_structure = true;
  d.structure.vertices = md.mesh.vertices;
  d.structure.triangles = md.mesh.triangles;
  d.structure.triangle_part = md.mesh.triangle_part;
  d.structure.part_count = md.mesh.part_names.size();
  d.structure.friction = friction;
  d.region.shape = bridge::ConversionRegion::Shape::Cylinder;
  d.region.radius = 20.0;
  d.region.z_min = -20.0;
  d.region.z_max = 20.0;
  d.flexural_strength = 2e3;
  return e.add_mesh_wall(md);
}

/// A 1.2 x 0.8 x 0.4 m block at rest, 5 cm above the 52 deg cone's slope on its +x side, half
/// way up, its bottom face parallel to the slope (tilted by the cone angle about y).
inline bridge::BlockInit block_above_cone() {
  const mesh::PierParams pp;
  const double ang = pp.cone_angle_deg * kPi / 180.0;
  const double z0 = 1.0, r0 = mesh::pier_radius_at(pp, z0);
  const Vec3 n(std::sin(ang), 0.0, std::cos(ang));  // outward normal of the slope
  bridge::BlockInit b;
  b.def.half_extents = Vec3(0.6, 0.4, 0.2);
  b.def.orientation = Quat(Eigen::AngleAxisd(ang, Vec3::UnitY()));
  b.def.position = Vec3(r0, 0.0, z0) + (0.2 + 0.05) * n;
  b.def.density = kRhoI;
  return b;
}

/// A fixed 6 x 6 x 1 m floor (top at z = 0) and three 1.0 x 0.6 x 0.4 m blocks stacked
/// crosswise on it, 2 mm apart.
inline std::vector<bridge::BlockInit> pile_blocks() {
  std::vector<bridge::BlockInit> blocks(4);
  blocks[0].def.half_extents = Vec3(3, 3, 0.5);
  blocks[0].def.position = Vec3(0, 0, -0.5);
  blocks[0].def.fixed = true;
  for (int k = 1; k <= 3; ++k) {
    blocks[k].def.half_extents = Vec3(0.5, 0.3, 0.2);
    blocks[k].def.position = Vec3(0.02 * k, 0.0, 0.4 * k - 0.2 + 0.002 * k);
    blocks[k].def.orientation = Quat(Eigen::AngleAxisd(k == 2 ? kPi / 2 : 0.0, Vec3::UnitZ()));
    blocks[k].def.density = kRhoI;
  }
  return blocks;
}

/// Total energy, all ranks: particles (kinetic, gravity, elastic), particle-block contacts and
/// block-particle bonds, rigid blocks' kinetic energy and m g z. Collective under MPI.
inline double total_energy(const bonded::Engine& e, const bridge::HybridSystem& h) {
  double E = e.energy().total() + e.comm().sum(h.coupling_elastic_energy());
  const rigid::RigidWorld& w = *h.world();
  E += w.kinetic_energy();
  for (const rigid::BlockId id : w.blocks())
    if (!w.fixed(id)) E += w.mass(id) * kG * w.position(id).z();
  return E;
}

// ---- Three-point bending (tests/bridge/test_conversion_consistency.cpp and its MPI twin) ----

// Three-point bending. The beam needs several particle layers through its depth to bend, so
// D = 0.1 m here (the set-ups above use 0.2 m: two layers in 0.4 m).
inline constexpr double kDb = 0.1;
// Lattice bonds of the particle ice: tensile strength (normal + bending stress of the parallel
// bond) and shear strength, Pa. Shear twice tension, so that the beam fails in bending.
inline constexpr double kSigmaC = 0.5e6, kTauC = 1.0e6;
// "The beam breaks" = the broken-bond count reaches kCrackBonds, one per lattice row of the
// bottom layer (6 rows across the 0.6 m width): a crack across the tensile face at mid-span.
// The break load is the largest load on the beam up to that step (after the conversion, in
// hybrid mode). Not "the load falls to half its maximum": the lattice beam does not fail in one
// go. Its load peaks as the bottom layer cracks (the first bonds to break are in tension, in the
// bottom layer within 8 cm of mid-span), dips, and then climbs again with the crack arrested in
// the HCP layers above and the two halves wedged together under the indenter. All-particle run
// continued to 1.6 s: 37.0 kN at 6 bonds broken, 35.0 kN at 10, back above 37 kN at 0.96 s,
// 63.0 kN at 1.58 s with 83 bonds broken; no step falls to half the maximum.
inline constexpr std::uint64_t kCrackBonds = 6;

// Particle ice of diameter kDb: lattice bonds with the finite strengths above; freeze bonds
// (used here only inside the load pad, see bend()) unbreakable. No gravity (see bend()).
inline bonded::EngineDef bend_ice_def() {
  bonded::EngineDef d = ice_def(0.05);
  d.gravity = Vec3::Zero();
  d.contact.kn = d.contact.kt = eq1_contact_stiffness(kE, kDb);
  const double m = kRhoI * bonded::hcp_cell_volume(kDb), I = 0.4 * m * 0.25 * kDb * kDb;
  d.bond[0] = bonded::ParallelBondParams::from_stiffness(d.contact.kn, d.contact.kn, 0.5 * kDb, kSigmaC, kTauC, 0.3,
                                                         0.5 * m, 0.5 * I);
  d.bond[1] = bonded::ParallelBondParams::from_stiffness(d.contact.kn, d.contact.kn, 0.5 * kDb, INFINITY, INFINITY,
                                                         0.3, 0.5 * m, 0.5 * I);
  return d;
}

// Axis-aligned closed box [lo, hi]: 12 triangles, counter-clockwise seen from outside, one part.
inline mesh::TriMesh box_mesh(const Vec3& lo, const Vec3& hi) {
  mesh::TriMesh m;
  for (int k = 0; k < 8; ++k)
    m.vertices.emplace_back((k & 1) ? hi.x() : lo.x(), (k & 2) ? hi.y() : lo.y(), (k & 4) ? hi.z() : lo.z());
  const std::uint32_t q[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& f : q) {
    m.triangles.push_back({f[0], f[1], f[2]});
    m.triangles.push_back({f[0], f[2], f[3]});
  }
  m.triangle_part.assign(m.triangles.size(), 0);
  m.part_names = {"indenter"};
  mesh::build_topology(m);
  return m;
}

struct BendResult {
  double peak = 0.0;                 // largest load on the beam (hybrid: after the conversion), N
  double peak_time = 0.0;            // s
  double break_time = -1.0;          // s; < 0: did not break
  double load_at_conversion = -1.0;  // N, the load on the beam in the step the policy converted it
  double conversion_time = -1.0;     // s
  double final_load = 0.0;           // N, at the end of the run
  std::uint64_t conversions = 0, bonds_broken = 0, sites_dropped = 0;
  std::size_t particles = 0;         // all ranks, at the end
  std::vector<double> loads;         // N, the load on the beam after every step
  // Distributed runs (1 and 0 when serial), at the end: ranks that own particles, bonds whose
  // two particles are owned by different ranks.
  std::int64_t ranks_with_particles = 1, bonds_across_ranks = 0;
};

// Three-point bending of a 2.4 m x 0.6 m beam block, 5 particle layers deep (0.43 m), on two
// fixed rigid support blocks 2.0 m apart (centre to centre, each 0.2 m wide), pressed at mid-span
// by a kinematic box indenter (0.2 m x 0.8 m) moving down at 0.04 m/s through a load pad; the
// run stops when the beam breaks (kCrackBonds) or at t_end.
//
// No gravity: the beam starts stress free, and every load on it is the indenter's and the
// supports' reactions. The indenter is both the particles' mesh wall and the rigid world's
// kinematic mesh (the structure). Its loads are those exerted BY the ice ON it, +z when the ice
// is pressed down, so the load on the beam is +(particles' mesh-wall z load + blocks'
// kinematic-mesh z load).
//
// The load pad: one layer of 2 x 6 particles joined by unbreakable bonds, between indenter and
// beam, in every run. Without it the rigid beam of the hybrid run is squeezed between a
// kinematic body and fixed blocks, with no compliance anywhere, and its load is whatever Bullet's
// solver makes of the conflict (tried: 949 kN in the first rigid step of contact, 25 times the
// particle beam's break load, and 2e9 N after 1 s in `never` mode), so the beam converted at a
// meaningless load. With the pad the load on the rigid beam is the pad's contact springs' and
// grows smoothly, as on the particle beam.
//
// The rigid beam is 1 mm deeper at top and bottom than the 5 HCP layers (spacing sqrt(2/3) D)
// that fill it: the converter centres the lattice, so the particle beam has 1 mm of clearance to
// the supports and the pad, and no site of the converted beam comes within contact distance of
// the pad pressing the block's top face (such sites would be dropped; checked: none is).
//
// distribute_over: spread the engine over this communicator's ranks (grid P x 1 x 1, cuts
// across the beam) once the hybrid system is built; every rank then calls bend() together.
inline BendResult bend(bridge::ConversionMode mode, double flexural_strength, double t_end,
                        const par::Comm* distribute_over = nullptr) {
  constexpr double kV = 0.04;  // m/s; quasi-static: the beam's first bending mode is ~16 Hz
  bonded::Engine e(bend_ice_def());
  add_spectator(e);
  const double hz0 = 0.5 * (4.0 * std::sqrt(2.0 / 3.0) * kDb + kDb), hz = hz0 + 1e-3;
  // The pad, 0.1 mm above the block's top face (exactly touching, rounding can make an overlap,
  // and HybridSystem would then move the block clear of the particles).
  const double r = 0.5 * kDb, zp = hz + r + 1e-4;
  const std::size_t pad_first = e.particles().owned();
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 6; ++j) {
      bonded::ParticleInit p;
      p.x = Vec3(-0.05 + 0.1 * i, -0.25 + 0.1 * j, zp);
      p.radius = r;
      p.mass = kRhoI * bonded::hcp_cell_volume(kDb);
      e.add_particle(p);
    }
  e.bond_touching(pad_first, e.particles().owned(), bonded::BondKind::Freeze);
  const double gap = 1e-3;  // indenter above the pad at t = 0
  bonded::MeshWallDef md;
  md.name = "indenter";
  md.mesh = box_mesh(Vec3(-0.1, -0.4, zp + r + gap), Vec3(0.1, 0.4, zp + r + gap + 0.2));
  md.velocity = Vec3(0, 0, -kV);
  md.friction = 0.1;
  const int wall = e.add_mesh_wall(md);
  // 0.09 D sqrt(rho/E) = 2.73e-5 s, below the engine's critical step with the beam (2.87e-5 s),
  // which 0.1 D sqrt(rho/E) (ice_dt(), the set-ups above) exceeds; the same step in every run.
  e.set_dt(eq2_time_step(0.09, kDb, kRhoI, kE));
  bridge::HybridDef d = dry_hybrid(mode);
  d.world.gravity = Vec3::Zero();
  d.ice.diameter = kDb;
  d.has_structure = true;
  d.structure.vertices = md.mesh.vertices;
  d.structure.triangles = md.mesh.triangles;
  d.structure.triangle_part = md.mesh.triangle_part;
  d.structure.part_count = 1;
  d.structure.velocity = md.velocity;
  d.structure.friction = 0.1;
  d.region.shape = bridge::ConversionRegion::Shape::Box;
  d.region.half_extents = Vec3(5, 5, 5);
  d.flexural_strength = flexural_strength;
  std::vector<bridge::BlockInit> blocks(3);
  blocks[0].def.half_extents = Vec3(1.2, 0.3, hz);
  blocks[0].def.density = kRhoI;
  for (int s = 1; s <= 2; ++s) {
    blocks[s].def.half_extents = Vec3(0.1, 0.5, 0.2);
    blocks[s].def.position = Vec3(s == 1 ? -1.0 : 1.0, 0.0, -hz - 0.2);
    blocks[s].def.fixed = true;
  }
  bridge::HybridSystem h(e, d, blocks);
  if (distribute_over) {
    bonded::ParallelDef pd;
    pd.grid = {distribute_over->size(), 1, 1};
    e.distribute(*distribute_over, pd);
  }
  BendResult out;
  std::uint64_t conversions = h.report().conversions;
  const auto n_steps = static_cast<std::uint64_t>(std::llround(t_end / e.dt()));
  for (std::uint64_t k = 0; k < n_steps; ++k) {
    h.step();
    const double F = e.mesh_wall_load(wall).force.z() + h.structure_force().z();
    out.final_load = F;
    out.loads.push_back(F);
    if (h.report().conversions > conversions) {
      conversions = h.report().conversions;
      out.conversion_time = e.time();
      out.load_at_conversion = F;
      out.peak = 0.0;  // the break load is the particle beam's
    }
    if (F > out.peak) {
      out.peak = F;
      out.peak_time = e.time();
    }
    if (e.stats().bonds_broken >= kCrackBonds) {
      out.break_time = e.time();
      break;
    }
  }
  out.conversions = h.report().conversions;
  out.sites_dropped = h.report().sites_dropped;
  out.bonds_broken = e.stats().bonds_broken;
  out.particles = static_cast<std::size_t>(e.global_particle_count());
  std::int64_t n[2] = {e.particles().owned() > 0 ? 1 : 0, 0};
  for (const bonded::Bond& bd : e.bonds()) n[1] += bd.j >= e.particles().owned();
  e.comm().sum(n, 2);
  out.ranks_with_particles = n[0];
  out.bonds_across_ranks = n[1];
  return out;
}

/// The bending test's criteria (issue 6), for a = all particles, b = hybrid, c = never: the
/// hybrid beam converts while loaded and breaks within 0.6 % of the particle beam's break load
/// (measured -0.053 %, serial and at 2 and 3 ranks);
/// the rigid beam never breaks and its load only grows past that.
inline void expect_bending_consistent(const BendResult& a, const BendResult& b, const BendResult& c) {
  ASSERT_GT(a.break_time, 0.0) << "the particle beam must break";
  EXPECT_EQ(a.sites_dropped, 0u);
  EXPECT_EQ(b.conversions, 1u);
  EXPECT_EQ(b.sites_dropped, 0u);
  EXPECT_GT(b.load_at_conversion, 0.0) << "the beam must convert while loaded";
  EXPECT_LT(b.load_at_conversion, a.peak);
  EXPECT_GT(b.break_time, b.conversion_time);
  EXPECT_LT(std::abs((b.peak - a.peak) / a.peak), 6e-3);  // measured -5.3e-4
  EXPECT_EQ(c.conversions, 0u);
  EXPECT_EQ(c.bonds_broken, 0u);
  EXPECT_GT(c.final_load, a.peak) << "the rigid beam carries more than the particle beam broke at";
  EXPECT_GE(c.final_load, c.peak) << "and its load only grows";
}

}  // namespace hs::test::hybrid
