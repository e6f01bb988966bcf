// Shared set-ups of the hybrid-system tests (tests/bridge and the MPI tests in tests/parallel):
// particle ice with E = 1e8 Pa and D = 0.2 m, a dry hybrid definition, a block released above the
// cone's slope, a settled pile of three blocks, and the total energy of such a system.
#pragma once

#include "bonded/contact_linear.h"
#include "bonded/engine.h"
#include "bonded/hcp_lattice.h"
#include "bridge/hybrid.h"
#include "mesh/pier.h"

#include <cmath>
#include <vector>

namespace hs::test::hybrid {

inline constexpr double kRhoI = 920.0, kD = 0.2, kE = 1e8, kG = 9.81;

/// dt of paper Eq. 2 (alpha 0.1) for this ice.
inline double ice_dt() { return 0.1 * kD * std::sqrt(kRhoI / kE); }

/// Particle ice as in the scenes, E = 1e8 Pa (contact overlaps under a block's weight stay small),
/// gravity on, bond damping 0.3 (lattice and freeze bonds alike). `restitution`: particle contacts
/// (Bullet's are plastic, e = 0). dt is left to the caller.
inline bonded::EngineDef ice_def(double restitution) {
  bonded::EngineDef d;
  d.gravity = Vec3(0, 0, -kG);
  d.youngs_modulus = kE;
  d.density = kRhoI;
  d.contact.kn = d.contact.kt = kPi * kE * kD / 12.0;
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

/// The parametric pier (friction 0.1) as the engine's mesh wall and as the hybrid's structure,
/// with a conversion region around it and a flexural strength so low (2 kPa) that a block
/// converts as soon as the cone pushes on it. Returns the mesh wall's index.
inline int add_cone(bonded::Engine& e, bridge::HybridDef& d) {
  bonded::MeshWallDef md;
  md.mesh = mesh::make_pier(mesh::PierParams{});
  md.friction = 0.1;
  d.has_structure = true;
  d.structure.vertices = md.mesh.vertices;
  d.structure.triangles = md.mesh.triangles;
  d.structure.triangle_part = md.mesh.triangle_part;
  d.structure.part_count = md.mesh.part_names.size();
  d.structure.friction = 0.1;
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

}  // namespace hs::test::hybrid
