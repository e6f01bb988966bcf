// From a scene to the solver's set-up: every scene value that sim/ hands on (sim::engine_def, the
// engine build_engine makes, sim::block_setup's HybridDef and rigid world, sim::relax_def,
// sim::parallel_def, sim::schedule) arrives where it belongs. Each value in the scene is distinct
// from every other and from its default, so a value dropped (left at its default), taken from the
// wrong field or swapped with another of the same type shows as a mismatch. The derived quantities (the calibrated springs, the contact
// damping) are computed here by the functions the build uses, from the scene's own values.
#include "bonded/contact_linear.h"
#include "common/hcp_geometry.h"
#include "mesh/pier.h"
#include "scene/scene.h"
#include "sim/blocks.h"
#include "sim/build.h"
#include "sim/calibrated_ice.h"
#include "sim/simulation.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

using namespace hs;
using nlohmann::json;

namespace {

// Every field set, each to a value no other field and no default has.
const char* const kScene = R"({
  "name": "wiring",
  "time": {"duration": 0.0617, "dt": 1.237e-5, "dt_alpha": 0.0731, "output_interval": 0.00419,
           "snapshot_interval": 0.0233, "checkpoint_interval": 0.0311},
  "material": {"density": 917.3, "youngs_modulus": 3.217e7, "poisson_ratio": 0.287, "particle_diameter": 0.2531,
               "restitution": 0.413, "friction": 0.347, "contact_model": "hertz", "tensile_strength": 4.31e5},
  "bonds": {"tensile_strength": 6.173e5, "shear_strength": 4.729e5, "damping_ratio": 0.1379, "radius_ratio": 0.8713,
            "freeze_tensile_strength": 2.311e4, "freeze_shear_strength": 1.877e4,
            "compressive_strength_ratio": 7.31, "crushed_contact": "elastic", "crushed_set_depth": 0.377,
            "strength_spread": 0.1931},
  "seed": 4243,
  "water": {"level": 0.0713, "density": 1031.7, "linear_drag_per_area": 1237.1, "drag_coefficient": 0.8317,
            "current": [0.0317, -0.0211, 0.0043]},
  "gravity": [0.0131, -0.0173, -9.7937],
  "ice": {"thickness": 0.6, "length": 1.7, "width": 1.3, "origin": [0.23, -0.41]},
  "walls": [{"name": "w_east", "point": [1.93, 0.1, 0.0], "normal": [-1, 0, 0], "velocity": [-0.0123, 0.0029, 0],
             "friction": 0.1913}],
  "structure": {"name": "cone", "pier": {"waterline_diameter": 2.173, "cone_angle_deg": 47.3, "cone_top_z": 0.71,
                                         "cone_bottom_z": -1.13, "neck_height": 0.53, "shaft_diameter": 1.61,
                                         "shaft_bottom_z": -3.07, "segments": 23},
                "position": [-3.71, 0.29, 0.0713], "velocity": [0.5173, 0.0119, -0.0007], "friction": 0.2297},
  "analysis": {"flexural_strength": 6.791e5},
  "stability": {"max_speed": 83.17, "max_overlap_ratio": 0.4371},
  "parallel": {"grid": [3, 1, 2], "balance_interval": 377, "cost": "time"},
  "blocks": {
    "list": [{"half_extents": [0.31, 0.27, 0.19], "position": [9.7, 5.3, -0.21], "orientation": [0.9, 0.1, -0.2, 0.3],
              "velocity": [0.071, -0.033, 0.017], "angular_velocity": [0.013, 0.029, -0.041]},
             {"half_extents": [0.43, 0.37, 0.23], "position": [12.1, -6.7, -0.17], "fixed": true}],
    "density": 903.7, "friction": 0.4127, "solver_iterations": 37, "fixed_friction_directions": false,
    "friction_sees_torque": true, "rigid_dt": 1.13e-3, "conversion": "all_at_start", "lattice": "world",
    "region": {"offset": [0.31, -0.17, 0.23], "radius": 7.37, "z_min": -2.31, "z_max": 1.17},
    "safety_factor": 1.737, "flexural_strength": 5.113e5, "stress_time_constant": 0.0419,
    "relax": {"max_time": 17.3, "speed": 0.0031, "hold": 0.73, "damping": 0.29, "jointed_time": 1.37,
              "lattice_time": 2.19, "lattice_damping": 0.41, "hold_freeze_bonds": true},
    "far_sleep": {"enabled": true, "wake_distance": 2.71, "speed": 0.0137, "still_time": 0.619, "start_asleep": true,
                  "wake_hops": 7, "loads_wake_neighbours": true, "loads_held": true, "region_awake": false,
                  "zone_wakes_neighbours": false}}
})";

scene::Scene wiring_scene(const json& patch = json::object()) {
  json j = json::parse(kScene);
  j.merge_patch(patch);
  return scene::parse_scene(j, ".");
}

void expect_vec(const Vec3& got, const Vec3& want, const char* what) {
  for (int a = 0; a < 3; ++a) EXPECT_EQ(got[a], want[a]) << what << " component " << a;
}

}  // namespace

// The engine's settings: time step, material, contact and bond laws, water, limits.
TEST(SceneWiring, EngineDefCarriesEverySetting) {
  const scene::Scene s = wiring_scene();
  const bonded::EngineDef d = sim::engine_def(s);
  const sim::CalibratedIce ci = sim::calibrate_ice(s);
  EXPECT_EQ(d.dt, 1.237e-5);
  EXPECT_EQ(d.dt_alpha, 0.0731);
  EXPECT_EQ(d.youngs_modulus, 3.217e7);
  EXPECT_EQ(d.poisson_ratio, 0.287);
  EXPECT_EQ(d.density, 917.3);
  expect_vec(d.gravity, Vec3(0.0131, -0.0173, -9.7937), "gravity");
  EXPECT_EQ(d.contact_model, ContactModel::HertzMindlin);
  // Contacts: the calibrated springs, the restitution's damping ratio, the friction.
  ASSERT_NE(ci.kn, ci.ks);
  EXPECT_EQ(d.contact.kn, ci.kn);
  EXPECT_EQ(d.contact.kt, ci.kn);  // k_t = k_n for contacts
  EXPECT_EQ(d.contact.zeta_n, bonded::damping_ratio_from_restitution(0.413));
  EXPECT_EQ(d.contact.zeta_t, bonded::damping_ratio_from_restitution(0.413));
  EXPECT_EQ(d.contact.mu, 0.347);
  const auto h = bonded::HertzContactParams::from_material(3.217e7, 0.287, 0.413, 0.347);
  EXPECT_EQ(d.hertz.e_star, h.e_star);
  EXPECT_EQ(d.hertz.g_star, h.g_star);
  EXPECT_EQ(d.hertz.beta, h.beta);
  EXPECT_EQ(d.hertz.mu, 0.347);
  // Bonds: the given strengths (explicit bonds.* under "calibrated"), radius, damping, and the pair
  // reduced mass and inertia of two lattice particles.
  EXPECT_EQ(ci.bond_tensile_strength, 6.173e5);
  EXPECT_EQ(ci.bond_shear_strength, 4.729e5);
  const double D = 0.2531, r = 0.5 * D, mass = 917.3 * hcp_cell_volume(D), inertia = 0.4 * mass * r * r;
  const auto lattice =
      bonded::ParallelBondParams::from_stiffness(ci.kn, ci.ks, 0.8713 * r, 6.173e5, 4.729e5, 0.1379, 0.5 * mass, 0.5 * inertia);
  const auto freeze =
      bonded::ParallelBondParams::from_stiffness(ci.kn, ci.ks, 0.8713 * r, 2.311e4, 1.877e4, 0.1379, 0.5 * mass, 0.5 * inertia);
  for (int k = 0; k < 2; ++k) {
    const auto& got = d.bond[k];
    const auto& want = k == 0 ? lattice : freeze;
    SCOPED_TRACE(k == 0 ? "lattice bond" : "freeze bond");
    EXPECT_EQ(got.kn, want.kn);
    EXPECT_EQ(got.ks, want.ks);
    EXPECT_EQ(got.kb, want.kb);
    EXPECT_EQ(got.kt, want.kt);
    EXPECT_EQ(got.gamma_n, want.gamma_n);
    EXPECT_EQ(got.gamma_s, want.gamma_s);
    EXPECT_EQ(got.gamma_b, want.gamma_b);
    EXPECT_EQ(got.gamma_t, want.gamma_t);
    EXPECT_EQ(got.radius, 0.8713 * r);
    EXPECT_EQ(got.sigma_c, k == 0 ? 6.173e5 : 2.311e4);
    EXPECT_EQ(got.tau_c, k == 0 ? 4.729e5 : 1.877e4);
    EXPECT_EQ(got.sigma_cc, 7.31 * 6.173e5);  // crushing is the ice's: the lattice bond's for both kinds
  }
  EXPECT_FALSE(d.crushed_set);  // "elastic"
  EXPECT_EQ(d.crushed_set_depth, 0.377);
  EXPECT_EQ(d.lattice_strength_spread.spread, 0.1931);
  EXPECT_EQ(d.lattice_strength_spread.seed, 4243u);
  EXPECT_TRUE(d.water.enabled);
  EXPECT_EQ(d.water.level, 0.0713);
  EXPECT_EQ(d.water.density, 1031.7);
  EXPECT_EQ(d.water.model, bonded::BuoyancyModel::Column);
  EXPECT_EQ(d.water.linear_drag_per_area, 1237.1);
  EXPECT_EQ(d.water.drag_coefficient, 0.8317);
  expect_vec(d.water.current, Vec3(0.0317, -0.0211, 0.0043), "water current");
  EXPECT_EQ(d.limits.max_speed, 83.17);
  EXPECT_EQ(d.limits.max_overlap_ratio, 0.4371);

  // water.enabled = false reaches the engine.
  EXPECT_FALSE(sim::engine_def(wiring_scene({{"water", {{"enabled", false}}}})).water.enabled);
}

// The built engine: its def is engine_def's, the sheet where the scene puts it, the plane wall and
// the structure (a mesh wall) with their own positions, velocities and frictions.
TEST(SceneWiring, BuiltEngineHasTheWallAndTheStructure) {
  const scene::Scene s = wiring_scene();
  const sim::Built b = sim::build_engine(s, false);
  const bonded::Engine& e = *b.engine;
  EXPECT_EQ(e.def().limits.max_speed, 83.17);
  EXPECT_EQ(e.def().water.density, 1031.7);
  // The sheet: inside the footprint [0.23, 1.93] x [-0.41, 0.89], reaching within D of each edge.
  ASSERT_GT(b.particles, 0u);
  double lo[2] = {1e30, 1e30}, hi[2] = {-1e30, -1e30};
  for (std::size_t i = 0; i < e.particles().size(); ++i)
    for (int a = 0; a < 2; ++a) {
      lo[a] = std::min(lo[a], e.particles().x[i][a]);
      hi[a] = std::max(hi[a], e.particles().x[i][a]);
    }
  const double r = 0.5 * 0.2531;
  EXPECT_GE(lo[0] - r, 0.23 - 1e-9);
  EXPECT_LT(lo[0] - r, 0.23 + 0.2531);
  EXPECT_LE(hi[0] + r, 1.93 + 1e-9);
  EXPECT_GT(hi[0] + r, 1.93 - 0.2531);
  EXPECT_GE(lo[1] - r, -0.41 - 1e-9);
  EXPECT_LT(lo[1] - r, -0.41 + 0.2531);
  EXPECT_LE(hi[1] + r, 0.89 + 1e-9);
  EXPECT_GT(hi[1] + r, 0.89 - 0.2531);
  // The sheet floats in the scene's water: its bottom at level - draft (ice_layout, Column buoyancy).
  const sim::IceLayout L = sim::ice_layout(s);
  const double h = static_cast<double>(L.layers) * hcp_layer_spacing(0.2531);
  EXPECT_NEAR(L.bottom_z, 0.0713 - h * 917.3 / 1031.7, 1e-12);

  ASSERT_EQ(e.walls().size(), 1u);
  const bonded::PlaneWall& w = e.walls()[0];
  EXPECT_EQ(w.name, "w_east");
  expect_vec(w.point, Vec3(1.93, 0.1, 0.0), "wall point");
  expect_vec(w.normal, Vec3(-1, 0, 0), "wall normal");
  expect_vec(w.velocity, Vec3(-0.0123, 0.0029, 0), "wall velocity");
  EXPECT_EQ(w.friction, 0.1913);

  ASSERT_GE(b.structure, 0);
  const bonded::MeshWallDef& m = e.mesh_wall(b.structure);
  EXPECT_EQ(m.name, "cone");
  expect_vec(m.position, Vec3(-3.71, 0.29, 0.0713), "structure position");
  expect_vec(m.velocity, Vec3(0.5173, 0.0119, -0.0007), "structure velocity");
  EXPECT_EQ(m.friction, 0.2297);
  // The pier's shape: make_pier of the scene's parameters, its radius the cone base's.
  mesh::PierParams p;
  p.waterline_diameter = 2.173;
  p.cone_angle_deg = 47.3;
  p.cone_top_z = 0.71;
  p.cone_bottom_z = -1.13;
  p.neck_height = 0.53;
  p.shaft_diameter = 1.61;
  p.shaft_bottom_z = -3.07;
  p.segments = 23;
  const mesh::TriMesh want = mesh::make_pier(p);
  EXPECT_EQ(b.structure_mesh.vertices, want.vertices);  // the mesh as built (the engine keeps its own copy)
  EXPECT_EQ(b.structure_parts, want.part_names);
  EXPECT_EQ(b.structure_radius, mesh::pier_cone_radius(p, -1.13));
}

// The hybrid system's settings and the rigid world's: block material, water, friction, solver,
// freeze joints, conversion policy and region, far sleep, the structure for block contact, the blocks.
TEST(SceneWiring, BlockSetupCarriesEverySetting) {
  const scene::Scene s = wiring_scene();
  const mesh::TriMesh pier = sim::structure_mesh(s);
  const double R = sim::structure_radius(s, pier);
  const sim::BlockSetup b = sim::block_setup(s, &pier, R);
  const bridge::HybridDef& d = b.def;
  EXPECT_EQ(d.mode, bridge::ConversionMode::AllAtStart);
  EXPECT_TRUE(d.ice.world_lattice);
  EXPECT_EQ(d.rigid_dt, 1.13e-3);
  EXPECT_EQ(d.ice.diameter, 0.2531);
  EXPECT_EQ(d.ice.buoyancy, bonded::BuoyancyModel::Column);
  EXPECT_EQ(d.block_density, 903.7);
  EXPECT_EQ(d.block_friction, 0.4127);
  EXPECT_EQ(d.safety_factor, 1.737);
  EXPECT_EQ(d.flexural_strength, 5.113e5);
  EXPECT_EQ(d.stress_time_constant, 0.0419);
  // A particle contact crushing a block face: the lattice bond's compressive strength x its area.
  const double rb = 0.8713 * 0.5 * 0.2531;
  EXPECT_EQ(d.contact_crushing_force, 7.31 * 6.173e5 * kPi * rb * rb);
  const rigid::RigidWorldDef& w = d.world;
  expect_vec(w.gravity, Vec3(0.0131, -0.0173, -9.7937), "rigid gravity");
  EXPECT_TRUE(w.water);
  EXPECT_EQ(w.water_level, 0.0713);
  EXPECT_EQ(w.water_density, 1031.7);  // the sea's, not the ice's (917.3) nor the blocks' (903.7)
  expect_vec(w.water_current, Vec3(0.0317, -0.0211, 0.0043), "rigid water current");
  EXPECT_EQ(w.linear_drag, 1237.1);
  EXPECT_EQ(w.quadratic_drag_cd, 0.8317);
  EXPECT_EQ(w.friction, 0.4127);
  EXPECT_EQ(w.solver_iterations, 37);
  EXPECT_FALSE(w.fixed_friction_directions);
  EXPECT_TRUE(w.friction_sees_torque);
  EXPECT_EQ(w.freeze_bond_strength, 2.311e4);
  EXPECT_EQ(w.freeze_bond_shear_strength, 1.877e4);
  EXPECT_TRUE(w.far_sleep.enabled);
  EXPECT_EQ(w.far_sleep.wake_distance, 2.71);
  EXPECT_EQ(w.far_sleep.speed, 0.0137);
  EXPECT_EQ(w.far_sleep.still_time, 0.619);
  EXPECT_TRUE(w.far_sleep.start_asleep);
  EXPECT_EQ(w.far_sleep.wake_hops, 7);
  EXPECT_TRUE(w.far_sleep.loads_wake_neighbours);
  EXPECT_TRUE(w.far_sleep.loads_held);
  EXPECT_FALSE(w.far_sleep.region_awake);
  EXPECT_FALSE(w.far_sleep.zone_wakes_neighbours);
  // The region moves with the structure: its offset and extent as given.
  EXPECT_EQ(d.region.shape, bridge::ConversionRegion::Shape::Cylinder);
  expect_vec(d.region.offset, Vec3(0.31, -0.17, 0.23), "region offset");
  EXPECT_EQ(d.region.radius, 7.37);
  EXPECT_EQ(d.region.z_min, -2.31);
  EXPECT_EQ(d.region.z_max, 1.17);
  // The structure in the rigid world.
  ASSERT_TRUE(d.has_structure);
  expect_vec(d.structure.position, Vec3(-3.71, 0.29, 0.0713), "rigid structure position");
  expect_vec(d.structure.velocity, Vec3(0.5173, 0.0119, -0.0007), "rigid structure velocity");
  EXPECT_EQ(d.structure.friction, 0.2297);
  EXPECT_EQ(d.structure.vertices, pier.vertices);
  EXPECT_EQ(d.structure.part_count, pier.part_names.size());
  // The blocks, in order, with the blocks' density.
  ASSERT_EQ(b.blocks.size(), 2u);
  const rigid::BlockDef& b0 = b.blocks[0].def;
  expect_vec(b0.half_extents, Vec3(0.31, 0.27, 0.19), "block 0 half extents");
  expect_vec(b0.position, Vec3(9.7, 5.3, -0.21), "block 0 position");
  const Quat q = Quat(0.9, 0.1, -0.2, 0.3).normalized();
  EXPECT_EQ(b0.orientation.coeffs(), q.coeffs());
  expect_vec(b0.velocity, Vec3(0.071, -0.033, 0.017), "block 0 velocity");
  expect_vec(b0.angular_velocity, Vec3(0.013, 0.029, -0.041), "block 0 angular velocity");
  EXPECT_FALSE(b0.fixed);
  EXPECT_EQ(b0.density, 903.7);
  const rigid::BlockDef& b1 = b.blocks[1].def;
  expect_vec(b1.half_extents, Vec3(0.43, 0.37, 0.23), "block 1 half extents");
  expect_vec(b1.position, Vec3(12.1, -6.7, -0.17), "block 1 position");
  EXPECT_TRUE(b1.fixed);
}

// The other branches of the same settings: conversion "hybrid" (its own lattice even with
// lattice "world"), a box region, the default region radius (structure radius + 5 m), freeze
// strengths as a fraction of the lattice bond's, and blocks with the material's density and friction.
TEST(SceneWiring, BlockSetupDefaultsAndFractions) {
  json patch = {{"bonds", {{"freeze_tensile_strength", nullptr}, {"freeze_shear_strength", nullptr},
                           {"freeze_strength_fraction", 0.0731}}},
                {"blocks", {{"conversion", "hybrid"}, {"density", nullptr}, {"friction", nullptr}, {"region", nullptr}}}};
  const scene::Scene s = wiring_scene(patch);
  const mesh::TriMesh pier = sim::structure_mesh(s);
  const double R = sim::structure_radius(s, pier);
  const sim::BlockSetup b = sim::block_setup(s, &pier, R);
  EXPECT_EQ(b.def.mode, bridge::ConversionMode::Hybrid);
  EXPECT_FALSE(b.def.ice.world_lattice);
  EXPECT_EQ(b.def.block_density, 917.3);
  EXPECT_EQ(b.def.block_friction, 0.347);
  EXPECT_EQ(b.def.world.friction, 0.347);
  EXPECT_EQ(b.def.world.water_density, 1031.7);
  EXPECT_EQ(b.blocks[0].def.density, 917.3);
  EXPECT_EQ(b.def.region.radius, R + 5.0);
  // Freeze bonds (rigid joints and the particles' freeze bonds alike) at the fraction.
  EXPECT_EQ(b.def.world.freeze_bond_strength, 0.0731 * 6.173e5);
  EXPECT_EQ(b.def.world.freeze_bond_shear_strength, 0.0731 * 4.729e5);
  const bonded::EngineDef d = sim::engine_def(s);
  EXPECT_EQ(d.bond[1].sigma_c, 0.0731 * 6.173e5);
  EXPECT_EQ(d.bond[1].tau_c, 0.0731 * 4.729e5);

  const scene::Scene box = wiring_scene(
      {{"blocks", {{"region", {{"shape", "box"}, {"offset", {0.11, 0.13, -0.07}}, {"half_extents", {7.1, 6.3, 2.9}}}}}}});
  const bridge::ConversionRegion& g = sim::block_setup(box, &pier, R).def.region;
  EXPECT_EQ(g.shape, bridge::ConversionRegion::Shape::Box);
  expect_vec(g.offset, Vec3(0.11, 0.13, -0.07), "box region offset");
  expect_vec(g.half_extents, Vec3(7.1, 6.3, 2.9), "box region half extents");
}

// The relaxation before the freeze and the spread over the ranks, as build_simulation hands them on.
TEST(SceneWiring, RelaxAndParallelSettings) {
  const scene::Scene s = wiring_scene();
  EXPECT_TRUE(s.blocks.relax.enabled);  // an object turns it on
  const bridge::RelaxDef r = sim::relax_def(s);
  EXPECT_EQ(r.max_time, 17.3);
  EXPECT_EQ(r.speed, 0.0031);
  EXPECT_EQ(r.hold, 0.73);
  EXPECT_EQ(r.damping, 0.29);
  EXPECT_EQ(r.jointed_time, 1.37);
  EXPECT_EQ(r.lattice_time, 2.19);
  EXPECT_EQ(r.lattice_damping, 0.41);
  EXPECT_EQ(r.hold_freeze_bonds, 1u);
  const bonded::ParallelDef p = sim::parallel_def(s);
  EXPECT_EQ(p.grid, (std::array<int, 3>{3, 1, 2}));
  EXPECT_EQ(p.balance_interval, 377u);
  EXPECT_EQ(p.cost, bonded::ParallelDef::Cost::Time);
  EXPECT_EQ(sim::parallel_def(wiring_scene({{"parallel", {{"cost", "work"}}}})).cost, bonded::ParallelDef::Cost::Work);
}

// The schedule: steps of the run and between rows, snapshots and checkpoints.
TEST(SceneWiring, ScheduleFollowsTheTimeSection) {
  const scene::Scene s = wiring_scene();
  const sim::Schedule sc = sim::schedule(s.time, 1.237e-5);
  EXPECT_EQ(sc.dt, 1.237e-5);
  EXPECT_EQ(sc.total_steps, static_cast<std::uint64_t>(std::ceil(0.0617 / 1.237e-5 - 1e-9)));  // 4988
  EXPECT_EQ(sc.output_every, static_cast<std::uint64_t>(std::llround(0.00419 / 1.237e-5)));    // 339
  EXPECT_EQ(sc.snapshot_every, static_cast<std::uint64_t>(std::llround(0.0233 / 1.237e-5)));   // 1884
  EXPECT_EQ(sc.checkpoint_every, static_cast<std::uint64_t>(std::llround(0.0311 / 1.237e-5))); // 2514
}

// blocks.flexural_strength (the conversion's flexural limit, docs/scene.md): given, its own value;
// not given, analysis.flexural_strength whatever the stiffness model, never the calibrated
// lattice's flexural strength; neither given, analysis' default 0.5e6.
TEST(SceneWiring, BlockFlexuralStrengthDefaultsToTheAnalysisValue) {
  const auto limit = [](const scene::Scene& s) { return sim::block_setup(s, nullptr, 0.0).def.flexural_strength; };
  EXPECT_EQ(limit(wiring_scene()), 5.113e5);
  const scene::Scene s = wiring_scene({{"blocks", {{"flexural_strength", nullptr}}}});
  EXPECT_EQ(limit(s), 6.791e5);
  EXPECT_NE(sim::calibrate_ice(s).flexural_strength, 6.791e5);
  // The lattice's strength from a flexural target (no explicit bond strengths, no analysis value).
  const scene::Scene t = wiring_scene({{"bonds", {{"tensile_strength", nullptr}, {"shear_strength", nullptr}}},
                                       {"material", {{"flexural_strength", 3.37e5}}},
                                       {"analysis", nullptr},
                                       {"blocks", {{"flexural_strength", nullptr}}}});
  EXPECT_NEAR(sim::calibrate_ice(t).flexural_strength, 3.37e5, 1e-6);
  EXPECT_EQ(limit(t), 0.5e6);
}
