// `hybridsim run`, `check` and `iso`. The run is the pipeline of README "Architecture":
// load the scene -> build the simulation -> step it while the recorders write the series ->
// analyse and report.
#include "app/run.h"
#include "sim/calibrated_ice.h"

#include "analysis/iso19906.h"
#include "app/checkpoint.h"
#include "app/output_lock.h"
#include "app/output_path.h"
#include "app/metrics_command.h"
#include "app/progress.h"
#include "app/run_summary.h"
#include "app/stop_signal.h"
#include "app/text.h"
#include "common/error.h"
#include "io/run_file.h"
#include "parallel/comm.h"
#include "scene/scene.h"
#include "sim/metrics.h"
#include "sim/recorder.h"
#include "sim/report.h"
#include "sim/simulation.h"
#include "sim/member_ridge.h"

#include <chrono>
#include <csignal>
#include <cmath>
#include <functional>
#include <cstdint>
#include <filesystem>
#include <optional>

namespace hs::app {

namespace {

namespace fs = std::filesystem;

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

void print_warnings(const std::vector<std::string>& warnings, std::FILE* err) {
  for (const auto& w : warnings) std::fprintf(err, "warning: %s\n", w.c_str());
}

/// `restart_changes`: the stability limits the restarts that led here moved (Restart::changes),
/// kept as the root attribute "restart_changes" when there are any.
io::RunFileMeta run_file_meta(const scene::Scene& s, const sim::CalibratedIce& ice, const par::Comm& comm, bool fsync,
                              const std::vector<std::string>& restart_changes) {
  io::RunFileMeta meta;
  if (!restart_changes.empty())
    meta.root_attributes.emplace_back("restart_changes", nlohmann::json(restart_changes).dump());
  meta.write_to_partial = true;  // an existing result is replaced only by a run that closed its file
  meta.fsync_on_flush = fsync;
  meta.scene_text = s.json.dump(2);
  meta.program_version = HYBRIDSIM_VERSION;
  meta.root_attributes.emplace_back("calibrated_ice", sim::calibrated_ice_to_json(ice).dump());
  meta.comm = &comm;
  return meta;
}

/// Under MPI the ranks agree every this many steps whether to flush or stop (one allreduce of
/// two doubles; docs/output.md gives the measured cost). Serial runs look every step.
constexpr std::uint64_t kMpiPollSteps = 16;

/// What the ranks decided after a step: flush the file now, stop (the signal) or go on.
struct PollResult {
  bool flush = false;
  int stop = 0;
  double mpi_seconds = 0.0;  ///< wall time in the agreement's collective (the run's cost)
};

/// The loop's look at the world outside the simulation after step k: a SIGINT/SIGTERM received,
/// or the wall-clock flush interval passed. Under MPI both are agreed collectively (max over the
/// ranks) every kMpiPollSteps steps, so every rank flushes and stops after the same step and no
/// rank is left waiting in a collective.
class LoopPoll {
 public:
  LoopPoll(const par::Comm& comm, const StopSignals& signals, double flush_interval)
      : comm_(comm), signals_(signals), every_(comm.parallel() ? kMpiPollSteps : 1), interval_(flush_interval),
        last_flush_(Clock::now()) {}
  PollResult after_step(std::uint64_t k, std::uint64_t total) {
    raise_test_signal("loop", k, comm_.rank());
    if (k % every_ != 0 && k != total) return {};
    const auto now = Clock::now();
    double v[2] = {static_cast<double>(signals_.received()),
                   std::chrono::duration<double>(now - last_flush_).count() >= interval_ ? 1.0 : 0.0};
    PollResult r;
    if (comm_.parallel()) {
      comm_.max(v, 2);
      r.mpi_seconds = seconds_since(now);
    }
    r.stop = static_cast<int>(v[0]);
    r.flush = v[1] > 0.0;
    if (r.flush) last_flush_ = now;
    return r;
  }

 private:
  const par::Comm& comm_;
  const StopSignals& signals_;
  std::uint64_t every_;
  double interval_;
  Clock::time_point last_flush_;
};

/// The particles every movable block would become: their volume / (D^3 / sqrt 2), the HCP cell.
double particles_if_all_converted(const scene::Scene& s, const sim::Simulation& sim) {
  double vol = 0.0;
  for (const auto& bi : sim.blocks().blocks)
    if (!bi.def.fixed) vol += 8.0 * bi.def.half_extents.prod();  // walls and floors never convert
  const double D = s.material.particle_diameter;
  return vol / (D * D * D / std::sqrt(2.0));
}

void print_check_blocks(std::ostream& out, const scene::Scene& s, const sim::Simulation& sim) {
  const auto& hsu = sim.blocks();
  double vol = 0.0;
  std::size_t fixed = 0;
  for (const auto& bi : hsu.blocks) {
    if (bi.def.fixed) {  // walls and floors: never ice to convert
      ++fixed;
      continue;
    }
    vol += 8.0 * bi.def.half_extents.prod();
  }
  const double est = particles_if_all_converted(s, sim);
  const sim::RunStats st = sim.run_stats();
  const sim::BlockReport& r = st.blocks;
  out << "blocks:           " << hsu.blocks.size() << " rigid (" << hsu.ridge_blocks_in_file << " in the ridge file";
  if (fixed) out << ", " << fixed << " fixed";
  if (hsu.loose_blocks_dropped)
    out << ", " << hsu.loose_blocks_dropped << " without a joint left out: blocks.loose_blocks";
  out << "), " << hsu.joints.size() << " freeze joints, " << sci(vol, 4) << " m^3 of ice (~" << sci(est, 3)
      << " particles if all converted); conversion \"" << st.conversion << "\"\n";
  out << "rigid step:       " << sci(r.rigid_dt, 4) << " s = " << r.steps_per_rigid_step
      << " DEM steps (stability limit " << sci(r.rigid_dt_limit, 4) << " s)\n";
  const auto& x = s.blocks.relax;
  if (x.enabled)
    out << "relaxation:       before the freeze, up to " << x.max_time << " s simulated (at rest: below " << x.speed
        << " m/s for " << x.hold << " s" << (x.damping > 0 ? ", damping " + sci(x.damping, 3) + " 1/s" : std::string())
        << ")"
        << (x.jointed_time > 0 ? ", then up to " + sci(x.jointed_time, 3) + " s with the joints between blocks held"
                               : std::string())
        << (x.lattice_time > 0 && s.blocks.conversion == "all_at_start"
                ? ", then up to " + sci(x.lattice_time, 3) + " s of the converted lattices"
                : std::string())
        << "\n";
  else
    out << "relaxation:       off (joints and freeze bonds made at the blocks' starting poses)\n";
}

/// The relaxation before the freeze at its longest, s simulated (0: none).
double longest_relaxation(const scene::Scene& s) {
  const auto& x = s.blocks.relax;
  if (!s.has_blocks || !x.enabled) return 0.0;
  return x.max_time + x.jointed_time + (s.blocks.conversion == "all_at_start" ? x.lattice_time : 0.0);
}


/// What the run-time estimate counts for a scene built as `check` builds it.
sim::CostInputs cost_inputs(const scene::Scene& s, const sim::Simulation& sim) {
  sim::CostInputs in;
  in.particles = static_cast<double>(sim.built().particles);
  in.steps = sim.schedule().total_steps;
  in.dt = sim.dt();
  if (sim.has_blocks()) {
    for (const auto& bi : sim.blocks().blocks) in.movable_blocks += bi.def.fixed ? 0 : 1;
    in.rigid_dt = sim.hybrid().report().rigid_dt;
    in.solver_iterations = s.blocks.solver_iterations;
    in.relax_time = longest_relaxation(s);
    if (s.blocks.conversion == "all_at_start") {
      // The blocks turn into lattices: after the rigid stages with lattice_time (docs/bridge.md,
      // "all_at_start: the lattices relax"), else before the whole relaxation.
      in.converted_particles = particles_if_all_converted(s, sim);
      const auto& x = s.blocks.relax;
      in.relax_lattice_time = x.lattice_time > 0 ? x.lattice_time : in.relax_time;
      in.relax_time -= in.relax_lattice_time;
    }
  }
  return in;
}

/// `check`'s run-time estimate (sim::estimate_cost, one core): the run's particles and rigid world,
/// the relaxation at its longest. Returns the total, s.
double print_time_estimate(std::ostream& out, const scene::Scene& s, const sim::Simulation& sim) {
  const sim::CostInputs in = cost_inputs(s, sim);
  const sim::CostRates rates = sim::default_cost_rates();
  const sim::CostEstimate e = sim::estimate_cost(in, rates);
  out << "estimated time:   " << duration_text(e.total()) << " on one core: the run " << duration_text(e.run())
      << " (particles " << duration_text(e.particles) << ": "
      << sci((in.particles + in.converted_particles) * in.steps, 3) << " particle-steps at ~"
      << sci(1.0 / rates.particle_step, 2) << "/s"
      << (in.converted_particles > 0 ? ", the blocks' ~" + sci(in.converted_particles, 3) + " particles included"
                                     : std::string());
  if (in.movable_blocks && e.rigid > 0)
    out << "; rigid world " << duration_text(e.rigid) << ": " << in.movable_blocks << " blocks x "
        << sci(e.rigid_steps, 3) << " rigid steps x " << in.solver_iterations << " solver iterations at ~"
        << sci(rates.block_iteration * 1e9, 2) << " ns";
  out << "; output and the rest ~" << sci(100.0 * rates.output_share, 2) << " %)";
  if (in.relax_time + in.relax_lattice_time > 0)
    out << " + the relaxation at most " << duration_text(e.relaxation()) << " ("
        << sci(in.relax_time + in.relax_lattice_time, 3)
        << " s simulated: particles " << duration_text(e.relax_particles) << ", rigid world "
        << duration_text(e.relax_rigid) << ")";
  out << "\n";
  return e.total();
}

/// The output path is writable and is none of the scene's input files.
void check_run_output(const std::string& out_path, const std::string& scene_path, const scene::Scene& s) {
  std::vector<InputFile> inputs{{"the scene file", scene_path}};
  if (s.has_structure && s.structure.type == "mesh") inputs.push_back({"the structure mesh", s.structure.mesh_path});
  if (s.has_blocks) inputs.push_back({"the ridge file", s.blocks.ridge_file_path});
  check_output_path(out_path, std::filesystem::path(out_path).replace_extension(".xmf").string(), inputs);
}

/// `check` warns (issue 14, item 4) when the estimates pass these limits.
constexpr double kWarnRunSeconds = 86400.0;                       // one day on one core
constexpr double kWarnOutputBytes = 10.0 * 1024 * 1024 * 1024;    // 10 GiB

void warn_past_limits(std::ostream& err, double run_seconds, double file_bytes, const std::string& output) {
  if (run_seconds > kWarnRunSeconds)
    err << "warning: /time/duration: the run is estimated at " << duration_text(run_seconds)
        << " on one core (more than a day); check /time/duration, /time/dt and the sheet size, or plan an mpirun\n";
  std::error_code ec;
  fs::path dir = fs::absolute(fs::path(output), ec).parent_path();
  const fs::space_info sp = fs::space(dir, ec);
  const bool too_big_for_disk = !ec && file_bytes > static_cast<double>(sp.available);
  if (file_bytes > kWarnOutputBytes || too_big_for_disk)
    err << "warning: /time/snapshot_interval: the output file is estimated at ~" << sci(file_bytes / 1073741824.0, 3)
        << " GiB" << (too_big_for_disk ? " (more than the " + sci(sp.available / 1073741824.0, 3) + " GiB free in " +
                                             dir.string() + ")"
                                       : std::string(" (more than 10 GiB)"))
        << "; increase /time/snapshot_interval (snapshots dominate) or /time/output_interval\n";
}

}  // namespace

namespace {

/// The scene built as `check` builds it: blocks counted, not converted; no relaxation; dt not checked.
sim::Simulation build_for_check(const scene::Scene& s, const RunOptions& opt) {
  return sim::build_simulation(
      s, par::serial(),
      {.check_dt = false, .convert = false, .ignore_memory_limit = opt.ignore_memory_limit, .relax = false});
}

}  // namespace

double estimated_core_seconds(const RunOptions& opt) {
  const scene::Scene s = scene::load_scene_file(opt.scene_path, opt.overrides);
  return sim::estimate_cost(cost_inputs(s, build_for_check(s, opt))).total();
}

int check_scene(const RunOptions& opt, std::ostream& out, std::ostream& err) {
  const scene::Scene s = scene::load_scene_file(opt.scene_path, opt.overrides);
  for (const auto& w : s.warnings) err << "warning: " << w << "\n";
  // dt is checked last, after the figures that explain it.
  const sim::Simulation sim = build_for_check(s, opt);
  for (const auto& w : sim.warnings()) err << "warning: " << w << "\n";
  const sim::Built& b = sim.built();
  const double dt = sim.dt(), crit = sim.critical_time_step();
  const sim::Schedule& sc = sim.schedule();
  const std::uint64_t rows = sc.total_steps / sc.output_every + 1;
  const std::uint64_t snaps = sc.snapshot_every ? sc.total_steps / sc.snapshot_every + 1 : 0;
  const double file_bytes = snaps * b.particles * (7 * 8 + 4 + 8) + rows * (8 * 16 + 6 * s.walls.size() * 8);
  out << "scene:            " << s.name << (s.description.empty() ? "" : " - " + s.description) << "\n";
  out << "particles:        " << b.particles << " (D = " << s.material.particle_diameter << " m, "
      << b.layout.layers << " layers";
  if (b.layout.consolidated_layers) out << ", " << b.layout.consolidated_layers << " in the consolidated layer";
  out << "; ice top z = " << sci(b.layout.top_z, 4) << " m, bottom z = " << sci(b.layout.bottom_z, 4) << " m)\n";
  out << "bonds:            " << b.bonds << " (" << sci(b.particles ? 2.0 * b.bonds / b.particles : 0.0, 3)
      << " per particle)\n";
  {
    const sim::CalibratedIce& ci = b.calibrated;
    for (const auto& w : ci.warnings) err << "warning: " << w << "\n";
    out << "ice:              " << ci.model << ": k_n = " << sci(ci.kn, 4) << " N/m, k_s = " << sci(ci.ks, 4)
        << " N/m; lattice E = " << sci(ci.youngs_modulus, 4) << " Pa, nu = " << sci(ci.poisson_ratio, 3)
        << ", flexural strength " << sci(ci.flexural_strength, 4) << " Pa (bonds " << sci(ci.bond_tensile_strength, 4)
        << " Pa from " << ci.strength_source;
    if (std::isfinite(s.bonds.compressive_strength_ratio))
      out << "; in compression " << sci(s.bonds.compressive_strength_ratio * ci.bond_tensile_strength, 4)
          << " Pa = bonds.compressive_strength_ratio " << s.bonds.compressive_strength_ratio << " x";
    if (s.bonds.strength_spread > 0)
      out << "; each lattice bond's strengths x a factor of its own, lognormal of mean 1 and sd "
          << s.bonds.strength_spread << ", seed " << s.seed;
    out << ")\n";
  }
  out << "walls:            " << s.walls.size() << "\n";
  if (sim.has_structure()) {
    const auto& st = s.structure;
    std::string parts;
    for (const auto& p : b.structure_parts) parts += (parts.empty() ? "" : ", ") + p;
    out << "structure:        '" << st.name << "' (" << st.type << "; parts " << parts << "), widest radius "
        << sci(b.structure_radius, 4) << " m, at (" << st.position.transpose() << ") m, velocity ("
        << st.velocity.transpose() << ") m/s\n";
  }
  if (s.has_blocks) print_check_blocks(out, s, sim);
  out << "time step:        dt = " << sci(dt, 4) << " s" << (s.time.dt == 0 ? " (paper Eq. 2)" : "")
      << ", critical dt = " << sci(crit, 4) << " s (margin x" << sci(crit / dt, 3) << ")\n";
  out << "steps:            " << sc.total_steps << " for " << s.time.duration << " s; " << rows
      << " series rows, " << snaps << " snapshots\n";
  const double ice_bytes = sim::engine_memory_bytes(b.particles, b.bonds, s.walls.size());
  sim::MemoryEstimate blocks;
  sim::add_blocks(blocks, sim.blocks(), s.material.particle_diameter, s.walls.size());
  out << "estimated memory: " << sci((ice_bytes + blocks.block_bytes) / 1048576.0, 3) << " MiB";
  if (blocks.blocks > 0) {
    out << " (ice " << sci(ice_bytes / 1048576.0, 3) << " MiB, blocks " << sci(blocks.block_bytes / 1048576.0, 3)
        << " MiB";
    if (blocks.block_particles > 0) out << " with ~" << sci(blocks.block_particles, 3) << " particles if all convert";
    out << ")";
  }
  out << "; output file ~" << sci(file_bytes / 1048576.0, 3) << " MiB\n";
  const double run_seconds = print_time_estimate(out, s, sim);
  out << "output:           " << (opt.output.empty() ? s.output : opt.output) << "\n";
  warn_past_limits(err, run_seconds, file_bytes, opt.output.empty() ? s.output : opt.output);
  sim.check_time_step();  // InputError at /time/dt, after the figures that explain it
  out << "ok\n";
  return 0;
}

namespace {

/// After an instability (SimulationError, seen alike on every rank): writes the last completed
/// step as a snapshot (the failed step's state is not written) and closes the file.
void keep_last_good_and_close(const sim::Simulation& sim, sim::Recorders& rec, io::RunFile& file,
                              const std::string& out_path, std::FILE* progress) {
  std::string kept;
  try {
    const std::uint64_t good = rec.write_last_good(file);
    kept = ", and the last good state (step " + std::to_string(good) + ", t = " +
           sci(rec.last_good_time(), 6) + " s) as snapshot " + std::to_string(file.snapshot_count() - 1);
  } catch (const std::exception& ex) {
    std::fprintf(progress, "hybridsim: could not write the last good state: %s\n", ex.what());
  }
  file.close();
  std::fprintf(progress, "hybridsim: series rows up to the last output before t = %g s%s kept in %s\n",
               sim.time(), kept.c_str(), out_path.c_str());
}

/// A word of a shell command, quoted when it needs it.
std::string shell_word(const std::string& w) {
  if (!w.empty() && w.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-+=.,/:@%") ==
                        std::string::npos)
    return w;
  std::string q = "'";
  for (const char c : w) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

/// The command that continues this run from its checkpoint.
std::string resume_command(const RunOptions& opt, const std::string& out_path, const par::Comm& comm) {
  std::string c = comm.parallel() ? "mpirun -np " + std::to_string(comm.size()) + " hybridsim run" : "hybridsim run";
  c += " " + shell_word(opt.scene_path);
  for (const auto& o : opt.overrides) c += " --set " + shell_word(o);
  c += " --restart " + shell_word(out_path);
  return c;
}

/// A run stopped by SIGINT/SIGTERM after step `last`: says what was kept and how to continue,
/// returns 128 + signal.
int report_stopped(int stop, std::uint64_t last, const scene::Scene& s, const sim::Simulation& sim, double wall,
                   const std::string& out_path, const std::string& resume, std::FILE* progress) {
  const std::uint64_t steps = sim.schedule().total_steps;
  const double t = sim.time();
  std::fprintf(progress,
               "hybridsim: stopped by %s after step %llu of %llu (t = %s s of %g s, %.1f s wall). Series rows up "
               "to t = %s s%s are in %s (closed)%s; no /analysis was written.\n"
               "hybridsim: %s%s\n"
               "hybridsim: exit code %d.\n",
               signal_name(stop), static_cast<unsigned long long>(last), static_cast<unsigned long long>(steps),
               sci(t, 6).c_str(), s.time.duration, wall, sci(t, 6).c_str(),
               sim.schedule().snapshot_every ? " and a snapshot of that step" : "", out_path.c_str(),
               last < steps ? (", the checkpoint of that step in " + io::checkpoint_path(out_path)).c_str() : "",
               last < steps ? "to continue the run: " : "the run had reached its last step",
               last < steps ? resume.c_str() : "", stopped_exit_code(stop));
  return stopped_exit_code(stop);
}

/// The relaxation's look outside after each rigid step: a progress line every 5 s of wall, and
/// whether SIGINT/SIGTERM asks it to stop (under MPI agreed every kMpiPollSteps calls).
std::function<bool(const sim::RelaxProgress&)> relaxation_poll(const scene::Scene& s, const par::Comm& comm,
                                                                  const StopSignals& signals, std::FILE* progress) {
  return [&s, &comm, &signals, progress, last_line = Clock::now(),
          calls = std::uint64_t{0}](const sim::RelaxProgress& p) mutable {
    raise_test_signal("relax", ++calls, comm.rank());
    if (seconds_since(last_line) >= 5.0) {
      last_line = Clock::now();
      std::fprintf(progress,
                   "relax%s t = %.4g s of at most %g s: fastest block %.3g m/s at (%.4g %.4g %.4g), particle %.3g m/s "
                   "at (%.4g %.4g %.4g), block KE %.3g J, below %g m/s for %.3g s, lattice bonds broken %llu\n",
                   p.stage == 2 ? " (jointed stage)" : p.stage == 3 ? " (lattice stage)" : "", p.time,
                   s.blocks.relax.max_time + (p.stage >= 2 ? s.blocks.relax.jointed_time : 0.0) +
                       (p.stage == 3 ? s.blocks.relax.lattice_time : 0.0),
                   p.max_block_speed,
                   p.fastest_block.x(), p.fastest_block.y(), p.fastest_block.z(), p.max_particle_speed,
                   p.fastest_particle.x(), p.fastest_particle.y(), p.fastest_particle.z(), p.block_kinetic_energy,
                   s.blocks.relax.speed, p.quiet_time, static_cast<unsigned long long>(p.lattice_bonds_broken));
      std::fflush(progress);
    }
    if (comm.parallel() && calls % kMpiPollSteps != 0) return false;
    double v = signals.received();
    if (comm.parallel()) comm.max(&v, 1);
    return v > 0.0;
  };
}

}  // namespace

namespace {

/// What a run reads before it builds anything: the scene, its ice, a restart's checkpoint and
/// where the output goes.
struct RunInput {
  scene::Scene s;
  double read_seconds = 0.0, calibration_seconds = 0.0;  ///< the run's cost: scene and checkpoint read, calibration
  sim::CalibratedIce ice;           ///< calibrate_ice(s), once for the run (warnings, build, run file)
  std::optional<Restart> restart;   ///< --restart: the checkpoint and the rows before it
  std::string out_path, ckpt_path;  ///< the run file and its checkpoint
  std::vector<std::string> changes; ///< Restart::changes (none without a restart)
  OutputLocks locks;                ///< the output and its checkpoint, held for the run's lifetime
};

/// Locks the run file and its checkpoint, and (with --restart) the run being continued, so that a
/// run writing any of them is refused here, before anything is read or written. A restart's own
/// run is locked while this run lasts: nothing else may continue it or write into it meanwhile.
OutputLocks lock_outputs(const RunOptions& opt, const RunInput& in, const std::optional<RestartFiles>& from,
                         const par::Comm& comm) {
  const std::string out_option = !opt.output.empty() ? "-o" : from ? "--restart" : "/output";
  std::vector<LockedFile> files{{in.out_path, "the output file", out_option},
                                {in.ckpt_path, "the output's checkpoint", out_option}};
  if (from) {
    files.push_back({io::strip_partial(from->run_file), "the restarted run's file", "--restart"});
    files.push_back({from->checkpoint_file, "the restarted run's checkpoint", "--restart"});
  }
  return OutputLocks(files, comm);
}

/// 1. load: the scene file, --set overrides applied, validated; with --restart the checkpoint and
/// the rows before it, read before anything is created (the output may be the restarted file
/// itself; it defaults to that run file). The output path is checked here, before the long work.
RunInput load_run(const RunOptions& opt, const par::Comm& comm, std::FILE* progress) {
  RunInput in;
  auto t = Clock::now();
  in.s = scene::load_scene_file(opt.scene_path, opt.overrides);
  in.read_seconds = seconds_since(t);
  const scene::Scene& s = in.s;
  print_warnings(s.warnings, progress);
  t = Clock::now();
  in.ice = sim::calibrate_ice(s);
  in.calibration_seconds = seconds_since(t);
  print_warnings(in.ice.warnings, progress);
  std::optional<RestartFiles> from;
  if (!opt.restart.empty()) from = restart_files(opt.restart);
  in.out_path = !opt.output.empty() ? opt.output : from ? io::strip_partial(from->run_file) : s.output;
  check_run_output(in.out_path, opt.scene_path, s);  // before the long work: exit 2, file untouched
  in.ckpt_path = io::checkpoint_path(in.out_path);
  in.locks = lock_outputs(opt, in, from, comm);  // exit 2 while another run writes any of them
  t = Clock::now();
  if (from) in.restart = read_restart(opt.restart, s, comm);
  in.read_seconds += seconds_since(t);
  if (sim::ridge_per_seed(in.s)) {  // the member's own ridge (docs/ridge.md, "A ridge per seed")
    const std::string out_dir = fs::absolute(fs::path(in.out_path)).parent_path().string();
    const sim::MemberRidge r =
        sim::prepare_member_ridge(in.s, opt.no_cache ? "" : sim::default_cache_dir(), out_dir, comm, progress);
    if (!r.generated)
      std::fprintf(progress, "hybridsim: the ridge of seed %llu from the cache: %s\n",
                   static_cast<unsigned long long>(in.s.seed), r.path.c_str());
  }
  if (in.restart) in.changes = in.restart->changes;
  for (std::size_t k = in.restart ? in.restart->carried_changes : 0; k < in.changes.size(); ++k)
    std::fprintf(progress, "hybridsim: restart changes %s\n", in.changes[k].c_str());
  return in;
}

/// 2. build: particles, walls, structure, blocks, schedule; each rank keeps its share. A restart
/// takes the relaxed ridge from the checkpoint instead of relaxing again. The relaxation before
/// the freeze may take minutes: a progress line every few seconds, and SIGINT/SIGTERM stop it
/// (nothing is written yet): then no simulation, and `stopped` = 128 + signal. Every rank relaxes
/// alike, so under MPI they agree on a stop every 16 rigid steps.
std::optional<sim::Simulation> build_run(const RunOptions& opt, const RunInput& in, const par::Comm& comm,
                                         const StopSignals& signals, Clock::time_point t_setup, std::FILE* progress,
                                         int& stopped) {
  sim::BuildOptions build{.ignore_memory_limit = opt.ignore_memory_limit, .calibrated = &in.ice};
  if (in.restart) build.restart_state = in.restart->all.empty() ? &in.restart->state : &in.restart->all.front();
  build.relax_progress = relaxation_poll(in.s, comm, signals, progress);
  build.relaxation_cache = {.dir = opt.no_cache ? "" : sim::default_cache_dir(), .file = opt.relaxation};
  std::optional<sim::Simulation> built;
  try {
    built.emplace(sim::build_simulation(in.s, comm, build));
  } catch (const sim::RelaxationStopped& e) {
    const int sig = signals.received() ? signals.received() : SIGINT;
    std::fprintf(progress,
                 "hybridsim: stopped by %s during the relaxation before the freeze (t = %s s of relaxation, "
                 "%.1f s wall); nothing was written (the run file is made after the relaxation) and there is no "
                 "checkpoint: run it again to start over.\nhybridsim: exit code %d.\n",
                 signal_name(sig), sci(e.time, 4).c_str(), seconds_since(t_setup), stopped_exit_code(sig));
    stopped = stopped_exit_code(sig);
  }
  return built;
}

/// How the loop ended.
struct LoopEnd {
  int stop = 0;             ///< the signal that stopped the run, 0 if none
  std::uint64_t last = 0;   ///< the last step completed
  std::uint64_t first = 0;  ///< the step this process started from (a restart's checkpoint step)
  double wall = 0.0;        ///< s of the loop
};

/// 3. loop: step, then the recorders (per-step sums; rows and snapshots when due), then the
/// poll: a wall-clock flush when due, a graceful stop on SIGINT/SIGTERM (a checkpoint, the rows
/// of that step). Closes the file; after an instability the last good state is kept first.
/// Everything but the step (timed inside it) and the poll's collective is the run's output cost.
LoopEnd run_loop(const RunOptions& opt, RunInput& in, sim::Simulation& sim, sim::Recorders& rec, io::RunFile& file,
                 const par::Comm& comm, const StopSignals& signals, std::FILE* progress) {
  const auto t0 = Clock::now();
  sim::CostLedger& cost = sim.cost_ledger();
  auto t_out = t0;  // the output phase's running start
  const std::uint64_t steps = sim.schedule().total_steps;
  ProgressLine bar(progress, in.s.time.duration, steps);
  LoopEnd end;
  const std::uint64_t ckpt_every = sim.schedule().checkpoint_every;
  try {
    LoopPoll poll(comm, signals, opt.flush_interval);
    if (in.restart) {  // the state and the rows of the checkpoint; the loop goes on from its step
      end.last = apply_restart(*in.restart, sim, rec, file, progress);
      cost.add(sim::Phase::Read, seconds_since(t_out));  // the checkpoint's state and rows
      t_out = Clock::now();
      end.first = end.last;
      bar.start_at(end.last);
      std::fprintf(progress, "hybridsim: restarted from %s at step %llu (t = %s s)\n",
                   in.restart->checkpoint_file.c_str(), static_cast<unsigned long long>(end.last),
                   sci(sim.time(), 6).c_str());
      in.restart.reset();
    } else {
      rec.write_initial(sim, file);  // row 0: the initial state
    }
    file.flush();
    cost.add(sim::Phase::Output, seconds_since(t_out));
    for (std::uint64_t k = end.last + 1; k <= steps; ++k) {
      sim.step();                    // particles one DEM step; blocks every rigid step
      t_out = Clock::now();
      rec.after_step(k, sim, file);  // sums and peaks; rows and snapshots when due
      bar.update(k, sim);            // progress line
      end.last = k;
      const PollResult p = poll.after_step(k, steps);
      cost.add(sim::Phase::MpiWait, p.mpi_seconds);
      double lap_mpi = p.mpi_seconds;  // in MpiWait, not in this lap's output
      const auto end_lap = [&] {
        cost.add(sim::Phase::Output, seconds_since(t_out) - lap_mpi);
        lap_mpi = 0.0;
        t_out = Clock::now();
      };
      // A checkpoint carries the output up to its own moment (CostLedger::output_lap).
      const auto checkpoint = [&] {
        end_lap();
        cost.output_lap = t_out;
        write_checkpoint(in.ckpt_path, in.s, sim, rec, file, comm, in.changes);
        cost.output_lap.reset();
      };
      if (p.stop) {  // finish here: a checkpoint, the rows (and snapshot) of this step, then close below
        end.stop = p.stop;
        if (k < steps) checkpoint();  // before write_stop's extra rows
        rec.write_stop(k, sim, file);
        end_lap();
        break;
      }
      if (ckpt_every && k % ckpt_every == 0 && k < steps)
        checkpoint();
      else if (p.flush)
        file.flush();
      end_lap();
    }
  } catch (const SimulationError&) {
    bar.end();
    keep_last_good_and_close(sim, rec, file, in.out_path, progress);
    throw;
  } catch (const std::exception& ex) {
    if (!comm.parallel()) throw;
    // Under MPI an error may have struck this rank alone; closing the file (collective) would
    // wait for the others forever. Report and end all ranks; the file holds the last flush.
    std::fprintf(stderr, "error (rank %d): %s; aborting all ranks, %s holds the output up to the last flush\n",
                 comm.rank(), ex.what(), file.writing_path().c_str());
    comm.abort(1);
  }
  t_out = Clock::now();
  bar.end();
  file.close();
  cost.add(sim::Phase::Output, seconds_since(t_out));
  end.wall = seconds_since(t0);
  return end;
}

}  // namespace

int run_scene(const RunOptions& opt, std::ostream& out, std::FILE* progress) {
  const par::Comm& comm = opt.comm ? *opt.comm : par::serial();
  // The first SIGINT/SIGTERM is recorded, not fatal, from here to the return: the relaxation polls
  // it (stop, nothing written), the loop polls it (finish the step, checkpoint, close); one that
  // arrives between the two stops the loop at its first poll (step 1, or 16 under MPI), and one
  // after the last step lets the report finish, so a single signal never kills the process with
  // its run file open (a second one does: the handler is one-shot).
  const auto t_start = Clock::now();  // the run's wall time (/analysis/cost) counts from here
  StopSignals signals;
  RunInput in = load_run(opt, comm, progress);  // 1. load
  const scene::Scene& s = in.s;
  const auto t_setup = Clock::now();
  int stopped = 0;
  std::optional<sim::Simulation> built = build_run(opt, in, comm, signals, t_setup, progress, stopped);  // 2. build
  if (!built) return stopped;
  sim::Simulation& sim = *built;
  sim::CostLedger& cost = sim.cost_ledger();
  cost.start = t_start;
  cost.add(sim::Phase::Read, in.read_seconds);
  cost.add(sim::Phase::Calibration, in.calibration_seconds);
  const auto t_file = Clock::now();
  print_warnings(sim.warnings(), progress);
  io::RunFile file(in.out_path, run_file_meta(s, sim.built().calibrated, comm, opt.fsync, in.changes));
  sim::Recorders rec(sim, s, comm);
  rec.declare(file);
  const RunCounts start = print_setup(progress, s, sim, seconds_since(t_setup), comm);
  cost.add(sim::Phase::Output, seconds_since(t_file));
  const LoopEnd end = run_loop(opt, in, sim, rec, file, comm, signals, progress);  // 3. loop
  if (end.stop)
    return report_stopped(end.stop, end.last, s, sim, end.wall, in.out_path, resume_command(opt, in.out_path, comm),
                          progress);

  // 4. report: pieces, ISO beside the run, the hybrid outcome, the cost -> /analysis and the summary
  const auto t_analysis = Clock::now();
  const sim::RunFigures fig = rec.figures();
  comm.barrier();  // every rank's close has completed before rank 0 reopens the file
  std::optional<sim::PileAtLoadPeak> at_peak;  // ISO's pile at the load peak, from the file (rank 0)
  if (comm.rank() == 0 && sim.has_structure() && s.structure.type == "pier") at_peak = sim::pile_at_load_peak(in.out_path);
  sim::RunReport an = sim::analyse_run(sim, s, fig, comm, at_peak);
  cost.add(sim::Phase::Analysis, seconds_since(t_analysis));
  an.cost = sim::reduce_cost(sim.cost(), comm);  // collective
  comm.barrier();  // every rank's close has completed before rank 0 reopens the file
  if (comm.rank() == 0) sim::write_analysis(in.out_path, an);
  print_summary(out, s, sim, fig, an, RunEnd{start, end.wall, in.out_path, end.first}, comm);
  if (comm.rank() == 0 && sim.has_structure()) {  // from the file: the one definition (docs/metrics.md)
    const std::vector<analysis::Metric> metrics = sim::compute_run_metrics(in.out_path);
    sim::write_run_metrics(in.out_path, metrics);
    print_metrics_table(out, metrics);
  }
  if (signals.received())
    std::fprintf(progress, "hybridsim: %s received after the last step: the run was complete and its report is written\n",
                 signal_name(signals.received()));
  return 0;
}

int iso_command(const RunOptions& opt, std::ostream& out) {
  nlohmann::json j = scene::read_json_file(opt.scene_path);
  analysis::IsoInputs in;
  nlohmann::json sources;
  if (j.is_object() && (j.contains("time") || j.contains("ice"))) {
    // A scene without a run: nominal thickness, h_r = analysis.rubble_height, the ridge file's keel.
    const scene::Scene s = scene::load_scene_file(opt.scene_path, opt.overrides);
    sim::IsoMeasured m;
    m.ridge = sim::scene_ridge_keel(s);
    const sim::IsoAssembly a = sim::assemble_iso_inputs(s, m);
    in = a.in;
    for (const auto& r : a.records) sources[r.key] = sim::to_string(r.source);
  } else {
    if (!opt.overrides.empty())
      throw InputError("--set", "--set applies to scenes; edit the ISO object instead");
    in = analysis::iso_inputs_from_json(j, "");
  }
  const analysis::IsoResult r = analysis::compute_iso(in);
  nlohmann::json o = analysis::iso_to_json(r);
  o["inputs"] = analysis::iso_inputs_to_json(in);
  if (!sources.is_null()) o["sources"] = sources;
  out << o.dump(2) << "\n";
  return 0;
}

}  // namespace hs::app
