#include "sim/simulation.h"

#include "common/error.h"
#include "parallel/comm.h"

#include <algorithm>
#include <optional>
#include <sstream>
#include <cmath>

namespace hs::sim {

Schedule schedule(const scene::TimeDef& t, double dt) {
  Schedule sc;
  sc.dt = dt;
  scene::check_step_count(t, dt, t.dt > 0 ? "" : " (from Eq. 2 with /time/dt = 0)");
  sc.total_steps = std::max<std::uint64_t>(1, static_cast<std::uint64_t>(std::ceil(t.duration / dt - 1e-9)));
  sc.output_every = std::max<std::uint64_t>(1, static_cast<std::uint64_t>(std::llround(t.output_interval / dt)));
  if (t.snapshot_interval > 0)
    sc.snapshot_every =
        std::max<std::uint64_t>(1, static_cast<std::uint64_t>(std::llround(t.snapshot_interval / dt)));
  if (t.checkpoint_interval > 0)
    sc.checkpoint_every =
        std::max<std::uint64_t>(1, static_cast<std::uint64_t>(std::llround(t.checkpoint_interval / dt)));
  return sc;
}

const Vec3& Simulation::structure_position() const { return engine().mesh_wall_position(built_.structure); }

void Simulation::structure_load(StructureLoad& out) const {
  const auto& L = engine().mesh_wall_load(built_.structure);
  const auto& bpf = hybrid_->structure_part_force();
  const auto& bpm = hybrid_->structure_part_moment();
  out.force = L.force + hybrid_->structure_force();
  out.moment = L.moment + hybrid_->structure_moment();
  const std::size_t n = built_.structure_parts.size();
  out.part_force.resize(n);
  out.part_moment.resize(n);
  for (std::size_t q = 0; q < n; ++q) {
    out.part_force[q] = L.part_force[q] + (q < bpf.size() ? bpf[q] : Vec3::Zero());
    out.part_moment[q] = L.part_moment[q] + (q < bpm.size() ? bpm[q] : Vec3::Zero());
  }
}

bridge::RelaxDef relax_def(const scene::Scene& s) {
  const auto& r = s.blocks.relax;
  bridge::RelaxDef d;
  d.max_time = r.max_time;
  d.speed = r.speed;
  d.hold = r.hold;
  d.damping = r.damping;
  d.jointed_time = r.jointed_time;
  d.lattice_time = r.lattice_time;
  d.lattice_damping = r.lattice_damping;
  d.hold_freeze_bonds = r.hold_freeze_bonds ? 1u : 0u;
  return d;
}

bonded::ParallelDef parallel_def(const scene::Scene& s) {
  bonded::ParallelDef pd;
  pd.grid = s.parallel.grid;
  pd.balance_interval = s.parallel.balance_interval;
  pd.cost = s.parallel.cost == "time" ? bonded::ParallelDef::Cost::Time : bonded::ParallelDef::Cost::Work;
  return pd;
}

Simulation build_simulation(const scene::Scene& s, const par::Comm& comm, const BuildOptions& opt) {
  Simulation sim;
  MemoryEstimate est = memory_estimate(s);
  if (!opt.ignore_memory_limit) check_memory(s, est, available_memory_bytes(), comm.size());
  // The scene's ice, once for the run: the engine's springs and bonds, the blocks' freeze and
  // conversion limits (Built::calibrated keeps it for the report and the run file).
  std::optional<CalibratedIce> own;
  const CalibratedIce& ice = opt.calibrated ? *opt.calibrated : own.emplace(calibrate_ice(s));
  sim.built_ = build_engine(s, ice, opt.check_dt);
  // InputError when the ice starts inside the structure; a warning for shallow overlaps
  const std::string overlap = check_structure_overlap(sim.built_, s);
  bonded::Engine& e = *sim.built_.engine;
  const mesh::TriMesh* structure = sim.has_structure() ? &sim.built_.structure_mesh : nullptr;
  sim.blocks_ = block_setup(s, sim.built_.calibrated, structure, sim.built_.structure_radius, sim.built_.ridge.get());
  if (!opt.ignore_memory_limit && !sim.blocks_.blocks.empty()) {  // before the rigid world and any conversion
    add_blocks(est, sim.blocks_, s.material.particle_diameter, s.walls.size());
    check_memory(s, est, available_memory_bytes(), comm.size());
  }
  if (!overlap.empty()) sim.blocks_.warnings.push_back(overlap);
  bridge::HybridDef def = sim.blocks_.def;
  if (!opt.convert) def.mode = bridge::ConversionMode::Never;  // count and check only
  // The relaxation before the freeze (docs/bridge.md, "Relaxation"): only with blocks, before
  // distribute() (every rank relaxes the whole scene alike, so 1 and N ranks start the same).
  const bool relax = opt.relax && s.blocks.relax.enabled && !sim.blocks_.blocks.empty();
  def.defer_freeze = relax;
  const auto& b = sim.blocks_;
  sim.hybrid_ = std::make_unique<bridge::HybridSystem>(e, def, b.blocks, b.joints, b.ice_joints);
  if (relax) {
    if (opt.restart_state) {
      try {
        sim.hybrid_->restore_relaxation(*opt.restart_state, "hybrid/");
      } catch (const std::exception& ex) {
        throw InputError("--restart", std::string("the checkpoint's relaxed ridge does not fit the scene as built: ") +
                                          ex.what());
      }
    } else {
      const auto& r = s.blocks.relax;
      const bridge::RelaxReport& rep = sim.hybrid_->relax(relax_def(s), opt.relax_progress);
      if (rep.stopped) throw RelaxationStopped(rep.time);
      // Not at rest at the freeze: the last stage did not end at rest (a first stage that ends
      // at max_time is what the jointed stage is for).
      const bool jointed = rep.jointed_time > 0.0, lattice = rep.lattice_time > 0.0;
      if (!rep.at_rest()) {
        std::ostringstream w;
        w << "/blocks/relax: the blocks and the sheet were not at rest after "
          << (lattice   ? "the lattice stage's lattice_time = "
              : jointed ? "the jointed stage's jointed_time = "
                        : "max_time = ")
          << (lattice ? r.lattice_time : jointed ? r.jointed_time : r.max_time)
          << " s of relaxation (fastest block " << rep.max_block_speed << " m/s, fastest particle "
          << rep.max_particle_speed << " m/s; at rest means below speed = " << r.speed << " m/s for hold = " << r.hold
          << " s); the joints and bonds were frozen there and the run starts from that state. Raise "
          << (lattice   ? "/blocks/relax/lattice_time"
              : jointed ? "/blocks/relax/jointed_time"
                        : "/blocks/relax/max_time, set /blocks/relax/jointed_time (e.g. 3)")
          << " or set /blocks/relax/damping (e.g. 0.5)";
        sim.blocks_.warnings.push_back(w.str());
      }
      // (lattice_time, lattice_damping and blocks.lattice are all_at_start's settings: a keel scene
      // carries them for its reference runs, and its hybrid and never runs pass them over quietly.)
      if (r.hold_freeze_bonds && !(r.lattice_time > 0.0 && def.mode == bridge::ConversionMode::AllAtStart))
        sim.blocks_.warnings.push_back("/blocks/relax/hold_freeze_bonds: set, but it acts only in all_at_start's "
                                       "lattice stage (blocks.conversion = all_at_start and blocks.relax.lattice_time "
                                       "> 0); ignored here");
      if (lattice && rep.freeze_bonds_overloaded) {
        std::ostringstream w;
        w << "/blocks/relax: " << rep.freeze_bonds_overloaded << " of the " << rep.freeze_bonds_held
          << " freeze bonds held in the lattice stage carry more than their strength at its end and will break at "
             "the run's first step";
        sim.blocks_.warnings.push_back(w.str());
      }
      if (jointed && !lattice && rep.joints_overloaded) {  // (a lattice stage removed those joints)
        std::ostringstream w;
        w << "/blocks/relax: " << rep.joints_overloaded << " of the " << rep.jointed_joints
          << " joints held in the jointed stage carry more than their strength at its end and will break at "
             "the run's first step (the keel's static load on small joints)";
        sim.blocks_.warnings.push_back(w.str());
      }
    }
  }
  if (comm.parallel()) {  // every rank built the whole scene; each keeps its share
    e.distribute(comm, parallel_def(s));
  }
  sim.schedule_ = schedule(s.time, e.dt());
  return sim;
}

}  // namespace hs::sim
