#include "sim/blocks.h"

#include "common/error.h"
#include "mesh/pier.h"
#include "sim/calibrated_ice.h"
#include "io/ridge_file.h"
#include "sim/ridge_sheet.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>

namespace hs::sim {

namespace {

/// The hybrid system's settings: rigid world, block material, conversion policy.
bridge::HybridDef hybrid_def(const scene::Scene& s, const CalibratedIce& ci) {
  bridge::HybridDef d;
  const auto& b = s.blocks;
  d.mode = bridge::conversion_mode_from_string(b.conversion);
  d.rigid_dt = b.rigid_dt;
  d.ice.diameter = s.material.particle_diameter;
  d.ice.buoyancy = bonded::BuoyancyModel::Column;
  // The world lattice is all_at_start's: a block converting during a hybrid run is cut from its
  // own lattice whatever blocks.lattice says (docs/bridge.md, "One lattice for a keel ...").
  d.ice.world_lattice = b.lattice == "world" && d.mode == bridge::ConversionMode::AllAtStart;
  d.block_density = b.density > 0.0 ? b.density : s.material.density;
  d.block_friction = b.friction >= 0.0 ? b.friction : s.material.friction;
  rigid::RigidWorldDef& w = d.world;
  w.gravity = s.gravity;
  w.water = s.water.enabled;
  w.water_level = s.water.level;
  w.water_density = s.water.density;
  w.water_current = s.water.current;
  w.linear_drag = s.water.linear_drag_per_area;  // one water for blocks and particles
  w.quadratic_drag_cd = s.water.drag_coefficient;
  w.friction = d.block_friction;
  w.solver_iterations = b.solver_iterations;
  w.solver_tolerance = b.solver_tolerance;
  w.fixed_friction_directions = b.fixed_friction_directions;
  w.friction_sees_torque = b.friction_sees_torque;
  // (ci: freeze strengths may be a fraction of the lattice bond's)
  w.freeze_bond_strength = ci.freeze_tensile_strength;
  w.freeze_bond_shear_strength = ci.freeze_shear_strength;
  d.safety_factor = b.safety_factor;
  d.stress_time_constant = b.stress_time_constant;
  w.far_sleep.enabled = b.far_sleep;
  w.far_sleep.wake_distance = b.far_sleep_wake_distance;
  w.far_sleep.speed = b.far_sleep_speed;
  w.far_sleep.still_time = b.far_sleep_still_time;
  w.far_sleep.start_asleep = b.far_sleep_start_asleep;
  w.far_sleep.wake_hops = b.far_sleep_wake_hops;
  w.far_sleep.loads_wake_neighbours = b.far_sleep_loads_wake_neighbours;
  w.far_sleep.loads_held = b.far_sleep_loads_held;
  w.far_sleep.region_awake = b.far_sleep_region_awake;
  w.far_sleep.zone_wakes_neighbours = b.far_sleep_zone_wakes_neighbours;
  // The conversion's flexural limit: blocks.flexural_strength, whose default is
  // analysis.flexural_strength (scene.cpp, docs/scene.md), not the calibrated lattice's strength.
  d.flexural_strength = b.flexural_strength;
  // The crushing criterion: a particle contact pressing a block as hard as would crush one of the
  // lattice's own bonds (compressive strength x bond area) converts it (criterion_crushing.h).
  // Off when the lattice's bonds do not break in compression.
  if (std::isfinite(s.bonds.compressive_strength_ratio)) {
    const double rb = s.bonds.radius_ratio * 0.5 * s.material.particle_diameter;
    d.contact_crushing_force = s.bonds.compressive_strength_ratio * ci.bond_tensile_strength * kPi * rb * rb;
  }
  return d;
}

bridge::ConversionRegion conversion_region(const scene::ConversionRegionDef& g, double structure_radius) {
  bridge::ConversionRegion r;
  r.shape = g.shape == "box" ? bridge::ConversionRegion::Shape::Box : bridge::ConversionRegion::Shape::Cylinder;
  r.offset = g.offset;
  if (g.shape == "box") r.half_extents = g.half_extents;
  r.radius = g.radius > 0.0 ? g.radius : structure_radius + 5.0;
  r.z_min = g.z_min;
  r.z_max = g.z_max;
  r.validate();
  return r;
}

rigid::KinematicMeshDef kinematic_structure(const scene::StructureDef& st, const mesh::TriMesh& m) {
  rigid::KinematicMeshDef k;
  k.vertices = m.vertices;
  k.triangles = m.triangles;
  k.triangle_part = m.triangle_part;
  k.part_count = std::max<std::size_t>(1, m.part_names.size());
  k.position = st.position;
  k.velocity = st.velocity;
  k.friction = st.friction;
  return k;
}

void add_block(BlockSetup& out, const Vec3& half, const Vec3& x, const Quat& q, const Vec3& v, const Vec3& omega,
               bool fixed = false) {
  bridge::BlockInit bi;
  bi.def.fixed = fixed;
  bi.def.half_extents = half;
  bi.def.position = x;
  bi.def.orientation = q;
  bi.def.velocity = v;
  bi.def.angular_velocity = omega;
  bi.def.density = out.def.block_density;
  out.blocks.push_back(bi);
}

/// The keel as the ridge file gives it (whole ridge, before keep_x / keep_y and the offset):
/// achieved keel depth and porosity (RidgeStats), and the depth of the consolidated layer's
/// underside (its fixed ice boxes; the level ice's without a consolidated layer; the
/// flotation draft of the definition's layer when the file has no ice boxes).
RidgeKeel ridge_keel(const rigid::RidgeResult& r, const std::string& path) {
  RidgeKeel k;
  k.path = path;
  k.keel_depth = r.stats.keel_depth_achieved;
  k.porosity = r.stats.keel_porosity;
  double bottom[2] = {-1.0, -1.0};  // deepest underside of the level ice (0) and the layer (1) boxes
  for (const auto& box : r.ice)
    if (box.part == 0 || box.part == 1)
      bottom[box.part] = std::max(bottom[box.part], -(box.position.z() - box.half_extents.z()));
  k.layer_bottom_depth = bottom[1] >= 0 ? bottom[1]
                         : bottom[0] >= 0 ? bottom[0]
                                          : r.def.consolidated_layer_thickness * r.def.ice_density / r.def.water_density;
  return k;
}

/// The ridge file's blocks inside keep_x / keep_y (and its sail unless keep_sail is false),
/// shifted by the offset, with their joints to each other and to the ice sheet.
void add_ridge_blocks(BlockSetup& out, const scene::Scene& s, const rigid::RidgeResult& r) {
  const auto& b = s.blocks;
  out.ridge_blocks_in_file = r.blocks.size();
  out.ridge = ridge_keel(r, b.ridge_file_path);
  std::vector<long> kept(r.blocks.size(), -1);  // ridge row -> index in out.blocks
  for (std::size_t k = 0; k < r.blocks.size(); ++k) {
    const auto& rb = r.blocks[k];
    const Vec3 x = rb.position + b.offset;
    if (x.x() < b.keep_x[0] || x.x() > b.keep_x[1] || x.y() < b.keep_y[0] || x.y() > b.keep_y[1]) continue;
    if (rb.part == 1 && !b.keep_sail) continue;
    kept[k] = static_cast<long>(out.blocks.size());
    add_block(out, rb.half_extents, x, rb.orientation, Vec3::Zero(), Vec3::Zero());
  }
  for (const auto& j : r.joints) {
    if (j.b < 0) {
      if (kept[j.a] >= 0)
        out.ice_joints.push_back({static_cast<std::size_t>(kept[j.a]), j.anchor + b.offset, j.normal, j.area});
      continue;
    }
    if (kept[j.a] < 0 || kept[j.b] < 0) continue;
    out.joints.push_back({static_cast<std::size_t>(kept[j.a]), static_cast<std::size_t>(kept[j.b]),
                          j.anchor + b.offset, j.normal, j.area});
  }
  if (s.has_ice && std::abs(r.def.level_ice_thickness - s.ice.thickness) > 1e-9) {
    std::ostringstream m;
    m << "/blocks/ridge_file: the ridge was generated under " << r.def.level_ice_thickness
      << " m level ice but the scene's ice is " << s.ice.thickness << " m thick";
    out.warnings.push_back(m.str());
  }
}

/// Keeps the blocks whose flag is set (in order) and the joints between kept blocks, renumbered.
void keep_blocks(BlockSetup& out, const std::vector<char>& keep) {
  std::vector<bridge::BlockInit> kept;
  std::vector<long> index(out.blocks.size(), -1);
  for (std::size_t k = 0; k < out.blocks.size(); ++k)
    if (keep[k]) {
      index[k] = static_cast<long>(kept.size());
      kept.push_back(out.blocks[k]);
    }
  std::vector<bridge::JointInit> joints;
  for (auto j : out.joints)
    if (index[j.a] >= 0 && index[j.b] >= 0) {
      j.a = static_cast<std::size_t>(index[j.a]);
      j.b = static_cast<std::size_t>(index[j.b]);
      joints.push_back(j);
    }
  out.joints = std::move(joints);
  std::vector<bridge::IceJointInit> ice;
  for (auto j : out.ice_joints)
    if (index[j.block] >= 0) {
      j.block = static_cast<std::size_t>(index[j.block]);
      ice.push_back(j);
    }
  out.ice_joints = std::move(ice);
  out.blocks = std::move(kept);
}

/// Ridge blocks frozen to nothing (no joint to another kept block or to the ice: the generator
/// found no face within the joint gap, only edges and corners) are loose rubble that friction
/// alone must hold; in a keel steeper than the friction angle they creep for as long as a
/// relaxation lasts and go on after the freeze (docs/bridge.md, "Relaxation").
/// blocks.loose_blocks = "drop" leaves them out (the default), "keep" keeps them.
void drop_loose_blocks(BlockSetup& out) {
  std::vector<char> jointed(out.blocks.size(), 0);
  for (const auto& j : out.joints) jointed[j.a] = jointed[j.b] = 1;
  for (const auto& j : out.ice_joints) jointed[j.block] = 1;
  for (std::size_t k = 0; k < out.blocks.size(); ++k)
    if (!jointed[k] && !out.blocks[k].def.fixed) ++out.loose_blocks_dropped;
  if (!out.loose_blocks_dropped) return;
  for (std::size_t k = 0; k < out.blocks.size(); ++k) jointed[k] |= out.blocks[k].def.fixed ? 1 : 0;
  keep_blocks(out, jointed);
}

}  // namespace

bool block_reaches_into_pier(const scene::StructureDef& st, const Vec3& half_extents, const Vec3& position) {
  const Vec3 rel = position - st.position;
  const double R = half_extents.norm();
  double r_pier = 0.0;
  for (int q = -4; q <= 4; ++q) r_pier = std::max(r_pier, mesh::pier_radius_at(st.pier, rel.z() + 0.25 * q * R));
  return std::hypot(rel.x(), rel.y()) < r_pier + R;
}

namespace {

/// Blocks that start inside the structure would be pushed out violently (or, as particles,
/// stop the run): a parametric pier is a solid of revolution, so a block is dropped when its
/// bounding sphere reaches inside the pier's radius at any height it spans. Joints follow.
void drop_blocks_inside_pier(BlockSetup& out, const scene::StructureDef& st) {
  std::vector<char> keep(out.blocks.size(), 1);
  std::size_t dropped = 0;
  for (std::size_t k = 0; k < out.blocks.size(); ++k) {
    const auto& bd = out.blocks[k].def;
    if (bd.fixed) continue;  // immovable: nothing to push out (a fixed box reaching into the pier is the scene's choice)
    if (block_reaches_into_pier(st, bd.half_extents, bd.position)) {
      keep[k] = 0;
      ++dropped;
    }
  }
  if (!dropped) return;
  keep_blocks(out, keep);
  out.warnings.push_back("/blocks: " + std::to_string(dropped) +
                         " blocks start inside or touching the pier and were left out; move the structure "
                         "(structure.position) or narrow keep_x / keep_y");
}

}  // namespace

std::optional<RidgeKeel> scene_ridge_keel(const scene::Scene& s) {
  if (!s.has_blocks || s.blocks.ridge_file_path.empty()) return std::nullopt;
  return ridge_keel(io::load_ridge(s.blocks.ridge_file_path), s.blocks.ridge_file_path);
}

BlockSetup block_setup(const scene::Scene& s, const mesh::TriMesh* structure, double structure_radius) {
  return block_setup(s, calibrate_ice(s), structure, structure_radius);
}

BlockSetup block_setup(const scene::Scene& s, const CalibratedIce& ice, const mesh::TriMesh* structure,
                       double structure_radius, const rigid::RidgeResult* ridge) {
  BlockSetup out;
  out.def = hybrid_def(s, ice);
  if (!s.has_blocks) return out;
  out.def.region = conversion_region(s.blocks.region, s.has_structure ? structure_radius : 0.0);
  if (s.has_structure && structure) {
    out.def.has_structure = true;
    out.def.structure = kinematic_structure(s.structure, *structure);
  }
  if (!s.blocks.ridge_file_path.empty()) {
    std::optional<rigid::RidgeResult> own;
    if (!ridge) {
      ridge = &own.emplace(io::load_ridge(s.blocks.ridge_file_path));
      check_ridge_generation(*ridge, s, s.blocks.ridge_file_path);  // made with this run's ice (docs/ridge.md)
    }
    add_ridge_blocks(out, s, *ridge);
    if (s.blocks.loose_blocks == "drop") drop_loose_blocks(out);
  }
  for (const auto& it : s.blocks.list)
    add_block(out, it.half_extents, it.position, it.orientation, it.velocity, it.angular_velocity, it.fixed);
  if (s.has_structure && s.structure.type == "pier") drop_blocks_inside_pier(out, s.structure);
  if (out.blocks.empty() && out.loose_blocks_dropped)
    throw InputError("/blocks/loose_blocks", "no block left: the " + std::to_string(out.loose_blocks_dropped) +
                                                 " ridge blocks kept have no joint and were left out; set \"keep\" "
                                                 "to keep loose blocks");
  if (out.blocks.empty())
    throw InputError("/blocks/keep_x", "no block left: none inside keep_x / keep_y, or all inside the structure");
  return out;
}

}  // namespace hs::sim
