// Conversion consistency (issue 6): a block dropped onto the cone gives the structure the same
// impulse whether it stays rigid, is particles from the start, or converts on contact; a block
// converted inside a settled pile injects < 1 % of m g h.
#include "bridge/hybrid.h"
#include "common/error.h"
#include "mesh/pier.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

using namespace hs;
using namespace hs::bonded;
using hs::bridge::BlockInit;
using hs::bridge::ConversionMode;
using hs::bridge::HybridDef;
using hs::bridge::HybridSystem;

namespace {

constexpr double kRhoI = 920.0, kD = 0.2, kE = 1e8, kG = 9.81;

// Particle ice as in the scenes, E = 1e8 Pa (contact overlaps under a block's weight stay small),
// bond damping 0.3. `restitution`: particle contacts (Bullet's are plastic, e = 0).
EngineDef ice_def(double restitution) {
  EngineDef d;
  d.gravity = Vec3(0, 0, -kG);
  d.youngs_modulus = kE;
  d.density = kRhoI;
  d.contact.kn = d.contact.kt = kPi * kE * kD / 12.0;
  d.contact.zeta_n = d.contact.zeta_t = damping_ratio_from_restitution(restitution);
  d.contact.mu = 0.3;
  const double m = kRhoI * hcp_cell_volume(kD), I = 0.4 * m * 0.25 * kD * kD;
  d.bond[0] = ParallelBondParams::from_stiffness(d.contact.kn, d.contact.kn, 0.5 * kD, INFINITY, INFINITY, 0.3,
                                                 0.5 * m, 0.5 * I);
  d.bond[1] = d.bond[0];
  return d;
}

HybridDef dry_hybrid(ConversionMode mode) {
  HybridDef d;
  d.mode = mode;
  d.world.water = false;
  d.world.friction = 0.3;
  d.ice.diameter = kD;
  d.block_density = kRhoI;
  d.block_friction = 0.3;
  d.stress_time_constant = 0.0;
  return d;
}

void add_spectator(Engine& e) {
  ParticleInit p;
  p.x = Vec3(1000, 1000, 1000);
  p.radius = 0.5 * kD;
  p.mass = kRhoI * hcp_cell_volume(kD);
  e.add_particle(p);
}

struct DropResult {
  Vec3 impulse = Vec3::Zero();  // on the structure, N s
  std::uint64_t conversions = 0;
  double first_conversion_time = -1.0;
};

// A 1.2 x 0.8 x 0.4 m block released 5 cm above the 52 deg cone's slope, its bottom face parallel
// to the slope, at rest; 0.6 s of falling, impact and sliding. Impulse = sum of the structure
// force (particles' mesh-wall load + blocks' kinematic-mesh load) x dt.
DropResult drop_on_cone(ConversionMode mode) {
  Engine e(ice_def(0.05));
  add_spectator(e);
  mesh::PierParams pp;
  MeshWallDef md;
  md.mesh = mesh::make_pier(pp);
  md.friction = 0.1;
  const int wall = e.add_mesh_wall(md);
  e.set_dt(0.1 * kD * std::sqrt(kRhoI / kE));
  HybridDef d = dry_hybrid(mode);
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
  d.flexural_strength = 2e3;  // low: converts as soon as the cone pushes on it
  // On the +x side of the cone, half way up the slope: tilted by the cone angle about y.
  const double ang = pp.cone_angle_deg * kPi / 180.0;
  const double z0 = 1.0, r0 = mesh::pier_radius_at(pp, z0);
  const Vec3 n(std::sin(ang), 0.0, std::cos(ang));  // outward normal of the slope
  BlockInit b;
  b.def.half_extents = Vec3(0.6, 0.4, 0.2);
  b.def.orientation = Quat(Eigen::AngleAxisd(ang, Vec3::UnitY()));
  b.def.position = Vec3(r0, 0.0, z0) + (0.2 + 0.05) * n;
  b.def.density = kRhoI;
  HybridSystem h(e, d, {b});
  DropResult out;
  const auto n_steps = static_cast<std::uint64_t>(std::llround(0.6 / e.dt()));
  for (std::uint64_t k = 0; k < n_steps; ++k) {
    h.step();
    out.impulse += (e.mesh_wall_load(wall).force + h.structure_force()) * e.dt();
    if (out.first_conversion_time < 0 && h.report().conversions > 0) out.first_conversion_time = e.time();
  }
  out.conversions = h.report().conversions;
  return out;
}

}  // namespace

TEST(ConversionConsistency, BlockDroppedOnConeGivesTheSameImpulse) {
  const DropResult rigid = drop_on_cone(ConversionMode::Never);
  const DropResult start = drop_on_cone(ConversionMode::AllAtStart);
  const DropResult contact = drop_on_cone(ConversionMode::Hybrid);
  EXPECT_EQ(rigid.conversions, 0u);
  EXPECT_EQ(start.conversions, 1u);
  EXPECT_EQ(contact.conversions, 1u);
  EXPECT_GT(contact.first_conversion_time, 0.0);
  const double ref = rigid.impulse.norm();
  ASSERT_GT(ref, 100.0) << "the block must have hit the cone";
  const double d_start = (start.impulse - rigid.impulse).norm() / ref;
  const double d_contact = (contact.impulse - rigid.impulse).norm() / ref;
  std::printf("[ consistency ] cone impulse (N s): rigid (%.1f, %.1f, %.1f), at start (%.1f, %.1f, %.1f), on "
              "contact at t = %.3f s (%.1f, %.1f, %.1f); differences %.2f %% and %.2f %% of |rigid|\n",
              rigid.impulse.x(), rigid.impulse.y(), rigid.impulse.z(), start.impulse.x(), start.impulse.y(),
              start.impulse.z(), contact.first_conversion_time, contact.impulse.x(), contact.impulse.y(),
              contact.impulse.z(), 100 * d_start, 100 * d_contact);
  EXPECT_LT(d_start, 0.10);
  EXPECT_LT(d_contact, 0.10);
}

namespace {
double total_energy(const Engine& e, const HybridSystem& h) {
  double E = e.energy().total() + h.coupling_elastic_energy();
  const rigid::RigidWorld& w = *h.world();
  E += w.kinetic_energy();
  for (const rigid::BlockId id : w.blocks())
    if (!w.fixed(id)) E += w.mass(id) * kG * w.position(id).z();
  return E;
}
}  // namespace

TEST(ConversionConsistency, BlockConvertedInASettledPileInjectsLessThanOnePercentOfMgh) {
  // A fixed floor and three 1.0 x 0.6 x 0.4 m blocks stacked crosswise; settle 1.5 s as rigid
  // blocks, convert the middle one, follow 0.5 s. Injected energy = the largest rise of the
  // total energy (rigid KE + PE, particle energy, contact and bond elastic energy) above its
  // value just before the conversion; h = height of the block's centre above the floor.
  Engine e(ice_def(0.05));
  add_spectator(e);
  e.set_dt(0.1 * kD * std::sqrt(kRhoI / kE));
  HybridDef d = dry_hybrid(ConversionMode::Never);
  d.world.linear_drag = 0.0;
  std::vector<BlockInit> blocks(4);
  blocks[0].def.half_extents = Vec3(3, 3, 0.5);
  blocks[0].def.position = Vec3(0, 0, -0.5);
  blocks[0].def.fixed = true;
  for (int k = 1; k <= 3; ++k) {
    blocks[k].def.half_extents = Vec3(0.5, 0.3, 0.2);
    blocks[k].def.position = Vec3(0.02 * k, 0.0, 0.4 * k - 0.2 + 0.002 * k);
    blocks[k].def.orientation = Quat(Eigen::AngleAxisd(k == 2 ? kPi / 2 : 0.0, Vec3::UnitZ()));
    blocks[k].def.density = kRhoI;
  }
  HybridSystem h(e, d, blocks);
  const auto steps = [&](double t) { return static_cast<std::uint64_t>(std::llround(t / e.dt())); };
  for (std::uint64_t k = 0, n = steps(1.5); k < n; ++k) h.step();
  const std::vector<rigid::BlockId> ids = h.world()->blocks();
  const rigid::BlockId middle = ids.at(2);
  const double m = h.world()->mass(middle), hgt = h.world()->position(middle).z();
  const double mgh = m * kG * hgt;
  const double ke_before = h.world()->kinetic_energy();
  const double E0 = total_energy(e, h);
  const auto rep = h.convert(middle);
  const double E_after = total_energy(e, h);
  double E_max = E_after;
  for (std::uint64_t k = 0, n = steps(0.5); k < n; ++k) {
    h.step();
    E_max = std::max(E_max, total_energy(e, h));
  }
  const double injected = E_max - E0;
  std::printf("[ consistency ] pile: rigid KE before %.3e J; middle block (%.1f kg, h = %.3f m, m g h = %.1f J) -> "
              "%zu particles (%zu sites dropped); energy jump at conversion %.3e J, largest rise in 0.5 s %.3e J = "
              "%.3f %% of m g h; energy at the end %.1f J below\n",
              ke_before, m, hgt, mgh, rep.particles_created, rep.particles_dropped, E_after - E0, injected,
              100.0 * injected / mgh, E0 - total_energy(e, h));
  EXPECT_LT(ke_before, 1e-3 * mgh) << "the pile must have settled";
  EXPECT_LT(injected, 0.01 * mgh);
}
