#include "bridge/hybrid.h"
#include "bridge/hybrid_impl.h"

#include "bridge/block_bonds.h"
#include "bridge/block_contact.h"
#include "bridge/conversion_criteria.h"

#include "common/error.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <sstream>

namespace hs::bridge {

namespace {
using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }
}  // namespace

bool sphere_reaches_block(const rigid::RigidWorld& w, rigid::BlockId o, const Vec3& site, double r) {
  const Mat3 R = w.orientation(o).toRotationMatrix();
  const Vec3 l = R.transpose() * (site - w.position(o));
  const Vec3 out = (l.cwiseAbs() - w.half_extents(o)).cwiseMax(0.0);
  return out.norm() < r;  // inside, or closer than r to its surface
}

BlockState block_state(const rigid::RigidWorld& w, rigid::BlockId id) {
  BlockState b;
  b.half_extents = w.half_extents(id);
  b.pose.position = w.position(id);
  b.pose.orientation = w.orientation(id);
  b.velocity = w.velocity(id);
  b.angular_velocity = w.angular_velocity(id);
  b.mass = w.mass(id);
  return b;
}

ConversionMode conversion_mode_from_string(const std::string& s, const std::string& path) {
  if (s == "hybrid") return ConversionMode::Hybrid;
  if (s == "all_at_start") return ConversionMode::AllAtStart;
  if (s == "never") return ConversionMode::Never;
  throw InputError(path, "\"" + s + "\" is not a conversion mode; use \"hybrid\", \"all_at_start\" or \"never\"");
}

const char* to_string(ConversionMode m) {
  switch (m) {
    case ConversionMode::Hybrid: return "hybrid";
    case ConversionMode::AllAtStart: return "all_at_start";
    case ConversionMode::Never: return "never";
  }
  return "?";
}

double block_particle_overlap(const bonded::ParticleStore& ps, const Vec3& half, const Vec3& c, const Quat& q) {
  const Mat3 R = q.toRotationMatrix();
  const double reach = half.norm();
  double worst = 0.0;
  for (std::size_t i = 0; i < ps.owned(); ++i) {
    const Vec3 d = ps.x[i] - c;
    const double r = ps.radius[i];
    if (d.squaredNorm() > (reach + r) * (reach + r)) continue;
    const Vec3 l = R.transpose() * d;
    const Vec3 out = (l.cwiseAbs() - half).cwiseMax(0.0);
    double depth;
    if (out.isZero(0.0))  // centre inside: out through the nearest face
      depth = r + (half - l.cwiseAbs()).minCoeff();
    else
      depth = r - out.norm();
    worst = std::max(worst, depth);
  }
  return worst;
}

Vec3 clearing_shift(const bonded::Engine& engine, const Vec3& half, const Vec3& c, const Quat& q) {
  // A block that starts overlapping particles would be thrown off by the contact springs
  // (energy from nowhere). It is moved clear along the axis direction (+-x, +-y, +-z) that
  // needs the shortest move, each direction in a few passes (a move can uncover other
  // particles), 1 mm to spare: a block under the ice moves down, one touching the side of a
  // thicker band moves sideways, one under a particle above it moves down.
  if (block_particle_overlap(engine.particles(), half, c, q) <= 0.0) return Vec3::Zero();
  const Vec3 dirs[6] = {Vec3(0, 0, -1), Vec3(0, 0, 1), Vec3(1, 0, 0), Vec3(-1, 0, 0), Vec3(0, 1, 0), Vec3(0, -1, 0)};
  Vec3 best = Vec3::Zero();
  double best_len = INFINITY;
  for (const Vec3& dir : dirs) {
    double len = 0.0;
    bool clear = false;
    for (int pass = 0; pass < 8 && len < best_len; ++pass) {
      const double o = block_particle_overlap(engine.particles(), half, c + len * dir, q);
      if (o <= 0.0) {
        clear = true;
        break;
      }
      len += o + 1e-3;
    }
    if (clear && len < best_len) {
      best_len = len;
      best = len * dir;
    }
  }
  return best;
}

double max_rigid_step(const RigidStepInputs& in) {
  if (!(in.min_mass_per_face_area > 0.0) || !(in.particle_diameter > 0.0) || !(in.contact_stiffness > 0.0) ||
      !(in.safety > 0.0))
    throw std::invalid_argument("max_rigid_step: every input must be > 0");
  const double D = in.particle_diameter;
  const double mass_per_contact = in.min_mass_per_face_area * 0.5 * std::sqrt(3.0) * D * D;
  return in.safety * 2.0 * std::sqrt(mass_per_contact / in.contact_stiffness);
}


namespace {

/// The rigid step (docs/bridge.md, "Multi-rate stepping"): the stability rule's limit, checked
/// against the requested step, rounded down to a whole number of DEM steps. Fills the report's
/// rigid_dt_limit, steps_per_rigid_step and rigid_dt.
void choose_rigid_step(const bonded::Engine& engine, const HybridDef& def, const std::vector<BlockInit>& blocks,
                       bool has_freeze_joints, HybridReport& report) {
  RigidStepInputs rs;
  rs.min_mass_per_face_area = INFINITY;
  Vec3 governing = Vec3::Zero();
  for (const auto& b : blocks) {
    if (b.def.fixed) continue;
    const Vec3& h = b.def.half_extents;
    const double face = std::max({4.0 * h.x() * h.y(), 4.0 * h.y() * h.z(), 4.0 * h.x() * h.z()});
    const double mpa = b.def.density * 8.0 * h.prod() / face;
    if (mpa < rs.min_mass_per_face_area) {
      rs.min_mass_per_face_area = mpa;
      governing = 2.0 * h;
    }
  }
  if (!std::isfinite(rs.min_mass_per_face_area)) rs.min_mass_per_face_area = 1e30;  // only fixed blocks
  rs.particle_diameter = def.ice.diameter;
  const auto& ed = engine.def();
  rs.contact_stiffness = bonded::with_contact_law(
      ed, [&](const auto& law) { return law.reference_stiffness(ed.youngs_modulus, def.ice.diameter); });
  rs.safety = def.rigid_dt_safety;
  report.rigid_dt_limit = max_rigid_step(rs);
  const double dt = engine.dt();
  if (!(dt > 0.0))
    throw InputError("/time/dt", "the DEM step is not set (no particles to take it from, paper Eq. 2); give time.dt");
  if (def.rigid_dt > report.rigid_dt_limit * (1.0 + 1e-12)) {
    std::ostringstream msg;
    msg << "rigid step " << def.rigid_dt << " s exceeds the stability limit " << report.rigid_dt_limit
        << " s (thinnest block " << governing.x() << " x " << governing.y() << " x " << governing.z()
        << " m: " << rs.min_mass_per_face_area << " kg per m^2 of its largest face, pressed by close-packed "
        << "particles of D = " << rs.particle_diameter << " m with contact stiffness " << rs.contact_stiffness
        << " N/m; docs/bridge.md, \"Multi-rate stepping\"); set rigid_dt <= " << report.rigid_dt_limit
        << " or 0 to use the limit";
    throw InputError("/blocks/rigid_dt", msg.str());
  }
  const double h_wanted = def.rigid_dt > 0.0 ? def.rigid_dt : report.rigid_dt_limit;
  const auto k = static_cast<std::uint64_t>(std::max(1.0, std::floor(h_wanted / dt + 1e-9)));
  // Block-particle freeze bonds (from ice joints now, or from block joints at conversions) with
  // no damping are negatively damped by the lagging block reaction when k > 1 (docs/bridge.md,
  // "Block-particle freeze bonds", Limits): refused.
  const auto& fb = engine.def().bond[static_cast<int>(bonded::BondKind::Freeze)];
  if (k > 1 && has_freeze_joints && fb.kn > 0.0 && fb.gamma_n == 0.0 && fb.gamma_s == 0.0)
    throw InputError("/bonds/damping_ratio",
                     "block-particle freeze bonds without damping are unstable with a rigid step of " +
                         std::to_string(k) + " DEM steps; set bonds.damping_ratio > 0 (e.g. 0.1) or "
                         "blocks.rigid_dt to the DEM step");
  report.steps_per_rigid_step = k;
  report.rigid_dt = static_cast<double>(k) * dt;
}

/// The rigid world's definition at the chosen rigid step.
rigid::RigidWorldDef hybrid_world_def(const bonded::Engine& engine, const HybridDef& def, double rigid_dt) {
  const auto& fb = engine.def().bond[static_cast<int>(bonded::BondKind::Freeze)];
  rigid::RigidWorldDef wd = def.world;
  wd.dt = rigid_dt;
  // Bullet's position correction pushes at erp x error / dt: keep the push of a 60 Hz world
  // (erp 0.2 at 1/60 s) at the much smaller rigid step, unless the caller set erp.
  const double erp_scaled = std::min(0.2, 0.2 * wd.dt * 60.0);
  if (!(wd.contact_erp > 0.0)) wd.contact_erp = erp_scaled;
  if (!(wd.joint_erp > 0.0)) wd.joint_erp = erp_scaled;
  // Every block-block penetration is removed by split impulse (no momentum, no kinetic energy):
  // a ridge settled at another step rests with overlaps of several cm, and the erp push that
  // removes those at this step would set the keel moving (docs/bridge.md). (Replaces any value
  // in def.world.)
  wd.split_impulse_depth = 0.0;
  // Freeze joints as springs with the stiffness per unit area of the particles' freeze bonds
  // (one bond of normal stiffness k_n per HCP cell face, sqrt(3)/2 D^2): a joint is as stiff as
  // the bonds it becomes at conversion, and its load is its deformation's, not the solver's
  // drift corrections (docs/bridge.md, "Freeze joints between blocks").
  if (!def.rigid_joints && !(wd.joint_stiffness > 0.0) && fb.kn > 0.0)
    wd.joint_stiffness = fb.kn / (0.5 * std::sqrt(3.0) * def.ice.diameter * def.ice.diameter);
  return wd;
}

}  // namespace

HybridSystem::HybridSystem(bonded::Engine& engine, const HybridDef& def, const std::vector<BlockInit>& blocks,
                           const std::vector<JointInit>& joints, const std::vector<IceJointInit>& ice_joints)
    : impl_(std::make_unique<Impl>()), engine_(engine) {
  Impl& m = *impl_;
  m.def = def;
  report_.blocks_initial = blocks.size();
  report_.peak_particles = static_cast<std::int64_t>(engine.particles().owned());
  if (blocks.empty()) return;  // no Bullet world
  // The block-particle bonds made here are a list replicated on every rank; made after
  // distribute() each rank would see only its own particles.
  if (engine.parallel())
    throw std::logic_error("HybridSystem: build it before Engine::distribute() (its freeze bonds are replicated)");
  choose_rigid_step(engine, def, blocks, !ice_joints.empty() || !joints.empty(), report_);
  world_ = std::make_unique<rigid::RigidWorld>(hybrid_world_def(engine, def, report_.rigid_dt));
  // Far sleep's wake-box margin: the largest half diagonal of a block that can move (a fixed wall
  // never enters the region). Set here for both paths: with the relaxation (deferred freeze) it
  // was left at 0.
  for (const auto& b : blocks)
    if (!b.def.fixed) m.wake_reach = std::max(m.wake_reach, b.def.half_extents.norm());
  if (def.defer_freeze) {  // blocks only; relax() makes the rest (relax.cpp)
    m.pending_ids = add_blocks(blocks, {});
    m.pending_joints = joints;
    m.pending_ice_joints = ice_joints;
    // The joints' anchors are material points of the blocks as given (before any clearing
    // shift): freeze() carries them with each block's whole motion since.
    for (const auto& b : blocks) {
      m.x0.push_back(b.def.position);
      m.q0.push_back(b.def.orientation.normalized());
    }
    m.freeze_pending = true;
    m.take_reference(*world_);
    m.extrapolate(world_->time());
    engine.add_force_source(&m.contact);
    engine.add_force_source(&m.bonds);
    m.contact_registered = true;
    return;
  }
  if (def.has_structure) m.mesh = world_->add_kinematic_mesh(def.structure);
  const std::vector<rigid::BlockId> ids = add_blocks(blocks, joints);
  m.take_reference(*world_);
  m.extrapolate(world_->time());
  for (const auto& j : ice_joints)
    report_.ice_bonds_created += m.bonds.bond_patch(engine.particles(), ids.at(j.block).index, j.anchor, j.normal, j.area);
  engine.add_force_source(&m.contact);
  engine.add_force_source(&m.bonds);
  m.contact_registered = true;
  if (def.mode == ConversionMode::AllAtStart) convert_all_at_start();
}

void HybridSystem::convert_all_at_start() {
  for (const rigid::BlockId id : world_->blocks()) {
    if (world_->fixed(id)) continue;
    try {
      convert(id);
    } catch (const InputError&) {  // thinner than D: stays rigid, as in hybrid mode
      ++report_.conversions_refused;
    }
  }
}

std::vector<rigid::BlockId> HybridSystem::add_blocks(const std::vector<BlockInit>& blocks,
                                                     const std::vector<JointInit>& joints) {
  Impl& m = *impl_;
  std::vector<rigid::BlockId> ids;
  ids.reserve(blocks.size());
  for (const auto& b : blocks) {
    rigid::BlockDef bd = b.def;
    if (!bd.fixed) {  // moved clear of the particles
      const Vec3 shift = clearing_shift(engine_, bd.half_extents, bd.position, bd.orientation);
      if (!shift.isZero(0.0)) {
        bd.position += shift;
        ++report_.blocks_moved_clear;
        report_.max_clearing_shift = std::max(report_.max_clearing_shift, shift.norm());
      }
    }
    ids.push_back(world_->add_block(bd));
  }
  for (const auto& j : joints)
    world_->add_freeze_joint(rigid::FreezeJointDef{ids.at(j.a), ids.at(j.b), j.anchor, j.normal, j.area});
  report_.blocks_now = world_->block_count();
  m.coupler.reset(world_->blocks());
  m.ids = world_->blocks();
  for (std::size_t k = 0; k < m.ids.size(); ++k) {  // the particles' view of every block
    const rigid::BlockId id = m.ids[k];
    ContactBlock cb;
    cb.id = (static_cast<std::uint64_t>(id.generation) << 32) | id.index;
    cb.half_extents = world_->half_extents(id);
    cb.position = world_->position(id);
    cb.orientation = world_->orientation(id);
    cb.velocity = world_->velocity(id);
    cb.angular_velocity = world_->angular_velocity(id);
    cb.mass = world_->fixed(id) ? INFINITY : world_->mass(id);
    cb.friction = m.def.block_friction;
    m.contact.add_block(cb);
  }
  return ids;
}

HybridSystem::~HybridSystem() {
  if (impl_ && impl_->contact_registered) {
    engine_.remove_force_source(&impl_->bonds);
    engine_.remove_force_source(&impl_->contact);
  }
}

void HybridSystem::step() {
  Impl& m = *impl_;
  if (world_) {
    // Forces of this step are evaluated at its end: blocks where they will be then.
    const auto tb = Clock::now();
    m.extrapolate(engine_.time() + engine_.dt());
    const bool last_before_rigid = m.since_rigid + 1 >= report_.steps_per_rigid_step;
    const bool policy = m.def.mode == ConversionMode::Hybrid && !m.freeze_pending;  // none while relaxing
    m.contact.set_recording(last_before_rigid && policy);
    m.bonds.set_recording(last_before_rigid && policy);
    report_.seconds_bridge += seconds_since(tb);
  }
  const bonded::ParallelStats& ps = engine_.parallel_stats();
  const double force0 = ps.force_seconds, mpi0 = ps.comm_seconds;
  const auto t0 = Clock::now();
  engine_.step();
  report_.seconds_bonded += seconds_since(t0);
  report_.seconds_bonded_force += ps.force_seconds - force0;
  report_.seconds_bonded_mpi += ps.comm_seconds - mpi0;
  if (!world_) return;
  if (++m.since_rigid < report_.steps_per_rigid_step) return;
  m.since_rigid = 0;
  const auto t1 = Clock::now();
  for (std::size_t k = 0; k < m.ids.size(); ++k) {
    const BlockLoad& L = m.contact.load(k);
    if (!L.impulse.isZero(0.0) || !L.angular_impulse.isZero(0.0))
      m.coupler.add_about_centre(k, L.impulse, L.angular_impulse);
  }
  m.contact.clear_impulses();
  m.bonds.take_impulses(m.bond_lin, m.bond_ang);
  for (std::size_t k = 0; k < m.ids.size(); ++k) {
    const std::uint32_t slot = m.ids[k].index;
    if (slot < m.bond_lin.size() && (!m.bond_lin[slot].isZero(0.0) || !m.bond_ang[slot].isZero(0.0)))
      m.coupler.add_about_centre(k, m.bond_lin[slot], m.bond_ang[slot]);
  }
  const auto t1_mpi = Clock::now();  // the sync point: broken bonds and impulses summed over the ranks
  m.bonds_broken_synced += m.bonds.sync_broken(engine_.comm());
  m.coupler.sum_and_apply(engine_.comm(), *world_);
  if (engine_.parallel()) report_.seconds_bridge_mpi += seconds_since(t1_mpi);
  report_.seconds_bridge += seconds_since(t1);
  const auto t2 = Clock::now();
  if (m.def.world.far_sleep.enabled && m.def.world.far_sleep.region_awake && m.def.mode == ConversionMode::Hybrid &&
      m.mesh >= 0) {
    // Far sleep: blocks that the conversion policy may look at stay awake (their loads are read).
    const ConversionRegion& rg = m.def.region;
    const Vec3 c = world_->mesh_position(m.mesh) + rg.offset;
    const Vec3 half = rg.shape == ConversionRegion::Shape::Box ? rg.half_extents : Vec3(rg.radius, rg.radius, 0.0);
    Vec3 lo = c - half, hi = c + half;
    if (rg.shape == ConversionRegion::Shape::Cylinder) {
      lo.z() = c.z() + rg.z_min;
      hi.z() = c.z() + rg.z_max;
    }
    const Vec3 grow = Vec3::Constant(m.wake_reach + m.def.world.far_sleep.wake_distance);
    world_->set_wake_boxes({{lo - grow, hi + grow}});
  }
  world_->substep();
  ++report_.rigid_steps;
  m.take_reference(*world_);
  report_.seconds_rigid += seconds_since(t2);
  const auto t3 = Clock::now();
  if (m.def.mode == ConversionMode::Hybrid && !m.freeze_pending) apply_policy();
  report_.blocks_now = world_->block_count();
  const auto t4 = Clock::now();
  report_.peak_particles = std::max(report_.peak_particles, engine_.global_particle_count());  // collective
  const auto t5 = Clock::now();
  if (engine_.parallel()) report_.seconds_bridge_mpi += std::chrono::duration<double>(t5 - t4).count();
  report_.seconds_bridge += std::chrono::duration<double>(t5 - t3).count();
}

namespace {

/// Every rank's records gathered on rank 0 (serial: a copy). T is copied as bytes (plain
/// records of integers, doubles and Eigen fixed-size vectors; its padding goes along unread).
template <class T>
std::vector<T> gathered_on_root(const par::Comm& comm, const std::vector<T>& rec) {
  par::Bytes mine(rec.size() * sizeof(T));
  if (!rec.empty()) std::memcpy(static_cast<void*>(mine.data()), rec.data(), mine.size());
  const par::Bytes all = comm.parallel() ? comm.gather(mine) : mine;
  std::vector<T> out(all.size() / sizeof(T));
  if (!out.empty()) std::memcpy(static_cast<void*>(out.data()), all.data(), out.size() * sizeof(T));
  return out;
}

/// The particle side's loads on the blocks in the last force evaluation, gathered on rank 0.
/// Under MPI each rank holds the contacts and block-particle bonds of its own particles.
struct ParticleSideLoads {
  std::vector<std::vector<PointLoad>> contact;  ///< by contact block k (the world's slot order)
  std::vector<std::vector<PointLoad>> bond;     ///< by block slot (BlockParticleBonds' numbering)
  std::vector<double> bond_u_tension, bond_u_shear;  ///< by block slot: the largest of its bonds
};

ParticleSideLoads gather_particle_side_loads(const par::Comm& comm, const BlockContact& contact,
                                             const BlockParticleBonds& bonds, std::size_t n_blocks) {
  ParticleSideLoads g;
  g.contact.resize(n_blocks);
  for (const auto& pf : gathered_on_root(comm, contact.recorded())) g.contact[pf.block].push_back({pf.point, pf.force});
  for (const auto& bf : gathered_on_root(comm, bonds.recorded())) {
    if (g.bond.size() <= bf.block) {
      g.bond.resize(bf.block + 1);
      g.bond_u_tension.resize(bf.block + 1, 0.0);
      g.bond_u_shear.resize(bf.block + 1, 0.0);
    }
    g.bond[bf.block].push_back({bf.point, bf.force});
    g.bond_u_tension[bf.block] = std::max(g.bond_u_tension[bf.block], bf.u_tension);
    g.bond_u_shear[bf.block] = std::max(g.bond_u_shear[bf.block], bf.u_shear);
  }
  return g;
}

/// Block `id` (contact block k)'s loads for the conversion criteria, written over `out`: its joints
/// and rigid contacts from the world, then the particle side's contacts and bonds.
void collect_block_loads(const rigid::RigidWorld& world, rigid::BlockId id, std::size_t k,
                         const ParticleSideLoads& g, BlockLoads& out) {
  out.box = BlockBox{world.half_extents(id), world.position(id), world.orientation(id)};
  out.joints.clear();
  for (const rigid::JointId j : world.joints_of(id)) {
    const rigid::JointLoad L = world.joint_load(j);
    out.joints.push_back({L.tension, L.shear, world.joint_area(j)});
  }
  out.loads.clear();
  for (const auto& c : world.contact_forces(id)) out.loads.push_back({c.point, c.force});
  out.particle_contact_force = 0.0;
  for (const auto& pf : g.contact[k]) {
    out.loads.push_back(pf);
    out.particle_contact_force = std::max(out.particle_contact_force, pf.force.norm());
  }
  out.bond_u_tension = out.bond_u_shear = 0.0;
  if (id.index < g.bond.size()) {
    for (const auto& bf : g.bond[id.index]) out.loads.push_back(bf);
    out.bond_u_tension = g.bond_u_tension[id.index];
    out.bond_u_shear = g.bond_u_shear[id.index];
  }
}

/// Rank 0's decisions to every rank: (slot, generation, governing criterion) triples.
void share_decisions(const par::Comm& comm, std::vector<rigid::BlockId>& to_convert, std::vector<int>& governing) {
  std::string msg;
  if (comm.rank() == 0)
    for (std::size_t k = 0; k < to_convert.size(); ++k) {
      const std::uint32_t rec3[3] = {to_convert[k].index, to_convert[k].generation,
                                     static_cast<std::uint32_t>(governing[k])};
      msg.append(reinterpret_cast<const char*>(rec3), sizeof rec3);
    }
  msg = comm.broadcast(msg);
  to_convert.clear();
  governing.clear();
  for (std::size_t o = 0; o + 12 <= msg.size(); o += 12) {
    std::uint32_t rec3[3];
    std::memcpy(rec3, msg.data() + o, sizeof rec3);
    to_convert.push_back(rigid::BlockId{rec3[0], rec3[1]});
    governing.push_back(static_cast<int>(rec3[2]));
  }
}

/// One conversion governed by criterion c (conversion_criteria()).
void count_conversion(HybridReport& r, int c) {
  const auto k = static_cast<std::size_t>(c);
  if (r.conversions_by_criterion.size() <= k) r.conversions_by_criterion.resize(conversion_criteria().size(), 0);
  ++r.conversions_by_criterion[k];
  if (k == kFreezeBondCriterion) ++r.conversions_freeze;
  if (k == kFlexureCriterion) ++r.conversions_flexure;
}

}  // namespace

void HybridSystem::apply_policy() {
  Impl& m = *impl_;
  const Vec3 sp = m.mesh >= 0 ? world_->mesh_position(m.mesh) : Vec3::Zero();
  ConversionStrengths strengths;
  strengths.freeze = {m.def.world.freeze_bond_strength, m.def.world.freeze_bond_shear_strength < 0.0
                                                            ? m.def.world.freeze_bond_strength
                                                            : m.def.world.freeze_bond_shear_strength};
  strengths.flexural_strength = m.def.flexural_strength;
  strengths.contact_crushing_force = m.def.contact_crushing_force;
  // Rank 0 gathers the particle side's loads, decides, and broadcasts the list of blocks to
  // convert, so that every rank's replicated world converts the same blocks. The block-particle
  // freeze bonds' forces are loads for the flexural criterion, and their stress over strength
  // counts in the freeze-bond criterion beside the joints'.
  // Timed in parts (HybridReport): the gather and the broadcast (MPI waits under MPI; serial, the
  // gather is a copy, counted with the stress estimates), the stress estimates, the decisions and
  // the conversions.
  const par::Comm& comm = engine_.comm();
  auto lap = Clock::now();
  const auto add_lap = [&lap](double& to) {
    const auto now = Clock::now();
    to += std::chrono::duration<double>(now - lap).count();
    lap = now;
  };
  const ParticleSideLoads gathered = gather_particle_side_loads(comm, m.contact, m.bonds, m.ids.size());
  if (comm.parallel()) add_lap(report_.seconds_bridge_mpi);
  std::vector<rigid::BlockId> to_convert;
  std::vector<int> governing;  // index into conversion_criteria()
  BlockLoads block;
  const bool decide_here = comm.rank() == 0;
  // The stress estimates of the blocks in the region (m.ids is the world's block list, slot order;
  // k indexes it, the contact blocks and the loads), then the decisions on them.
  std::vector<std::pair<std::size_t, ConversionDecision>> estimates;
  for (std::size_t k = 0; decide_here && k < m.ids.size(); ++k) {
    const rigid::BlockId id = m.ids[k];
    if (world_->fixed(id)) continue;  // fixed blocks are walls and floors, not ice
    if (id.index < m.unconvertible.size() && m.unconvertible[id.index]) continue;
    if (!m.def.region.contains_block(sp, world_->position(id), world_->half_extents(id))) continue;
    collect_block_loads(*world_, id, k, gathered, block);
    estimates.emplace_back(k, evaluate_criteria(block, strengths));
  }
  add_lap(report_.seconds_stress);
  for (const auto& [k, dec] : estimates) {
    const rigid::BlockId id = m.ids[k];
    if (m.u_filtered.size() <= id.index) m.u_filtered.resize(id.index + 1, 0.0);
    double& u = m.u_filtered[id.index];
    const double tau = m.def.stress_time_constant;
    u = tau > 0.0 ? u + (dec.utilisation - u) * std::min(1.0, report_.rigid_dt / tau) : dec.utilisation;
    report_.max_utilisation = std::max(report_.max_utilisation, u);
    if (converts(u, m.def.safety_factor)) {
      to_convert.push_back(id);
      governing.push_back(dec.governing);
    }
  }
  add_lap(report_.seconds_policy);
  if (comm.parallel()) {
    share_decisions(comm, to_convert, governing);
    double mu = report_.max_utilisation;
    comm.max(&mu, 1);
    report_.max_utilisation = mu;
  }
  if (comm.parallel()) add_lap(report_.seconds_bridge_mpi);
  for (std::size_t k = 0; k < to_convert.size(); ++k) {
    try {
      convert(to_convert[k]);
    } catch (const InputError&) {
      // Same decision on every rank (same replicated state), so no rank diverges.
      if (m.unconvertible.size() <= to_convert[k].index) m.unconvertible.resize(to_convert[k].index + 1, 0);
      m.unconvertible[to_convert[k].index] = 1;
      ++report_.conversions_refused;
      continue;
    }
    count_conversion(report_, governing[k]);
  }
  add_lap(report_.seconds_conversion);
}

ConversionReport HybridSystem::convert(rigid::BlockId id) {
  Impl& m = *impl_;
  // Collective under MPI (every rank converts the same block). The bond list must be the same on
  // every rank before the hand-over reads it: a bond broken since the last rigid step is so far
  // marked on its particle's owner only. And the blocks' poses the bonds see are brought to now
  // (after a rigid step: the world's own), so that bonds made below start stress free.
  m.bonds_broken_synced += m.bonds.sync_broken(engine_.comm());
  m.extrapolate(engine_.time());
  const BlockState b = block_state(*world_, id);
  // Sites that would start inside (or touching) another rigid block are dropped too: the
  // block-block contact was Bullet's, with its own small penetrations, and a particle there
  // would be thrown out by the particle-block contact spring. (Sites behind the particles' plane
  // walls are the converter's own check, as are those overlapping particles.) The lattice
  // stage's batch tests only the blocks that stay rigid (Impl::batch_rigid).
  std::vector<rigid::BlockId> near;
  const double reach = b.half_extents.norm() + m.def.ice.diameter;
  for (const rigid::BlockId o : m.ids)
    if (!(o == id) && (world_->position(o) - b.pose.position).norm() < reach + world_->half_extents(o).norm() &&
        (m.batch_rigid.empty() || m.batch_rigid[o.index]))
      near.push_back(o);
  const SiteBlocked inside_other = [&](const Vec3& site, double r) {
    for (const rigid::BlockId o : near)
      if (sphere_reaches_block(*world_, o, site, r)) return true;
    return false;
  };
  // Freeze bonds carry over (docs/bridge.md, "Conversion"): the block's bonds to particles
  // become particle-particle freeze bonds to its new particles (attachments, made by the
  // converter), and its joints to other blocks become block-particle bonds. Both are chosen from
  // replicated data (the bond list, the new particles' site list), so under MPI every rank makes
  // the same choice. (A block the converter refuses keeps its bonds.)
  std::vector<Attachment> attach;
  for (const ReleasedBond& rb : m.bonds.bonds_of(id.index)) attach.push_back({rb.gid, rb.anchor});
  const ConversionReport r = convert_block(engine_, b, m.def.ice, inside_other, attach);
  m.bonds.release_block(id.index);
  report_.block_bonds_handed_over += r.bonds_attached;
  report_.block_bonds_unmatched += r.attachments_skipped;
  const std::vector<rigid::JointId> joints = world_->joints_of(id);
  for (const rigid::JointId j : joints) {
    const rigid::FreezeJointDef jd = world_->joint_def(j);
    const bool a_stays = !(jd.a == id);
    const rigid::BlockId other = a_stays ? jd.a : jd.b;
    if (world_->fixed(other)) continue;
    // Normal from the remaining block towards the converted one.
    report_.joints_to_bonds += bond_joint_to_particles(m.bonds, other.index, jd.anchor,
                                                       a_stays ? jd.normal : Vec3(-jd.normal), jd.area, r);
  }
  report_.joints_released += joints.size();
  const auto it = std::find(m.ids.begin(), m.ids.end(), id);
  const std::size_t k = static_cast<std::size_t>(it - m.ids.begin());
  m.contact.remove_block(k);
  m.ids.erase(it);
  m.ref.erase(m.ref.begin() + static_cast<std::ptrdiff_t>(k));
  if (k < m.frozen.size()) m.frozen.erase(m.frozen.begin() + static_cast<std::ptrdiff_t>(k));
  world_->remove_block(id);
  m.coupler.reset(world_->blocks());
  ++report_.conversions;
  report_.particles_created += r.particles_created;
  report_.bonds_created += r.bonds_created;
  report_.sites_dropped += r.particles_dropped;
  report_.kinetic_energy_change += r.kinetic_energy_after - r.kinetic_energy_before;
  report_.blocks_now = world_->block_count();
  return r;
}

Vec3 HybridSystem::structure_force() const {
  return world_ && impl_->mesh >= 0 ? world_->mesh_load(impl_->mesh).force : Vec3::Zero();
}
Vec3 HybridSystem::structure_moment() const {
  return world_ && impl_->mesh >= 0 ? world_->mesh_load(impl_->mesh).moment : Vec3::Zero();
}
const std::vector<Vec3>& HybridSystem::structure_part_force() const {
  return world_ && impl_->mesh >= 0 ? world_->mesh_load(impl_->mesh).part_force : impl_->no_parts;
}
const std::vector<Vec3>& HybridSystem::structure_part_moment() const {
  return world_ && impl_->mesh >= 0 ? world_->mesh_load(impl_->mesh).part_moment : impl_->no_parts;
}
double HybridSystem::coupling_elastic_energy() const {
  if (!world_) return 0.0;
  const auto& ps = engine_.particles();
  return impl_->contact.elastic_energy(ps, ps.owned(), engine_.def()) + impl_->bonds.elastic_energy(ps, engine_.def());
}

std::size_t HybridSystem::block_particle_bonds() const { return impl_->bonds.size(); }
std::uint64_t HybridSystem::block_particle_bonds_broken() const { return impl_->bonds_broken_synced; }
double HybridSystem::rigid_kinetic_energy() const { return world_ ? world_->kinetic_energy() : 0.0; }

}  // namespace hs::bridge
