#include "sim/cost.h"

#include "common/state_archive.h"
#include "parallel/comm.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <vector>

namespace hs::sim {

const std::array<PhaseInfo, kPhaseCount>& phase_info() {
  static const std::array<PhaseInfo, kPhaseCount> info{{
      {"read", "read", "set-up: reading the scene file, the ridge file and a restart's checkpoint"},
      {"calibration", "calibration", "set-up: the calibrated ice (springs and strengths from the scene's ice)"},
      {"build", "build", "set-up: ice lattice, walls, structure, blocks, hybrid system, spreading over the ranks"},
      {"relax_rigid", "relaxation (rigid)", "set-up: the relaxation before the freeze, its stage without joints"},
      {"relax_jointed", "relaxation (jointed)", "set-up: the relaxation's jointed stage (blocks.relax.jointed_time)"},
      {"relax_lattice", "relaxation (lattice)",
       "set-up: the relaxation's lattice stage, its conversion included (blocks.relax.lattice_time)"},
      {"freeze", "freeze",
       "set-up: joints and freeze bonds made at the relaxed geometry (a restart: the relaxed ridge restored)"},
      {"particle_forces", "forces",
       "step: the engine's force evaluation (contacts, bonds, walls, particle-block contact)"},
      {"particle_other", "integration, neighbour lists",
       "step: the rest of the engine's step (integration, neighbour lists, ghost packing)"},
      {"rigid_world", "rigid world", "step: the rigid world's step (Bullet: water, contact, joints, solver)"},
      {"bridge_coupling", "coupling", "step: block poses for the particles, impulses onto the blocks"},
      {"bridge_stress", "stress estimates", "step: the conversion policy's block loads and stress estimates"},
      {"bridge_policy", "policy", "step: the conversion policy's filtered utilisations and decisions"},
      {"bridge_conversion", "conversions", "step: blocks turned into particles"},
      {"output", "output",
       "the run file, series rows, snapshots, checkpoints, flushes and progress lines (their MPI reductions "
       "included)"},
      {"mpi_wait", "MPI wait",
       "MPI collectives and halo exchanges: the engine's, the bridge's and the loop's poll (measured around the "
       "calls)"},
      {"analysis", "analysis", "the end-of-run analysis (pieces, ISO 19906)"},
  }};
  return info;
}

void CostLedger::save(StateArchive& a) const {
  std::vector<double> s(seconds.begin(), seconds.end());
  if (output_lap) s[static_cast<std::size_t>(Phase::Output)] += seconds_since(*output_lap);
  const double wall = wall_before + seconds_since(start);
  a.put("cost/seconds", s);
  a.put("cost/figures", std::vector<double>{particle_steps, wall, static_cast<double>(processes_before + 1)});
}

namespace {

struct Saved {
  std::vector<double> seconds, figures;
};

bool read_saved(const StateArchive& a, Saved& s) {
  if (!a.has("cost/seconds") || !a.has("cost/figures")) return false;
  s.seconds = a.get<double>("cost/seconds");
  s.figures = a.get<double>("cost/figures");
  if (s.seconds.size() != kPhaseCount || s.figures.size() != 3)
    throw std::runtime_error("checkpoint: cost figures of another version ('cost/seconds', 'cost/figures')");
  return true;
}

}  // namespace

void CostLedger::add_saved(const StateArchive& a) { add_saved_union(&a, 1, 0); }

void CostLedger::add_saved_union(const StateArchive* all, std::size_t n, int rank) {
  std::size_t found = 0;
  std::array<double, kPhaseCount> sum{};
  double wall = 0.0, steps = 0.0, processes = 0.0;
  for (std::size_t r = 0; r < n; ++r) {
    Saved s;
    if (!read_saved(all[r], s)) continue;
    ++found;
    for (std::size_t k = 0; k < kPhaseCount; ++k) sum[k] += s.seconds[k];
    steps += s.figures[0];
    wall += s.figures[1];
    processes = std::max(processes, s.figures[2]);
  }
  if (!found) return;
  const double f = 1.0 / static_cast<double>(found);
  for (std::size_t k = 0; k < kPhaseCount; ++k) seconds[k] += f * sum[k];
  if (n == 1 || rank == 0) particle_steps += steps;
  wall_before += f * wall;
  processes_before += static_cast<std::uint64_t>(processes);
}

double RunCost::sum() const {
  double s = 0.0;
  for (const double v : seconds) s += v;
  return s;
}

double RunCost::setup() const {
  double s = 0.0;
  for (std::size_t k = 0; k < kFirstStepPhase; ++k) s += seconds[k];
  return s;
}

RunCost reduce_cost(const RunCost& mine, const par::Comm& comm) {
  RunCost r = mine;
  r.ranks = comm.size();
  r.max = mine.seconds;
  r.wall_max = mine.wall;
  if (!comm.parallel()) return r;
  std::vector<double> v(mine.seconds.begin(), mine.seconds.end());
  v.push_back(mine.wall);
  std::vector<double> mx = v;
  v.push_back(mine.particle_steps);
  comm.sum(v.data(), static_cast<int>(v.size()));
  comm.max(mx.data(), static_cast<int>(mx.size()));
  const double n = static_cast<double>(comm.size());
  for (std::size_t k = 0; k < kPhaseCount; ++k) {
    r.seconds[k] = v[k] / n;
    r.max[k] = mx[k];
  }
  r.wall = v[kPhaseCount] / n;
  r.wall_max = mx[kPhaseCount];
  r.particle_steps = v[kPhaseCount + 1];
  return r;
}

CostRates default_cost_rates() {
  // Measured on the dev box (docs/results/cost_model.md): /analysis/cost of short serial runs on
  // a machine shared with other jobs, each phase scaled by the process's CPU time over its wall
  // time. Particles: 4.7e6 (level_ice_cone), 4.2e6 (consolidated_layer_cone) and 4.1e6
  // (ridge_keel_8m_cone) particle-steps/s; the rigid world: 639 ns per block and solver
  // iteration (ridge_keel_8m_cone, 1,299 blocks, 120 iterations); output and the rest: 4-5 %.
  CostRates r;
  r.particle_step = 1.0 / 4.4e6;
  r.block_iteration = 6.4e-7;
  r.output_share = 0.05;
  return r;
}

CostEstimate estimate_cost(const CostInputs& in, const CostRates& r) {
  CostEstimate e;
  const bool converted = in.converted_particles > 0.0;  // all_at_start: no block moves in the run
  const double run_particles = in.particles + in.converted_particles;
  e.particles = run_particles * static_cast<double>(in.steps) * r.particle_step;
  const double block_iterations = static_cast<double>(in.movable_blocks) * in.solver_iterations * r.block_iteration;
  if (in.rigid_dt > 0.0 && in.movable_blocks > 0) {
    e.rigid_steps = std::floor(static_cast<double>(in.steps) * in.dt / in.rigid_dt + 1e-9);
    e.rigid = converted ? 0.0 : e.rigid_steps * block_iterations;
    e.relax_rigid_steps = std::ceil(in.relax_time / in.rigid_dt - 1e-9);
    e.relax_rigid = e.relax_rigid_steps * block_iterations;
  }
  if (in.dt > 0.0) {
    e.relax_steps = std::ceil(in.relax_time / in.dt - 1e-9);
    const double lattice_steps = std::ceil(in.relax_lattice_time / in.dt - 1e-9);
    e.relax_particles = (in.particles * e.relax_steps + run_particles * lattice_steps) * r.particle_step;
    e.relax_steps += lattice_steps;
  }
  e.other = r.output_share * (e.particles + e.rigid);
  return e;
}

namespace {

std::string fmt(const char* f, double a, double b) {
  char buf[96];
  std::snprintf(buf, sizeof buf, f, a, b);
  return buf;
}

}  // namespace

std::string cost_table(const RunCost& c) {
  const auto& info = phase_info();
  const double wall = std::max(c.wall, 1e-12);
  const auto s = [&](Phase p) { return c.phase(p); };
  struct Group {
    const char* label;
    Phase first, last;  // inclusive
  };
  const Group groups[] = {
      {"set-up", Phase::Read, Phase::Freeze},
      {"particles", Phase::ParticleForces, Phase::ParticleOther},
      {"rigid world", Phase::RigidWorld, Phase::RigidWorld},
      {"bridge", Phase::BridgeCoupling, Phase::BridgeConversion},
      {"output", Phase::Output, Phase::Output},
      {"MPI wait", Phase::MpiWait, Phase::MpiWait},
      {"analysis", Phase::Analysis, Phase::Analysis},
  };
  std::string out = "  cost (wall time, s, and share of the run's " + fmt("%.4g s", c.wall, 0) +
                    (c.processes > 1 ? ", " + std::to_string(c.processes) + " processes (restarts) together"
                                     : std::string()) +
                    (c.ranks > 1 ? "; mean over " + std::to_string(c.ranks) + " ranks, largest in brackets"
                                 : std::string()) +
                    "; /analysis/cost):\n";
  double step_total = 0.0;
  for (std::size_t k = kFirstStepPhase; k < kPhaseCount; ++k)
    if (static_cast<Phase>(k) != Phase::Analysis) step_total += c.seconds[k];
  for (const Group& g : groups) {
    double t = 0.0;
    for (int k = static_cast<int>(g.first); k <= static_cast<int>(g.last); ++k) t += s(static_cast<Phase>(k));
    char line[96];
    std::snprintf(line, sizeof line, "    %-12s %10.4g s %5.1f %%", g.label, t, 100.0 * t / wall);
    out += line;
    if (g.first != g.last) {
      std::string parts;
      for (int k = static_cast<int>(g.first); k <= static_cast<int>(g.last); ++k) {
        const double v = c.seconds[static_cast<std::size_t>(k)];
        if (v <= 0.0 && g.first == Phase::Read) continue;  // set-up stages that did not run
        parts += (parts.empty() ? "" : ", ") + std::string(info[static_cast<std::size_t>(k)].label) + " " +
                 fmt("%.3g", v, 0);
        if (c.ranks > 1) parts += fmt(" (%.3g)", c.max[static_cast<std::size_t>(k)], 0);
      }
      out += ": " + parts;
    } else if (c.ranks > 1) {
      out += fmt(" (%.4g s)", c.max[static_cast<std::size_t>(g.first)], 0);
    }
    out += "\n";
  }
  const double rest = c.wall - c.sum();
  {
    char line[96];
    std::snprintf(line, sizeof line, "    %-12s %10.4g s %5.1f %%\n", "unaccounted", rest, 100.0 * rest / wall);
    out += line;
  }
  // The step's shares (set-up and analysis left out): where a longer run's time goes.
  const double st = std::max(step_total, 1e-12);
  const auto share = [&](double v) { return fmt("%.0f %%", 100.0 * v / st, 0); };
  out += "    per step: particles " + share(s(Phase::ParticleForces) + s(Phase::ParticleOther)) + ", rigid world " +
         share(s(Phase::RigidWorld)) + ", bridge " +
         share(s(Phase::BridgeCoupling) + s(Phase::BridgeStress) + s(Phase::BridgePolicy) +
               s(Phase::BridgeConversion)) +
         ", output " + share(s(Phase::Output)) + ", MPI wait " + share(s(Phase::MpiWait)) + " (" +
         std::to_string(c.steps) + " steps, " + std::to_string(c.rigid_steps) + " rigid steps, " +
         fmt("%.3g particle-steps)\n", c.particle_steps, 0);
  return out;
}

}  // namespace hs::sim
