// The relaxation before the freeze (docs/bridge.md, "Relaxation"): HybridSystem::relax,
// restore_relaxation and freeze. The paper's set-up: the ridge settled, then released in water
// under gravity and buoyancy so that the pre-stress of the settling is dissipated, then frozen.
#include "bridge/hybrid.h"
#include "bridge/hybrid_impl.h"

#include <cmath>
#include <algorithm>
#include <array>
#include <cstdint>
#include <map>
#include <limits>
#include <stdexcept>

namespace hs::bridge {

namespace {

/// The figures a relaxation's report takes from where it ended.
void take_end_state(RelaxReport& R, const RelaxProgress& P) {
  R.time = P.time;
  R.max_block_speed = P.max_block_speed;
  R.max_particle_speed = P.max_particle_speed;
  R.block_kinetic_energy = P.block_kinetic_energy;
}

/// The lattice stage's held freeze bonds (RelaxDef::hold_freeze_bonds), if it held them.
void count_held_freeze_bonds(const bonded::Engine& e, RelaxReport& R) {
  if (!e.bonds_unbreakable(bonded::BondKind::Freeze)) return;
  R.freeze_bonds_held = e.bond_count(bonded::BondKind::Freeze);
  R.freeze_bonds_overloaded = e.overloaded_bond_count(bonded::BondKind::Freeze);
}

/// Fastest point of a block: centre speed + |omega| x half diagonal (an upper bound).
double block_speed(const rigid::RigidWorld& w, rigid::BlockId id) {
  return w.velocity(id).norm() + w.angular_velocity(id).norm() * w.half_extents(id).norm();
}

/// The fastest block and particle now (speeds and where they are) into P.
void fastest(const rigid::RigidWorld& w, const std::vector<rigid::BlockId>& ids, const bonded::ParticleStore& ps,
             RelaxProgress& P) {
  P.max_block_speed = 0.0;
  for (const rigid::BlockId id : ids)
    if (!w.fixed(id)) {
      const double v = block_speed(w, id);
      if (v > P.max_block_speed) {
        P.max_block_speed = v;
        P.fastest_block = w.position(id);
      }
    }
  double v2 = 0.0;
  for (std::size_t i = 0; i < ps.owned(); ++i)
    if (ps.v[i].squaredNorm() > v2) {
      v2 = ps.v[i].squaredNorm();
      P.fastest_particle = ps.x[i];
    }
  P.max_particle_speed = std::sqrt(v2);
}

}  // namespace

bool HybridSystem::freeze_pending() const { return impl_->freeze_pending; }
const RelaxReport& HybridSystem::relax_report() const { return impl_->relax; }
double HybridSystem::far_sleep_reach() const { return impl_->wake_reach; }
double HybridSystem::block_bond_elastic_energy() const {
  return world_ ? impl_->bonds.elastic_energy(engine_.particles(), engine_.def()) : 0.0;
}

const RelaxReport& HybridSystem::relax(const RelaxDef& def, const RelaxProgressFn& progress) {
  Impl& m = *impl_;
  if (!m.freeze_pending) throw std::logic_error("HybridSystem::relax: nothing waits for a relaxation");
  if (engine_.parallel()) throw std::logic_error("HybridSystem::relax: relax before Engine::distribute()");
  if (!(def.max_time > 0.0) || !(def.speed > 0.0) || !(def.hold >= 0.0) || !(def.damping >= 0.0))
    throw std::invalid_argument("HybridSystem::relax: max_time and speed must be > 0, hold and damping >= 0");
  RelaxReport& R = m.relax;
  R = RelaxReport{};
  R.ran = 1;
  R.def = def;
  engine_.set_walls_parked(true);
  auto& ps = engine_.particles();
  // The sheet's heights at the start, by global id (the store is reordered at neighbour rebuilds).
  GlobalId max_gid = 0;
  for (std::size_t i = 0; i < ps.owned(); ++i) max_gid = std::max(max_gid, ps.gid[i]);
  std::vector<double> z0(ps.owned() ? max_gid + 1 : 0, std::numeric_limits<double>::quiet_NaN());
  for (std::size_t i = 0; i < ps.owned(); ++i) z0[ps.gid[i]] = ps.x[i].z();
  const auto sheet_dz = [&](double& mean, double& max_abs) {
    double sum = 0.0;
    std::size_t n = 0;
    max_abs = 0.0;
    for (std::size_t i = 0; i < ps.owned(); ++i) {
      if (ps.gid[i] >= z0.size() || std::isnan(z0[ps.gid[i]])) continue;
      const double dz = ps.x[i].z() - z0[ps.gid[i]];
      sum += dz;
      max_abs = std::max(max_abs, std::abs(dz));
      ++n;
    }
    mean = n ? sum / static_cast<double>(n) : 0.0;
  };
  // all_at_start: the lattices relax with the sheet (their freeze bonds held back until the
  // freeze, or held in place: hold_freeze_bonds), not the rigid blocks they came from: converted now, or (lattice_time > 0) after the
  // rigid blocks have relaxed as in hybrid mode. After z0: the sheet's figures stay the sheet's.
  const bool lattice_stage = m.def.mode == ConversionMode::AllAtStart && def.lattice_time > 0.0;
  if (m.def.mode == ConversionMode::AllAtStart && !lattice_stage) convert_before_relaxation();
  // The lattice stage's conversion makes the ridge's joints at the relaxed poses: kept from now.
  const std::vector<JointInit> ridge_joints = m.pending_joints;
  std::uint64_t broken0 = engine_.stats().bonds_broken;
  std::uint64_t broken_before = 0;  // lattice bonds broken before the lattice stage's clock reset
  const std::uint64_t k = report_.steps_per_rigid_step;
  const double h = report_.rigid_dt, dt = engine_.dt();
  double damping = 0.0, fp = 1.0, fb = 1.0;  // the stage's: particles every step, blocks every rigid step
  const auto set_damping = [&](double d) {
    damping = d;
    fp = std::exp(-d * dt);
    fb = std::exp(-d * h);
  };
  set_damping(def.damping);
  RelaxProgress P;
  // Up to `duration` s more: true when at rest (the speeds below def.speed for def.hold s).
  const auto run_stage = [&](double duration) {
    const auto n = static_cast<std::uint64_t>(std::ceil(duration / h - 1e-9));
    P.quiet_time = 0.0;
    for (std::uint64_t r = 0; r < n; ++r) {
      for (std::uint64_t s = 0; s < k; ++s) {
        step();
        ++R.steps;
        if (damping > 0.0)
          for (std::size_t i = 0; i < ps.owned(); ++i) {
            ps.v[i] *= fp;
            ps.omega[i] *= fp;
          }
      }
      ++R.rigid_steps;
      if (damping > 0.0) {
        for (const rigid::BlockId id : m.ids)
          if (!world_->fixed(id)) world_->set_velocity(id, fb * world_->velocity(id), fb * world_->angular_velocity(id));
        m.take_reference(*world_);
      }
      P.time = static_cast<double>(R.rigid_steps) * h;
      fastest(*world_, m.ids, ps, P);
      P.block_kinetic_energy = world_->kinetic_energy();
      P.lattice_bonds_broken = broken_before + (engine_.stats().bonds_broken - broken0);
      P.quiet_time = P.max_block_speed < def.speed && P.max_particle_speed < def.speed ? P.quiet_time + h : 0.0;
      double mean = 0.0, max_abs = 0.0;
      sheet_dz(mean, max_abs);
      R.sheet_peak_mean_dz = std::max(R.sheet_peak_mean_dz, std::abs(mean));
      if (progress && progress(P)) {
        R.stopped = 1;
        return false;
      }
      if (P.quiet_time >= def.hold - 1e-12) return true;
    }
    return false;
  };
  R.converged = run_stage(def.max_time) ? 1 : 0;
  if (!R.stopped && def.jointed_time > 0.0) {
    R.unjointed_max_block_speed = P.max_block_speed;
    const double t1 = P.time;
    begin_jointed_stage();
    P.stage = 2;
    R.jointed_converged = run_stage(def.jointed_time) ? 1 : 0;
    R.jointed_time = P.time - t1;
    R.jointed_joints = world_->joint_count();
    R.joints_overloaded = world_->overloaded_joint_count();
    world_->set_joints_breakable(true);
  }
  if (!R.stopped && lattice_stage) {
    R.rigid_max_block_speed = P.max_block_speed;
    const double t2 = P.time;
    broken_before = P.lattice_bonds_broken;
    convert_after_rigid_relaxation(ridge_joints);
    broken0 = engine_.stats().bonds_broken;
    P.stage = 3;
    set_damping(def.lattice_stage_damping());
    R.lattice_converged = run_stage(def.lattice_time) ? 1 : 0;
    R.lattice_time = P.time - t2;
    count_held_freeze_bonds(engine_, R);
  }
  take_end_state(R, P);
  sheet_dz(R.sheet_mean_dz, R.sheet_max_dz);
  R.lattice_bonds_broken = broken_before + (engine_.stats().bonds_broken - broken0);
  if (R.stopped) return R;
  m.relaxed_world.entries.clear();
  world_->save_state(m.relaxed_world, "");
  freeze();
  return R;
}

void HybridSystem::begin_jointed_stage() {
  Impl& m = *impl_;
  m.unjointed_world.entries.clear();
  world_->save_state(m.unjointed_world, "");
  make_pending_block_joints();
  world_->set_joints_breakable(false);
}

void HybridSystem::restore_relaxation(const StateArchive& a, const std::string& p) {
  Impl& m = *impl_;
  if (!m.freeze_pending) return;
  const std::string pre = p + "relaxed/";
  if (!a.has(p + "relax_report"))
    throw std::runtime_error("hybrid checkpoint: the scene relaxes its blocks but the checkpoint holds no relaxed "
                             "state (written by a version without the relaxation?)");
  m.relax = a.get_value<RelaxReport>(p + "relax_report");
  const auto read = [&](const std::string& prefix, StateArchive& out) {
    out.entries.clear();
    for (const auto& [key, value] : a.entries)
      if (key.compare(0, prefix.size(), prefix) == 0) out.entries.emplace(key.substr(prefix.size()), value);
  };
  // The same conversion as in the original relaxation (same blocks, same poses, the same sheet):
  // the world then holds the blocks the saved one did; the engine's particles are restored
  // afterwards.
  if (m.relax.lattice_time > 0.0) {
    read(p + "preconvert/", m.preconvert_world);
    read(p + "preconvert_engine/", m.preconvert_engine);
    if (m.preconvert_world.entries.empty() || m.preconvert_engine.entries.empty())
      throw std::runtime_error("hybrid checkpoint: a lattice stage ran but the state it converted is missing");
    if (m.relax.jointed_time > 0.0) {
      // The jointed stage's joints were made and then removed before the conversion: made again
      // here, so that the world has the same joint slots as the one saved (the saved free slots
      // and generations then take over).
      const std::vector<JointInit> ridge_joints = m.pending_joints;
      read(p + "unjointed/", m.unjointed_world);
      world_->load_state(m.unjointed_world, "");
      make_pending_block_joints();
      m.pending_joints = ridge_joints;
    }
    engine_.load_state(m.preconvert_engine, "");
    world_->load_state(m.preconvert_world, "");
    m.take_reference(*world_);
    convert_before_relaxation();
  } else if (m.def.mode == ConversionMode::AllAtStart) {
    convert_before_relaxation();
  }
  if (m.relax.jointed_time > 0.0 && m.relax.lattice_time == 0.0) {
    // the joints of the jointed stage, made from the same poses as then (a lattice stage removed
    // them before its conversion)
    read(p + "unjointed/", m.unjointed_world);
    world_->load_state(m.unjointed_world, "");
    make_pending_block_joints();
  }
  read(pre, m.relaxed_world);
  world_->load_state(m.relaxed_world, "");
  m.take_reference(*world_);
  freeze();
}

void HybridSystem::freeze() {
  Impl& m = *impl_;
  m.freeze_pending = false;
  engine_.set_walls_parked(false);
  engine_.set_bonds_unbreakable(bonded::BondKind::Freeze, false);
  engine_.reset_clock();
  world_->reset_clock();
  if (m.def.has_structure) m.mesh = world_->add_kinematic_mesh(m.def.structure);
  make_pending_joints();
  if (m.converted_before_relax) {
    // all_at_start: the freeze bonds its conversion made, stress free at the relaxed positions
    // (the particles at their relaxed positions, the blocks left rigid at their relaxed poses).
    for (const bonded::Bond& b : m.held_bonds) engine_.add_bond(b.gi, b.gj, b.kind);
    for (const BlockParticleBond& b : m.held_block_bonds) m.bonds.remake(engine_.particles(), b);
    m.held_bonds.clear();
    m.held_block_bonds.clear();
  } else if (m.def.mode == ConversionMode::AllAtStart) {
    convert_all_at_start();
  }
  report_.rigid_steps = 0;  // the run's, from t = 0, and so are its wall times (the set-up is timed apart)
  report_.seconds_rigid = report_.seconds_bonded = report_.seconds_bridge = 0.0;
  report_.seconds_bonded_force = report_.seconds_bonded_mpi = 0.0;
  report_.seconds_stress = report_.seconds_policy = report_.seconds_conversion = report_.seconds_bridge_mpi = 0.0;
  report_.blocks_now = world_->block_count();
  report_.peak_particles = std::max(report_.peak_particles, engine_.global_particle_count());
}

void HybridSystem::make_pending_block_joints() {
  Impl& m = *impl_;
  for (const auto& j : m.pending_joints)
    world_->add_freeze_joint(rigid::FreezeJointDef{m.pending_ids.at(j.a), m.pending_ids.at(j.b),
                                                   pending_point(j.a, j.anchor), pending_direction(j.a, j.normal),
                                                   j.area});
  m.pending_joints.clear();
}

Vec3 HybridSystem::pending_point(std::size_t k, const Vec3& point) const {
  const Impl& m = *impl_;
  const rigid::BlockId id = m.pending_ids.at(k);
  return world_->position(id) + world_->orientation(id) * (m.q0[k].conjugate() * (point - m.x0[k]));
}

Vec3 HybridSystem::pending_direction(std::size_t k, const Vec3& dir) const {
  const Impl& m = *impl_;
  return world_->orientation(m.pending_ids.at(k)) * (m.q0[k].conjugate() * dir);
}

void HybridSystem::make_pending_joints() {
  Impl& m = *impl_;
  make_pending_block_joints();  // none left when the relaxation's jointed stage made them
  m.take_reference(*world_);
  m.extrapolate(world_->time());
  for (const auto& j : m.pending_ice_joints)
    report_.ice_bonds_created += m.bonds.bond_patch(engine_.particles(), m.pending_ids.at(j.block).index,
                                                    pending_point(j.block, j.anchor),
                                                    pending_direction(j.block, j.normal), j.area);
  m.pending_ice_joints.clear();
}

void HybridSystem::convert_after_rigid_relaxation(const std::vector<JointInit>& ridge_joints) {
  Impl& m = *impl_;
  // The rigid stages' joints go (the jointed stage's); the conversion makes the ridge's joints
  // again at the relaxed poses, as it would have at the starting ones.
  for (const rigid::BlockId id : world_->blocks())
    for (const rigid::JointId j : world_->joints_of(id)) world_->remove_joint(j);
  m.pending_joints = ridge_joints;
  // Both clocks from 0 (the stage's steps count from there), then the relaxed sheet and world
  // saved: a restart loads both and converts exactly as here (restore_relaxation).
  engine_.reset_clock();
  world_->reset_clock();
  m.take_reference(*world_);
  m.preconvert_engine.entries.clear();
  engine_.save_state(m.preconvert_engine, "");
  m.preconvert_world.entries.clear();
  world_->save_state(m.preconvert_world, "");
  convert_before_relaxation();
}

std::vector<char> HybridSystem::plan_lattice_batch() const {
  const Impl& m = *impl_;
  const double D = m.def.ice.diameter, r = 0.5 * D, rt = site_test_radius(m.def.ice);
  const std::vector<rigid::BlockId> blocks = world_->blocks();
  std::uint32_t slots = 0;
  for (const rigid::BlockId id : blocks) slots = std::max(slots, id.index + 1);
  std::vector<char> rigid(slots, 0);
  std::vector<std::vector<Vec3>> sites(blocks.size());
  std::vector<Vec3> all;
  for (std::size_t k = 0; k < blocks.size(); ++k) {
    const rigid::BlockId id = blocks[k];
    if (world_->fixed(id) || !lattice_fits(world_->half_extents(id), D)) {
      rigid[id.index] = 1;
      continue;
    }
    sites[k] = lattice_sites(block_state(*world_, id), m.def.ice);
    if (sites[k].empty()) {  // (a world lattice may miss a thin block)
      rigid[id.index] = 1;
      continue;
    }
    all.insert(all.end(), sites[k].begin(), sites[k].end());
  }
  // The sheet's particles and the walls take the same sites whatever the batch does.
  const std::vector<char> sheet = engine_.overlapping_sites(all, std::vector<double>(all.size(), rt));
  std::vector<std::vector<char>> taken(blocks.size());
  for (std::size_t k = 0, s = 0; k < blocks.size(); ++k) {
    taken[k].assign(sites[k].size(), 0);
    for (std::size_t i = 0; i < sites[k].size(); ++i, ++s)
      taken[k][i] = sheet[s] != 0 || behind_a_wall(engine_, sites[k][i], r);
  }
  // A dry run of the batch in its order (the world's): a block keeps the sites clear of the
  // blocks that stay rigid and of the sites kept before it, as the converter will decide. A
  // block left with none stays rigid, and the run starts again with it as an obstacle.
  const auto cell = [D](const Vec3& p) { return (p / D).array().floor().cast<std::int64_t>().eval(); };
  for (bool again = true; again;) {
    again = false;
    std::map<std::array<std::int64_t, 3>, std::vector<Vec3>> kept;  // by cell of size D
    std::vector<rigid::BlockId> obstacles;
    for (const rigid::BlockId o : blocks)
      if (rigid[o.index]) obstacles.push_back(o);
    for (std::size_t k = 0; k < blocks.size() && !again; ++k) {
      const rigid::BlockId id = blocks[k];
      if (rigid[id.index]) continue;
      std::vector<Vec3> mine;
      for (std::size_t i = 0; i < sites[k].size(); ++i) {
        const Vec3& p = sites[k][i];
        if (taken[k][i]) continue;
        bool hit = false;
        for (const rigid::BlockId o : obstacles)
          hit = hit || sphere_reaches_block(*world_, o, p, r);
        const auto c = cell(p);
        for (int dx = -1; dx <= 1 && !hit; ++dx)
          for (int dy = -1; dy <= 1 && !hit; ++dy)
            for (int dz = -1; dz <= 1 && !hit; ++dz) {
              const auto it = kept.find({c.x() + dx, c.y() + dy, c.z() + dz});
              if (it != kept.end())
                for (const Vec3& q : it->second)
                  if ((q - p).norm() < r + rt) hit = true;  // as overlapping_sites: particle r + site rt
            }
        if (!hit) mine.push_back(p);
      }
      if (mine.empty()) {
        rigid[id.index] = 1;
        again = true;
      }
      for (const Vec3& p : mine) {
        const auto c = cell(p);
        kept[{c.x(), c.y(), c.z()}].push_back(p);
      }
    }
  }
  return rigid;
}

void HybridSystem::convert_before_relaxation() {
  Impl& m = *impl_;
  if (m.converted_before_relax) return;
  const std::vector<JointInit> joints = m.pending_joints;
  const GlobalId first_new = engine_.particles().next_gid();
  // The joints as the ridge file gives them, at the blocks' poses now (moved clear of the
  // sheet): every conversion turns them into freeze bonds as in a run (HybridSystem::convert).
  make_pending_joints();
  if (m.relax.def.lattice_time > 0.0) m.batch_rigid = plan_lattice_batch();
  convert_all_at_start();
  m.batch_rigid.clear();
  // Held back until the freeze: the joints between blocks left rigid (refused by the converter;
  // made again from the ridge file's joints at the relaxed poses), the block-particle bonds, and
  // the particle-particle freeze bonds to the new particles (both ends' ids kept), unless the
  // lattice stage holds those in place, unbreakable (hold_freeze_bonds).
  for (const rigid::BlockId id : world_->blocks())
    for (const rigid::JointId j : world_->joints_of(id)) world_->remove_joint(j);
  for (const JointInit& j : joints)
    if (world_->alive(m.pending_ids.at(j.a)) && world_->alive(m.pending_ids.at(j.b))) m.pending_joints.push_back(j);
  m.held_block_bonds = m.bonds.take_all();
  if (m.relax.def.lattice_time > 0.0 && m.relax.def.hold_freeze_bonds)
    engine_.set_bonds_unbreakable(bonded::BondKind::Freeze, true);  // in place, unbreakable until the freeze
  else
    m.held_bonds = engine_.remove_bonds([&](const bonded::Bond& b) {
      return b.kind == bonded::BondKind::Freeze && std::max(b.gi, b.gj) >= first_new;
    });
  m.converted_before_relax = true;
}

}  // namespace hs::bridge
