#include "app/run.h"

#include "bonded/engine.h"
#include "common/error.h"
#include "io/run_file.h"
#include "scene/scene.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <iomanip>
#include <sstream>

namespace hs::app {

namespace {

using Clock = std::chrono::steady_clock;

std::string duration_text(double s) {
  if (!std::isfinite(s) || s < 0) return "?";
  const long t = std::lround(s);
  char buf[64];
  if (t >= 3600)
    std::snprintf(buf, sizeof buf, "%ld:%02ld:%02ld", t / 3600, (t / 60) % 60, t % 60);
  else
    std::snprintf(buf, sizeof buf, "%ld:%02ld", t / 60, t % 60);
  return buf;
}

std::string sci(double x, int prec = 3) {
  std::ostringstream s;
  s << std::setprecision(prec) << x;
  return s.str();
}

struct Schedule {
  double dt = 0;
  std::uint64_t total_steps = 0;
  std::uint64_t output_every = 1;    ///< steps between series rows
  std::uint64_t snapshot_every = 0;  ///< 0 = no snapshots
};

Schedule schedule(const scene::Scene& s, double dt) {
  Schedule sc;
  sc.dt = dt;
  sc.total_steps = std::max<std::uint64_t>(1, static_cast<std::uint64_t>(std::ceil(s.time.duration / dt - 1e-9)));
  sc.output_every = std::max<std::uint64_t>(1, static_cast<std::uint64_t>(std::llround(s.time.output_interval / dt)));
  if (s.time.snapshot_interval > 0)
    sc.snapshot_every =
        std::max<std::uint64_t>(1, static_cast<std::uint64_t>(std::llround(s.time.snapshot_interval / dt)));
  return sc;
}

/// Rough resident memory of the engine for n particles and b bonds.
double memory_estimate_bytes(std::size_t n, std::size_t bonds, std::size_t walls) {
  const double per_particle = 5 * sizeof(Vec3) + sizeof(Quat) + 5 * sizeof(double) + sizeof(GlobalId) +
                              sizeof(bonded::MaterialIndex) + 2 + sizeof(Vec3) /*x at build*/ +
                              3 * sizeof(std::uint32_t) /*cells*/ + walls * sizeof(Vec3) /*wall history*/ +
                              32 /*gid index*/ + 4 * sizeof(bonded::ContactPair) /*contacts, assumed*/;
  return n * per_particle + bonds * (sizeof(bonded::Bond) + 8 /*partner lists*/);
}

void print_warnings(const scene::Scene& s, std::FILE* err) {
  for (const auto& w : s.warnings) std::fprintf(err, "warning: %s\n", w.c_str());
}

}  // namespace

int check_scene(const RunOptions& opt, std::ostream& out, std::ostream& err) {
  const scene::Scene s = scene::load_scene_file(opt.scene_path, opt.overrides);
  for (const auto& w : s.warnings) err << "warning: " << w << "\n";
  scene::Built b = scene::build_engine(s, false);
  const bonded::Engine& e = *b.engine;
  const double dt = e.dt(), crit = e.critical_time_step();
  const Schedule sc = schedule(s, dt);
  const double psteps = static_cast<double>(b.particles) * sc.total_steps;
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
  out << "walls:            " << s.walls.size() << "\n";
  out << "time step:        dt = " << sci(dt, 4) << " s" << (s.time.dt == 0 ? " (paper Eq. 2)" : "")
      << ", critical dt = " << sci(crit, 4) << " s (margin x" << sci(crit / dt, 3) << ")\n";
  out << "steps:            " << sc.total_steps << " for " << s.time.duration << " s; " << rows
      << " series rows, " << snaps << " snapshots\n";
  out << "estimated memory: " << sci(memory_estimate_bytes(b.particles, b.bonds, s.walls.size()) / 1048576.0, 3)
      << " MiB; output file ~" << sci(file_bytes / 1048576.0, 3) << " MiB\n";
  out << "estimated time:   " << duration_text(psteps / kParticleStepsPerSecond) << " (" << sci(psteps, 3)
      << " particle-steps at ~" << sci(kParticleStepsPerSecond, 2) << "/s, one core)\n";
  out << "output:           " << (opt.output.empty() ? s.output : opt.output) << "\n";
  e.check_time_step();  // InputError at /time/dt, after the figures that explain it
  out << "ok\n";
  return 0;
}

int run_scene(const RunOptions& opt, std::ostream& out, std::FILE* progress) {
  const scene::Scene s = scene::load_scene_file(opt.scene_path, opt.overrides);
  print_warnings(s, progress);
  const auto t_setup = Clock::now();
  scene::Built b = scene::build_engine(s, true);
  bonded::Engine& e = *b.engine;
  const Schedule sc = schedule(s, e.dt());
  const std::size_t nwalls = s.walls.size();

  io::RunFileMeta meta;
  meta.scene_text = s.json.dump(2);
  meta.program_version = HYBRIDSIM_VERSION;
  const std::string out_path = opt.output.empty() ? s.output : opt.output;
  io::RunFile file(out_path, meta);

  const int id_time = file.add_series("/series/time", 1, "s", "simulated time");
  const int id_step = file.add_int_series("/series/step", 1, "1", "step number");
  const int id_force = file.add_series("/series/force", 3, "N",
                                       "total force on all walls, mean over the output interval ending at time");
  std::vector<int> id_part(nwalls);
  for (std::size_t k = 0; k < nwalls; ++k)
    id_part[k] = file.add_series("/series/parts/" + s.walls[k].name + "/force", 3, "N",
                                 "force on wall '" + s.walls[k].name + "', mean over the output interval");
  struct EnergySeries {
    const char* name;
    const char* description;
    int id;
  };
  EnergySeries en[] = {
      {"kinetic", "kinetic energy, translational + rotational", 0},
      {"kinetic_translational", "translational kinetic energy", 0},
      {"kinetic_rotational", "rotational kinetic energy", 0},
      {"gravity_potential", "gravitational potential energy (reference z = 0)", 0},
      {"buoyancy_potential", "buoyancy potential energy", 0},
      {"bond_elastic", "elastic energy in intact bonds", 0},
      {"contact_elastic", "elastic energy in contacts", 0},
      {"total", "sum of the above", 0},
  };
  for (auto& x : en) x.id = file.add_series(std::string("/series/energy/") + x.name, 1, "J", x.description);
  const int id_broken = file.add_int_series("/series/bonds_broken", 1, "1", "bonds broken since the start");
  const int id_bonds = file.add_int_series("/series/bonds", 1, "1", "intact bonds");
  const int id_particles = file.add_int_series("/series/particles", 1, "1", "particles");

  std::vector<Vec3> force_sum(nwalls, Vec3::Zero());
  std::uint64_t force_count = 0;
  std::vector<double> peak(nwalls, 0.0), peak_time(nwalls, 0.0);

  auto write_row = [&]() {
    const double t = e.time();
    const std::int64_t st = static_cast<std::int64_t>(e.step_count());
    file.append(id_time, &t);
    file.append(id_step, &st);
    Vec3 total = Vec3::Zero();
    for (std::size_t k = 0; k < nwalls; ++k) {
      const Vec3 f = force_count ? Vec3(force_sum[k] / static_cast<double>(force_count))
                                 : e.wall_force(static_cast<int>(k));
      total += f;
      file.append(id_part[k], f.data());
      force_sum[k].setZero();
    }
    force_count = 0;
    file.append(id_force, total.data());
    const auto E = e.energy();
    const double v[] = {E.kinetic_translational + E.kinetic_rotational,
                        E.kinetic_translational,
                        E.kinetic_rotational,
                        E.gravity_potential,
                        E.buoyancy_potential,
                        E.bond_elastic,
                        E.contact_elastic,
                        E.total()};
    for (std::size_t k = 0; k < std::size(en); ++k) file.append(en[k].id, &v[k]);
    const std::int64_t broken = static_cast<std::int64_t>(e.stats().bonds_broken);
    const std::int64_t nb = static_cast<std::int64_t>(e.bonds().size());
    const std::int64_t np = static_cast<std::int64_t>(e.particles().owned());
    file.append(id_broken, &broken);
    file.append(id_bonds, &nb);
    file.append(id_particles, &np);
  };

  std::vector<std::int32_t> ibuf;
  std::vector<std::int64_t> lbuf;
  auto write_snapshot = [&]() {
    const auto& p = e.particles();
    const std::size_t n = p.owned();
    file.begin_snapshot(e.time(), e.step_count());
    file.write_field("position", p.x.data()->data(), n, 3, "m");
    file.write_field("velocity", p.v.data()->data(), n, 3, "m/s");
    file.write_field("radius", p.radius.data(), n, 1, "m");
    ibuf.assign(p.bond_count.begin(), p.bond_count.begin() + n);
    file.write_field("bond_count", ibuf.data(), n, 1, "1");
    lbuf.assign(p.gid.begin(), p.gid.begin() + n);
    file.write_field("global_id", lbuf.data(), n, 1, "1");
    file.end_snapshot();
  };

  const bool tty = isatty(fileno(progress)) != 0;
  const double setup_s = std::chrono::duration<double>(Clock::now() - t_setup).count();
  std::fprintf(progress,
               "hybridsim: %s: %zu particles, %zu bonds, %zu walls; dt = %.4g s, %llu steps to t = %g s "
               "(setup %.1f s)\n",
               s.name.c_str(), b.particles, b.bonds, nwalls, e.dt(), static_cast<unsigned long long>(sc.total_steps),
               s.time.duration, setup_s);
  std::fflush(progress);

  const auto t0 = Clock::now();
  auto last_report = t0;
  std::uint64_t last_report_step = 0;
  double rate = 0.0;  // steps/s, smoothed
  bool progress_line_open = false;

  try {
    // Row 0 is the initial state (forces are zero until the first step; Engine::compute_forces
    // cannot be called before the first neighbour build).
    write_row();
    if (sc.snapshot_every) write_snapshot();
    file.flush();
    for (std::uint64_t k = 1; k <= sc.total_steps; ++k) {
      e.step();
      for (std::size_t w = 0; w < nwalls; ++w) {
        const Vec3& f = e.wall_force(static_cast<int>(w));
        force_sum[w] += f;
        const double m = f.norm();
        if (m > peak[w]) {
          peak[w] = m;
          peak_time[w] = e.time();
        }
      }
      ++force_count;
      if (k % sc.output_every == 0 || k == sc.total_steps) write_row();
      if (sc.snapshot_every && (k % sc.snapshot_every == 0 || k == sc.total_steps)) write_snapshot();
      if ((k & 63) == 0 || k == sc.total_steps) {
        const auto now = Clock::now();
        const double since = std::chrono::duration<double>(now - last_report).count();
        const double interval = tty ? 0.5 : 10.0;
        if (since >= interval || (k == sc.total_steps && tty)) {
          const double inst = (k - last_report_step) / std::max(since, 1e-9);
          rate = rate == 0.0 ? inst : 0.5 * rate + 0.5 * inst;
          const double left = (sc.total_steps - k) / std::max(rate, 1e-9);
          const double elapsed = std::chrono::duration<double>(now - t0).count();
          if (tty) {
            std::fprintf(progress, "\r  t = %.4g / %g s  step %llu/%llu  %.0f steps/s  %s left  bonds broken %llu   ",
                         e.time(), s.time.duration, static_cast<unsigned long long>(k),
                         static_cast<unsigned long long>(sc.total_steps), rate, duration_text(left).c_str(),
                         static_cast<unsigned long long>(e.stats().bonds_broken));
            progress_line_open = true;
          } else {
            std::fprintf(progress,
                         "[%s] t = %.4g / %g s, step %llu/%llu, %.0f steps/s, %s left, bonds broken %llu\n",
                         duration_text(elapsed).c_str(), e.time(), s.time.duration,
                         static_cast<unsigned long long>(k), static_cast<unsigned long long>(sc.total_steps), rate,
                         duration_text(left).c_str(), static_cast<unsigned long long>(e.stats().bonds_broken));
          }
          std::fflush(progress);
          last_report = now;
          last_report_step = k;
        }
      }
    }
  } catch (const SimulationError&) {
    if (progress_line_open) std::fprintf(progress, "\n");
    file.close();  // keep what was written so far
    std::fprintf(progress, "hybridsim: output up to t = %g s kept in %s\n", e.time(), out_path.c_str());
    throw;
  }
  if (progress_line_open) std::fprintf(progress, "\n");
  const std::size_t rows = file.series_rows(id_time), snaps = file.snapshot_count();
  file.close();

  const double wall = std::chrono::duration<double>(Clock::now() - t0).count();
  const auto& st = e.stats();
  out << "hybridsim: " << s.name << " finished: " << e.step_count() << " steps to t = " << sci(e.time(), 6)
      << " s in " << sci(wall, 4) << " s wall (" << sci(e.step_count() / std::max(wall, 1e-9), 4) << " steps/s, "
      << sci(static_cast<double>(b.particles) * e.step_count() / std::max(wall, 1e-9), 3)
      << " particle-steps/s)\n";
  out << "  particles " << b.particles << ", bonds " << b.bonds << ", broken " << st.bonds_broken << " ("
      << st.bonds_broken_tension << " tension, " << st.bonds_broken_shear << " shear)\n";
  for (std::size_t w = 0; w < nwalls; ++w)
    out << "  peak force on wall '" << s.walls[w].name << "': " << sci(peak[w], 4) << " N at t = "
        << sci(peak_time[w], 4) << " s\n";
  out << "  output: " << out_path << " (" << rows << " series rows, " << snaps << " snapshots)\n";
  return 0;
}

}  // namespace hs::app
