// Simulation::run_stats and Simulation::progress: the figures of a run for the command's lines.
#include "sim/simulation.h"

#include "bridge/conversion_criteria.h"
#include "rigid/rigid_world.h"

namespace hs::sim {

Progress Simulation::progress() const { return {engine().time(), engine().stats().bonds_broken}; }

RunStats Simulation::run_stats() const {
  const bonded::Engine& e = engine();
  RunStats r;
  r.particles = static_cast<long long>(e.global_particle_count());
  r.bonds = static_cast<long long>(e.global_bond_count());
  r.step = e.step_count();
  r.time = e.time();
  r.dt = e.dt();
  const auto& st = e.stats();
  r.bonds_broken = st.bonds_broken;
  r.bonds_broken_tension = st.bonds_broken_tension;
  r.bonds_broken_shear = st.bonds_broken_shear;
  r.bonds_broken_compression = st.bonds_broken_compression;

  const bridge::HybridSystem& h = hybrid();
  r.has_blocks = has_blocks();
  r.conversion = bridge::to_string(blocks_.def.mode);
  r.blocks = h.report();
  r.freeze_joints = blocks_.joints.size();
  r.ice_joints = blocks_.ice_joints.size();
  r.conversions_crushing = r.blocks.conversions_by(bridge::kCrushingCriterion);
  r.far_sleep = blocks_.def.world.far_sleep.enabled;
  if (r.has_blocks) {
    r.relax = h.relax_report();
    r.block_particle_bonds_broken = h.block_particle_bonds_broken();
    if (const rigid::RigidWorld* w = h.world()) {
      r.freeze_joints_broken = w->broken_joint_count();
      r.awake_blocks = w->awake_count();
      r.sleepers_woken_by_solve = w->sleepers_woken_by_solve();
      r.solves_repeated = w->solves_repeated();
      const rigid::RigidWorld::SolverStats ss = w->solver_stats();
      r.solver_solves = ss.solves;
      r.solver_iterations = ss.iterations;
      r.solver_max_iterations = ss.max_iterations;
      r.solver_iteration_cap = w->def().solver_iterations;
      r.solver_tolerance = w->def().solver_tolerance;
    }
  }

  const auto& ps = e.parallel_stats();
  r.force_seconds = ps.force_seconds;
  r.comm_seconds = ps.comm_seconds;
  r.exchanges = ps.exchanges;
  r.migrated = ps.migrated;
  r.balances = ps.balances;
  r.boxes = e.decomposition().dims();
  for (int a = 0; a < 3; ++a) r.cuts[a] = e.decomposition().cuts(a);
  return r;
}

}  // namespace hs::sim

namespace hs::sim {

RunCost Simulation::cost() const {
  RunCost c;
  c.seconds = cost_ledger_.seconds;
  const bridge::HybridReport& r = hybrid().report();
  const auto add = [&c](Phase p, double s) { c.seconds[static_cast<std::size_t>(p)] += s; };
  add(Phase::ParticleForces, r.seconds_bonded_force);
  add(Phase::ParticleOther, r.seconds_bonded - r.seconds_bonded_force - r.seconds_bonded_mpi);
  add(Phase::RigidWorld, r.seconds_rigid);
  add(Phase::BridgeCoupling,
      r.seconds_bridge - r.seconds_stress - r.seconds_policy - r.seconds_conversion - r.seconds_bridge_mpi);
  add(Phase::BridgeStress, r.seconds_stress);
  add(Phase::BridgePolicy, r.seconds_policy);
  add(Phase::BridgeConversion, r.seconds_conversion);
  add(Phase::MpiWait, r.seconds_bonded_mpi + r.seconds_bridge_mpi);
  c.max = c.seconds;
  c.wall = cost_ledger_.wall_before + seconds_since(cost_ledger_.start);
  c.wall_max = c.wall;
  c.steps = step_count();
  c.rigid_steps = r.rigid_steps;
  c.particle_steps = cost_ledger_.particle_steps;
  c.processes = cost_ledger_.processes_before + 1;
  return c;
}

}  // namespace hs::sim
