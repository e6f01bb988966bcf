// Building a scene's engine (moved from src/scene: a scene is definitions only).
#include "sim/build.h"

#include "bonded/hcp_lattice.h"
#include "sim/calibrated_ice.h"
#include "common/error.h"
#include "common/ice_formulas.h"
#include "json/reader.h"
#include "mesh/pier.h"
#include "mesh/sphere_mesh_contact.h"
#include "sim/iso_inputs.h"
#include "sim/ridge_sheet.h"
#include "io/ridge_file.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <optional>
#include <string>

namespace hs::sim {

bonded::EngineDef engine_def(const scene::Scene& s) { return engine_def(s, calibrate_ice(s)); }

bonded::EngineDef engine_def(const scene::Scene& s, const CalibratedIce& ci) {
  using namespace bonded;
  EngineDef d;
  const auto& m = s.material;
  d.dt = s.time.dt;
  d.dt_alpha = s.time.dt_alpha;
  d.youngs_modulus = m.youngs_modulus;
  d.poisson_ratio = m.poisson_ratio;
  d.density = m.density;
  d.gravity = s.gravity;
  d.contact_model = m.contact_model;
  // Springs and bond strengths of the scene's stiffness model (calibrated_ice.h); paper_eq1 gives
  // k_n = k_s = effective_stiffness() and the bonds' strengths exactly as before the model existed.
  const double k = ci.kn, ks = ci.ks;
  d.contact.kn = d.contact.kt = k;
  d.contact.zeta_n = d.contact.zeta_t = damping_ratio_from_restitution(m.restitution);
  d.contact.mu = m.friction;
  d.hertz = HertzContactParams::from_material(m.youngs_modulus, m.poisson_ratio, m.restitution, m.friction);
  // Bonds: pair reduced mass and inertia of two lattice particles.
  const double D = m.particle_diameter, r = 0.5 * D;
  const double mass = m.density * hcp_cell_volume(D);
  const double inertia = 0.4 * mass * r * r;
  const auto& b = s.bonds;
  d.bond[static_cast<int>(BondKind::Lattice)] =
      ParallelBondParams::from_stiffness(k, ks, b.radius_ratio * r, ci.bond_tensile_strength, ci.bond_shear_strength,
                                         b.damping_ratio, 0.5 * mass, 0.5 * inertia);
  d.bond[static_cast<int>(BondKind::Freeze)] =
      ParallelBondParams::from_stiffness(k, ks, b.radius_ratio * r, ci.freeze_tensile_strength,
                                         ci.freeze_shear_strength, b.damping_ratio, 0.5 * mass, 0.5 * inertia);
  // Crushing is the ice's, not the frozen interface's: freeze bonds get the lattice's compressive
  // strength (their weakness is in tension and shear).
  for (const BondKind kind : {BondKind::Lattice, BondKind::Freeze})
    d.bond[static_cast<int>(kind)].sigma_cc = b.compressive_strength_ratio * ci.bond_tensile_strength;
  d.water.enabled = s.water.enabled;
  d.water.level = s.water.level;
  d.water.density = s.water.density;
  d.water.model = BuoyancyModel::Column;
  d.water.linear_drag_per_area = s.water.linear_drag_per_area;
  d.water.drag_coefficient = s.water.drag_coefficient;
  d.water.current = s.water.current;
  d.limits.max_speed = s.stability.max_speed;
  d.limits.max_overlap_ratio = s.stability.max_overlap_ratio;
  d.crushed_set = b.crushed_contact == "set";
  d.crushed_set_depth = b.crushed_set_depth;
  d.lattice_strength_spread = {b.strength_spread, s.seed};
  return d;
}

IceLayout ice_layout(const scene::Scene& s) {
  IceLayout L;
  const double D = s.material.particle_diameter;
  const double c = bonded::hcp_layer_spacing(D);
  L.layers = static_cast<std::size_t>(std::max(1L, std::lround(s.ice.thickness / c)));
  const double h = L.layers * c;
  // Floating at equilibrium (Column buoyancy): draft h rho_i / rho_w, freeboard h (1 - rho_i/rho_w).
  // Without water the sheet rests with its bottom at z = 0.
  const double draft = s.water.enabled ? flotation_draft(h, s.material.density, s.water.density) : 0.0;
  const double level = s.water.enabled ? s.water.level : 0.0;
  L.bottom_z = level - draft;
  L.top_z = L.bottom_z + h;
  if (s.ice.has_consolidated_layer)
    L.consolidated_layers = static_cast<std::size_t>(
        std::max<long>(static_cast<long>(L.layers) + 1, std::lround(s.ice.consolidated_layer.thickness / c)));
  return L;
}

mesh::TriMesh structure_mesh(const scene::Scene& s) {
  if (s.structure.type == "pier") return mesh::make_pier(s.structure.pier);
  try {
    return mesh::load_mesh(s.structure.mesh_path);
  } catch (const InputError& e) {
    throw InputError("/structure/mesh", "cannot use mesh file \"" + s.structure.mesh_path + "\": " + e.what());
  }
}

double structure_radius(const scene::Scene& s, const mesh::TriMesh& m) {
  if (s.structure.type == "pier") return mesh::pier_cone_radius(s.structure.pier, s.structure.pier.cone_bottom_z);
  const mesh::Aabb b = mesh::bounding_box(m);
  return 0.5 * std::max(b.extent().x(), b.extent().y());
}

analysis::IsoInputs iso_inputs(const scene::Scene& s, double rubble_height) {
  IsoMeasured m;
  m.rubble_height = rubble_height;
  return assemble_iso_inputs(s, m).in;
}

double engine_memory_bytes(double particles, double bonds, std::size_t walls) {
  using namespace bonded;
  const double per_particle = 5 * sizeof(Vec3) + sizeof(Quat) + 5 * sizeof(double) + sizeof(GlobalId) +
                              sizeof(MaterialIndex) + 2 + sizeof(Vec3) /*x at build*/ +
                              3 * sizeof(std::uint32_t) /*cells*/ + walls * sizeof(Vec3) /*wall history*/ +
                              32 /*gid index*/ + 4 * sizeof(ContactPair) /*contacts, assumed*/;
  return particles * per_particle + bonds * (sizeof(Bond) + 8 /*partner lists*/);
}

MemoryEstimate memory_estimate(const scene::Scene& s) {
  const auto& ice = s.ice;
  const double D = s.material.particle_diameter;
  const double c = bonded::hcp_layer_spacing(D);
  const double per_layer = ice.length * ice.width / (D * D * std::sqrt(3.0) / 2.0);
  const double thick = std::max(ice.thickness, ice.has_consolidated_layer ? ice.consolidated_layer.thickness : 0.0);
  MemoryEstimate m;
  m.particles = per_layer * std::max(1.0, std::round(thick / c));
  m.bonds = 6.0 * m.particles;
  // The lattice is filled once as a list of centres before the particles are added.
  m.bytes = engine_memory_bytes(m.particles, m.bonds, s.walls.size()) + m.particles * sizeof(Vec3);
  return m;
}

double available_memory_bytes() {
  std::ifstream in("/proc/meminfo");
  std::string key, unit;
  double kb = 0;
  while (in >> key >> kb) {
    std::getline(in, unit);
    if (key == "MemAvailable:") return kb * 1024.0;
  }
  return -1.0;
}

void add_blocks(MemoryEstimate& est, const BlockSetup& b, double particle_diameter, std::size_t walls) {
  est.bytes -= est.block_bytes;  // adding twice replaces
  est.blocks = static_cast<double>(b.blocks.size());
  est.joints = static_cast<double>(b.joints.size() + b.ice_joints.size());
  est.block_particles = 0;
  if (b.def.mode != bridge::ConversionMode::Never) {
    double volume = 0;
    for (const auto& bl : b.blocks)
      if (!bl.def.fixed) volume += 8.0 * bl.def.half_extents.prod();  // fixed boxes (walls) never convert
    est.block_particles = volume / hcp_cell_volume(particle_diameter);
  }
  est.block_bytes = est.blocks * kBytesPerBlock + est.joints * kBytesPerJoint +
                    engine_memory_bytes(est.block_particles, 6.0 * est.block_particles, walls);
  est.bytes += est.block_bytes;
}

void check_memory(const scene::Scene& s, const MemoryEstimate& est, double available, int ranks) {
  if (available < 0) return;
  const double need = est.bytes * std::max(ranks, 1);
  if (need <= available) return;
  const auto gib = [](double b) { return json_fmt(b / 1073741824.0) + " GiB"; };
  const auto& ice = s.ice;
  const bool blocks_dominate = est.block_bytes > est.bytes - est.block_bytes;
  const std::string head =
      "the scene needs about " + gib(need) + " of memory" +
      (ranks > 1 ? " (" + gib(est.bytes) + " on each of " + std::to_string(ranks) +
                       " ranks: every rank builds the whole scene before keeping its share)"
                 : std::string()) +
      " but only " + gib(available) + " is available (MemAvailable in /proc/meminfo): ";
  const std::string ice_part =
      "~" + json_fmt(est.particles) + " particles and ~" + json_fmt(est.bonds) + " bonds from /ice/length = " +
      json_fmt(ice.length) + " m x /ice/width = " + json_fmt(ice.width) + " m x /ice/thickness = " +
      json_fmt(ice.thickness) + " m at /material/particle_diameter = " + json_fmt(s.material.particle_diameter) + " m";
  const std::string block_part =
      gib(est.block_bytes) + " for " + json_fmt(est.blocks) + " rigid blocks and " + json_fmt(est.joints) +
      " joints from /blocks" + (s.blocks.ridge_file.empty() ? "" : "/ridge_file = \"" + s.blocks.ridge_file + "\"") +
      (est.block_particles > 0 ? ", and ~" + json_fmt(est.block_particles) +
                                     " particles if every block is converted (/blocks/conversion = \"" +
                                     s.blocks.conversion + "\")"
                               : std::string());
  const std::string flag = ", or pass --ignore-memory-limit to try anyway";
  if (blocks_dominate)
    throw InputError("/blocks", head + block_part + " (the ice: " + ice_part +
                                    "); keep fewer blocks (/blocks/keep_x, /blocks/keep_y), use a coarser ridge, or "
                                    "set /blocks/conversion to \"never\" if the blocks need not break" + flag);
  throw InputError("/ice", head + ice_part + (est.blocks > 0 ? " (the blocks: " + block_part + ")" : std::string()) +
                               "; reduce the sheet or increase the particle diameter (the count goes as 1/D^3)" +
                               flag);
}

namespace {

/// Solid angle of triangle (a, b, c) seen from the origin (Van Oosterom & Strackee 1983), sr.
double solid_angle(const Vec3& a, const Vec3& b, const Vec3& c) {
  const double la = a.norm(), lb = b.norm(), lc = c.norm();
  const double num = a.dot(b.cross(c));
  const double den = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
  return 2.0 * std::atan2(num, den);
}

/// Whether p (mesh-local) is inside the closed mesh: winding number = total solid angle / 4 pi.
bool inside_closed_mesh(const mesh::TriMesh& m, const Vec3& p) {
  double w = 0.0;
  for (const auto& t : m.triangles)
    w += solid_angle(m.vertices[t[0]] - p, m.vertices[t[1]] - p, m.vertices[t[2]] - p);
  return std::abs(w) > 2.0 * M_PI;
}

}  // namespace

StructureOverlap structure_overlap(const Built& b, const scene::Scene& s) {
  StructureOverlap o;
  if (b.structure < 0) return o;
  const auto& ps = b.engine->particles();
  const Vec3 offset = s.structure.position;
  const mesh::TriMesh& m = b.structure_mesh;
  const mesh::Aabb box = mesh::bounding_box(m);
  double rmax = 0.0;
  for (std::size_t i = 0; i < ps.size(); ++i) rmax = std::max(rmax, ps.radius[i]);
  if (rmax <= 0) return o;
  const bool closed = mesh::is_closed(m);
  const mesh::MeshGrid grid(m, rmax);
  std::vector<mesh::MeshContact> contacts;
  mesh::MeshQueryScratch scratch;
  for (std::size_t i = 0; i < ps.size(); ++i) {
    const double r = ps.radius[i];
    const Vec3 c = ps.x[i] - offset;
    // Only spheres reaching into the mesh's bounding box can touch or be inside it.
    if ((c.array() < box.lo.array() - r).any() || (c.array() > box.hi.array() + r).any()) continue;
    grid.query(c, r, contacts, scratch);
    double deepest = 0.0;
    for (const auto& k : contacts) deepest = std::max(deepest, k.overlap);
    const bool in = closed && inside_closed_mesh(m, c);
    if (deepest <= kInitialOverlapTolerance * r && !in) continue;
    ++o.particles;
    if (in) ++o.inside;
    if (in || deepest >= s.stability.max_overlap_ratio * r) ++o.deep;
    if (in && o.inside == 1 && o.max_overlap == 0) o.first = ps.x[i];
    if (!in && deepest > o.max_overlap) {
      o.max_overlap = deepest;
      o.max_overlap_ratio = deepest / r;
      if (o.inside == 0) o.first = ps.x[i];
    }
  }
  return o;
}

std::string check_structure_overlap(const Built& b, const scene::Scene& s) {
  const StructureOverlap o = structure_overlap(b, s);
  if (o.particles == 0) return "";
  const auto v3 = [](const Vec3& v) {
    return "[" + json_fmt(v.x()) + ", " + json_fmt(v.y()) + ", " + json_fmt(v.z()) + "]";
  };
  const std::string what =
      std::to_string(o.particles) + " ice particles start " + (o.inside ? "inside or " : "") +
      "overlapping the structure '" + s.structure.name + "' at " + v3(s.structure.position) + " m (" +
      (o.inside ? std::to_string(o.inside) + " with the centre inside it; " : std::string()) +
      (o.max_overlap > 0 ? "deepest surface overlap " + json_fmt(o.max_overlap) + " m = " +
                               json_fmt(o.max_overlap_ratio) + " of the radius; "
                         : std::string()) +
      "e.g. the particle at " + v3(o.first) + " m)";
  // A position that clears the sheet along x, on the side the structure comes from (its
  // velocity; -x when it does not move along x): its bounding box one diameter off the edge.
  const mesh::Aabb box = mesh::bounding_box(b.structure_mesh);
  const double D = s.material.particle_diameter;
  const double x0 = s.ice.origin[0], x1 = x0 + s.ice.length;
  const bool from_minus = !(s.structure.velocity.x() < 0);
  const std::string clear = from_minus ? "/structure/position x <= " + json_fmt(x0 - box.hi.x() - D)
                                       : "/structure/position x >= " + json_fmt(x1 - box.lo.x() + D);
  const std::string how = "place the structure clear of the sheet (x from " + json_fmt(x0) + " to " + json_fmt(x1) +
                          " m, y from " + json_fmt(s.ice.origin[1]) + " to " +
                          json_fmt(s.ice.origin[1] + s.ice.width) + " m): move it away from the ice by at least " +
                          "the deepest overlap, or to " + clear + " m (clear of its bounding box), or move /ice/origin";
  if (o.deep == 0)
    return "/structure/position: " + what + "; they are pushed out at the first steps; to start without contact, " +
           how;
  throw InputError("/structure/position", what + ": the load would be wrong from the first step (the run stops as "
                                                 "unstable at overlaps of /stability/max_overlap_ratio = " +
                                              json_fmt(s.stability.max_overlap_ratio) +
                                              " of the radius, and a particle inside the structure is never pushed "
                                              "out). " + std::string(1, static_cast<char>(std::toupper(how[0]))) +
                                              how.substr(1));
}

Built build_engine(const scene::Scene& s, bool check_dt) { return build_engine(s, calibrate_ice(s), check_dt); }

Built build_engine(const scene::Scene& s, const CalibratedIce& ice, bool check_dt) {
  using namespace bonded;
  Built out;
  out.engine = std::make_unique<Engine>(engine_def(s, ice));
  out.calibrated = ice;
  Engine& e = *out.engine;
  const double D = s.material.particle_diameter;
  const double c = hcp_layer_spacing(D);
  const IceLayout L = ice_layout(s);
  out.layout = L;

  // One lattice for the whole sheet. With a consolidated layer the box is as thick as that
  // layer, hanging lower by the number of extra layers its own equilibrium draft needs (a
  // whole number of layers, so the lattice stays continuous), and the level ice keeps only
  // its own layers outside the band. sheet_geometry says where: the ridge generator settles
  // its keel under plates of the same geometry (docs/ridge.md, "Floating plates").
  const SheetGeometry g = sheet_geometry(s);
  const std::size_t total_layers = g.total_layers;
  const double box_bottom = g.box_bottom;
  // A ridge generated under floating plates: the sheet starts where the plates ended (lifted by
  // the keel's net buoyancy), so blocks and sheet start in contact and in equilibrium.
  if (s.has_blocks && !s.blocks.ridge_file_path.empty()) {
    auto r = std::make_shared<rigid::RidgeResult>(io::load_ridge(s.blocks.ridge_file_path));
    check_ridge_generation(*r, s, s.blocks.ridge_file_path);  // made with this run's ice (docs/ridge.md)
    out.ridge = std::move(r);
  }
  const rigid::RidgeResult* ridge = out.ridge.get();
  const Vec3 half(0.5 * s.ice.length, 0.5 * s.ice.width, 0.5 * total_layers * c);
  const Pose pose{Vec3(s.ice.origin[0] + half.x(), s.ice.origin[1] + half.y(), box_bottom + half.z()),
                  Quat::Identity()};
  const auto centres = hcp_fill_box(half, pose, D);

  ParticleInit p;
  p.radius = 0.5 * D;
  p.mass = s.material.density * hcp_cell_volume(D);
  p.buoyant_volume = hcp_cell_volume(D);
  e.particles().reserve(centres.size());
  const double level_lo = L.bottom_z - 0.25 * c, level_hi = L.top_z + 0.25 * c;
  // Keep the spheres that lie wholly inside the footprint, so that walls placed at the
  // sheet's edges (origin, origin + length/width) touch but do not overlap it.
  const double x0 = s.ice.origin[0], x1 = x0 + s.ice.length, y0 = s.ice.origin[1], y1 = y0 + s.ice.width;
  const double r = 0.5 * D, eps = 1e-9 * D;
  for (const auto& x : centres) {
    if (x.x() - r < x0 - eps || x.x() + r > x1 + eps || x.y() - r < y0 - eps || x.y() + r > y1 + eps) continue;
    if (s.ice.has_consolidated_layer) {
      const auto& cl = s.ice.consolidated_layer;
      const bool in_band = std::abs(x.x() - cl.center_x) <= 0.5 * cl.width;
      if (!in_band && (x.z() < level_lo || x.z() > level_hi)) continue;
    }
    p.x = x;
    if (ridge) p.x.z() += sheet_lift(*ridge, x.x() - s.blocks.offset.x());
    e.add_particle(p);
  }
  out.particles = e.particles().size();
  out.lattice_thickness = lattice_mean_thickness(e.particles(), s);
  out.bonds = e.bond_touching(0, e.particles().size(), BondKind::Lattice);

  for (const auto& w : s.walls) e.add_wall(PlaneWall{w.name, w.point, w.normal, w.velocity, w.friction});
  if (s.has_structure) {
    MeshWallDef md;
    md.name = s.structure.name;
    out.structure_mesh = structure_mesh(s);  // the one build of the mesh: the blocks' contact uses it too
    out.structure_radius = structure_radius(s, out.structure_mesh);
    md.mesh = out.structure_mesh;
    md.position = s.structure.position;
    md.velocity = s.structure.velocity;
    md.friction = s.structure.friction;
    out.structure = e.add_mesh_wall(std::move(md));
    out.structure_parts = e.mesh_wall(out.structure).mesh.part_names;
  }
  if (check_dt) e.check_time_step();
  return out;
}


}  // namespace hs::sim
