// Settling an existing ridge again under another ice cover (docs/rigid.md, "The bench's ridge at
// rest"): see resettle_ridge in ridge.h. Its steps: the input checked, then per phase a rigid
// world of the cover, the plates, the obstacle and the blocks (those outside the region held)
// stepped with the generator's speed cap and damping, then the result: blocks renumbered without
// the left-out ones, joints carried with their first block, the plates as the new ice.
#include "ridge/internal.h"

#include "common/error.h"

#include <chrono>

namespace hs::rigid {

namespace {

/// What the phases carry from one to the next: the current poses of the blocks and plates.
struct Resettle {
  const RidgeResult& in;
  const RidgeResettleDef& rd;
  std::vector<RidgeBlock> blocks;  ///< current poses
  std::vector<IceBox> plates;      ///< current poses (rest poses in rd.plates)
  std::vector<Vec3> last_second;   ///< moving blocks' positions one second before the end
  double ke = 0.0, t_total = 0.0, t_end = 0.0;

  Resettle(const RidgeResult& input, const RidgeResettleDef& def)
      : in(input), rd(def), blocks(input.blocks), plates(def.plates) {
    for (const auto& ph : rd.phases) t_end += ph.time;
  }
  bool kept(std::size_t i) const { return rd.keep.empty() || rd.keep[i] != 0; }
  bool moves(std::size_t i) const {
    const Vec3& x = in.blocks[i].position;
    return (x.array() >= rd.region_lo.array()).all() && (x.array() <= rd.region_hi.array()).all();
  }
};

void check_resettle(const RidgeResult& in, const RidgeResettleDef& rd) {
  const std::size_t n = in.blocks.size();
  if (!rd.keep.empty() && rd.keep.size() != n)
    throw InputError("resettle/keep", "must have one flag per block of the ridge (" + std::to_string(n) + ")");
  if (rd.phases.empty()) throw InputError("resettle/phases", "needs at least one phase");
  for (const auto& ph : rd.phases)
    if (!(ph.dt > 0.0) || !(ph.time >= 0.0) || ph.solver_iterations < 1 || !(ph.damping >= 0.0))
      throw InputError("resettle/phases", "each phase needs dt > 0, time >= 0, solver_iterations >= 1, damping >= 0");
}

/// The generator's settle world at the phase's step, without sleep and with every penetration
/// removed by position.
RigidWorldDef phase_world_def(const RidgeDef& d, const RidgeResettleDef::Phase& ph) {
  RidgeDef pd = d;
  pd.settle.dt = ph.dt;
  pd.settle.solver_iterations = ph.solver_iterations;
  pd.settle.allow_sleep = false;  // (Bullet's islands would join the held blocks' neighbours)
  RigidWorldDef wd = detail::settle_world_def(pd);
  // Every penetration removed by position (split impulse) as in the run's world (bridge): at a
  // small step the erp push of a shallow overlap (Bullet's below 4 cm) is a kick (0.2 x 4 cm at
  // 1/240 s: 1.9 m/s), and a block pile that rested at 1/30 s has such overlaps everywhere.
  wd.split_impulse_depth = 0.0;
  return wd;
}

/// The cover (fixed), the plates at their current poses (heave only, joined: the settle world's
/// joints never break) and the obstacle into the world; the plates' ids.
std::vector<BlockId> add_cover(RigidWorld& world, const Resettle& r) {
  const RidgeResettleDef& rd = r.rd;
  const std::vector<IceBox>& plates = r.plates;
  for (const IceBox& b : rd.fixed_boxes) {
    BlockDef bd;
    bd.half_extents = b.half_extents;
    bd.position = b.position;
    bd.fixed = true;
    world.add_block(bd);
  }
  std::vector<BlockId> plate_ids;
  for (std::size_t k = 0; k < plates.size(); ++k) {
    const IceBox& rest = rd.plates[k];
    BlockDef bd;
    bd.half_extents = rest.half_extents;
    bd.position = plates[k].position;
    bd.density = plate_density(rest.position.z() + rest.half_extents.z(), rest.position.z() - rest.half_extents.z(),
                               r.in.def.water_density);
    bd.linear_factor = Vec3::UnitZ();
    bd.angular_factor = Vec3::Zero();
    plate_ids.push_back(world.add_block(bd));
  }
  for (std::size_t k = 0; k + 1 < plates.size(); ++k) {  // joined: the settle world's joints never break
    FreezeJointDef j;
    j.a = plate_ids[k];
    j.b = plate_ids[k + 1];
    j.anchor = 0.5 * (plates[k].position + plates[k + 1].position);
    j.normal = (plates[k + 1].position - plates[k].position).normalized();
    j.area = 1.0;
    world.add_freeze_joint(j);
  }
  if (!rd.obstacle_triangles.empty()) {
    KinematicMeshDef m;
    m.vertices = rd.obstacle_vertices;
    m.triangles = rd.obstacle_triangles;
    m.position = rd.obstacle_position;
    world.add_kinematic_mesh(m);
  }
  return plate_ids;
}

/// The kept blocks at their current poses (those outside the region fixed): ids per block of the
/// input; the moving ones' indices to `moving`.
std::vector<BlockId> add_blocks(RigidWorld& world, const Resettle& r, std::vector<std::size_t>& moving) {
  const std::size_t n = r.in.blocks.size();
  std::vector<BlockId> ids(n);
  for (std::size_t i = 0; i < n; ++i) {
    if (!r.kept(i)) continue;
    BlockDef bd;
    bd.half_extents = r.blocks[i].half_extents;
    bd.position = r.blocks[i].position;
    bd.orientation = r.blocks[i].orientation;
    bd.density = r.in.def.ice_density;
    bd.fixed = !r.moves(i);
    ids[i] = world.add_block(bd);
    if (!bd.fixed) moving.push_back(i);
  }
  return ids;
}

/// One phase: the steps with the speed cap and damping on the moving blocks, progress, then the
/// moving blocks' and plates' poses back into r.
void run_phase(Resettle& r, const RidgeResettleDef::Phase& ph, const RidgeProgressFn& progress) {
  const RidgeDef& d = r.in.def;
  const std::size_t n = r.in.blocks.size();
  const double vcap_h = d.settle.speed_cap_factor * d.block_thickness;  // / dt: the generator's cap
  RigidWorld world(phase_world_def(d, ph));
  const std::vector<BlockId> plate_ids = add_cover(world, r);
  std::vector<std::size_t> moving;
  const std::vector<BlockId> ids = add_blocks(world, r, moving);
  const auto steps = static_cast<std::uint64_t>(std::llround(ph.time / ph.dt));
  const double damp = 1.0 / (1.0 + ph.damping * ph.dt), vcap = vcap_h / ph.dt;
  const std::uint64_t report_every = std::max<std::uint64_t>(1, static_cast<std::uint64_t>(std::lround(0.25 / ph.dt)));
  for (std::uint64_t s = 0; s < steps; ++s) {
    world.substep();
    r.t_total += ph.dt;
    for (const std::size_t i : moving) {
      Vec3 v = world.velocity(ids[i]), w = world.angular_velocity(ids[i]);
      const double sv = v.norm(), sw = w.norm() * r.blocks[i].half_extents.maxCoeff();
      if (sv > vcap) v *= vcap / sv;
      if (sw > vcap) w *= vcap / sw;
      world.set_velocity(ids[i], v * damp, w * damp);
    }
    if (r.last_second.empty() && r.t_total >= r.t_end - 1.0 - 1e-9) {
      r.last_second.assign(n, Vec3::Zero());
      for (const std::size_t i : moving) r.last_second[i] = world.position(ids[i]);
    }
    if ((s + 1) % report_every == 0 || s + 1 == steps) {
      r.ke = world.kinetic_energy() / static_cast<double>(std::max<std::size_t>(1, moving.size()));
      if (progress) {
        RidgeProgress q;
        q.phase = "resettle";
        q.time = r.t_total;
        q.max_time = r.t_end;
        q.kinetic_energy_per_block = r.ke;
        q.blocks = moving.size();
        progress(q);
      }
    }
  }
  for (const std::size_t i : moving) {
    r.blocks[i].position = world.position(ids[i]);
    r.blocks[i].orientation = world.orientation(ids[i]);
    if (r.blocks[i].orientation.w() < 0.0) r.blocks[i].orientation.coeffs() *= -1.0;  // canonical sign
  }
  for (std::size_t k = 0; k < r.plates.size(); ++k) r.plates[k].position = world.position(plate_ids[k]);
}

/// The input's joints into res, renumbered by `index` (-1: block left out, its joints dropped),
/// each anchor and normal carried with its first block; a joint to the ice to the plate nearest
/// its anchor in x (dropped without plates).
void carry_joints(const Resettle& r, const std::vector<std::int32_t>& index, RidgeResult& res,
                  RidgeResettleStats& st) {
  const std::vector<RidgeBlock>& blocks = r.blocks;
  const std::vector<IceBox>& plates = r.plates;
  res.joints.clear();
  for (const RidgeJoint& j : r.in.joints) {
    const auto a = static_cast<std::size_t>(j.a);
    if (index[a] < 0 || (j.b >= 0 && index[static_cast<std::size_t>(j.b)] < 0)) {
      ++st.dropped_joints;
      continue;
    }
    RidgeJoint o = j;
    o.a = index[a];
    if (j.b >= 0) o.b = index[static_cast<std::size_t>(j.b)];
    const Quat dq = blocks[a].orientation * r.in.blocks[a].orientation.conjugate();
    o.anchor = blocks[a].position + dq * (j.anchor - r.in.blocks[a].position);
    o.normal = dq * j.normal;
    if (j.b < 0) {  // to the ice: the result's ice is the plates; the plate nearest the anchor in x
      if (plates.empty()) {
        ++st.dropped_joints;
        continue;
      }
      std::size_t best = 0;
      double dist = std::numeric_limits<double>::infinity();
      for (std::size_t k = 0; k < plates.size(); ++k) {
        const double dx = std::max(0.0, std::abs(o.anchor.x() - plates[k].position.x()) - plates[k].half_extents.x());
        if (dx < dist) dist = dx, best = k;
      }
      o.b = -1 - static_cast<std::int32_t>(best);
    }
    res.joints.push_back(o);
  }
}

/// The result: blocks renumbered without the left-out ones, joints carried, the plates as the ice.
RidgeResult resettled(const Resettle& r, RidgeResettleStats& st) {
  const std::size_t n = r.in.blocks.size();
  RidgeResult res = r.in;
  res.blocks.clear();
  std::vector<std::int32_t> index(n, -1);
  for (std::size_t i = 0; i < n; ++i) {
    if (!r.kept(i)) continue;
    index[i] = static_cast<std::int32_t>(res.blocks.size());
    res.blocks.push_back(r.blocks[i]);
    st.max_displacement = std::max(st.max_displacement, (r.blocks[i].position - r.in.blocks[i].position).norm());
    if (!r.last_second.empty() && r.moves(i))
      st.last_second_max_displacement =
          std::max(st.last_second_max_displacement, (r.blocks[i].position - r.last_second[i]).norm());
  }
  carry_joints(r, index, res, st);
  res.ice.clear();
  for (std::size_t k = 0; k < r.plates.size(); ++k) {
    IceBox b = r.rd.plates[k];
    b.lift = r.plates[k].position.z() - r.rd.plates[k].position.z();
    b.position = r.plates[k].position;
    res.ice.push_back(b);
  }
  if (!r.plates.empty()) {
    res.def.sheet.floating = true;
    res.def.sheet.plates_joined = true;
    st.plate_lift = res.ice.front().lift;
  }
  res.stats.keel_blocks = res.stats.sail_blocks = 0;
  for (const RidgeBlock& b : res.blocks) (b.part == 0 ? res.stats.keel_blocks : res.stats.sail_blocks)++;
  res.stats.joints = res.joints.size();
  res.stats.ice_joints = static_cast<std::size_t>(
      std::count_if(res.joints.begin(), res.joints.end(), [](const RidgeJoint& j) { return j.b < 0; }));
  return res;
}

}  // namespace

RidgeResult resettle_ridge(const RidgeResult& in, const RidgeResettleDef& rd, RidgeResettleStats* stats_out,
                           const RidgeProgressFn& progress) {
  const auto wall0 = std::chrono::steady_clock::now();
  check_resettle(in, rd);
  RidgeResettleStats st;
  Resettle r(in, rd);
  for (std::size_t i = 0; i < in.blocks.size(); ++i) {
    if (!r.kept(i)) ++st.dropped_blocks;
    else if (r.moves(i)) ++st.moving_blocks;
    else ++st.held_blocks;
  }
  for (const auto& ph : rd.phases) run_phase(r, ph, progress);
  st.final_kinetic_energy_per_block = r.ke;
  RidgeResult res = resettled(r, st);
  st.wall_time = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  if (stats_out) *stats_out = st;
  return res;
}

}  // namespace hs::rigid
