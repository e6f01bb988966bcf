// `hybridsim bench hybrid`: the rigid world at the paper's scale (docs/rigid.md, "Far sleep").
//
// The scene: the paper-size ridge (scenes/ridge_paper_size.json: ~28,000 keel and ~1,500 sail blocks,
// ~81,000 freeze joints, 200 m along y) with the parametric pier at the keel's -x edge half-way along
// it (y = 100 m), moving into the ridge at 0.4 m/s; a bonded particle sheet (the keel cone scene's:
// 0.6 m level ice and the 0.9 m consolidated layer, D = 0.25 m, calibrated E = 1e7 Pa) over
// x = [-26.5, 0] m, y = 100 +- 8 m; everywhere else the ridge's own ice cover (the fixed boxes it was
// generated under) as fixed rigid boxes; the conversion region a 13 m cylinder about the pier;
// hybrid mode. Every block of the file is present (those inside the pier aside). Ice, blocks and
// water have the density and friction the ridge was generated with (the file's), the blocks lie
// where the file has them: the ridge is as much at rest as its generation left it.
// With --idle the sheet and the pier lie 300 m further along -x (the pier parked): nothing touches a
// block, far sleep keeps every block asleep, and the rigid world's time is what holding the ridge
// costs by itself (the work over every block, pair, manifold and joint per rigid step).
// Timed: `steps` DEM steps after set-up; reported: the rigid world's ms per rigid step, the DEM's ms
// per step, the bridge's, the rigid world's share of the wall time of a hybrid step, and the awake
// blocks and those of them moving faster than the far-sleep speed (what keeps the rest awake).
//
// The ridge takes ~15 min of one core to generate; the bench looks for it in the cache directory
// ($HYBRIDSIM_CACHE_DIR, else $XDG_CACHE_HOME/hybridsim, else ~/.cache/hybridsim) as
// ridge_paper_size_ridge.h5 and says how to make it when it is missing; --ridge FILE takes another
// ridge file (e.g. scenes/ridge_keel_8m.json's for a quick run: the sheet is then placed at its
// middle along y).
#include "app/bench.h"

#include "common/error.h"
#include "io/ridge_file.h"
#include "scene/scene.h"
#include "sim/simulation.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdio>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <sys/resource.h>

namespace hs::app {

namespace {

using Clock = std::chrono::steady_clock;

std::string bench_cache_dir() {
  if (const char* d = std::getenv("HYBRIDSIM_CACHE_DIR")) return std::string(d) == "off" ? std::string() : d;
  if (const char* d = std::getenv("XDG_CACHE_HOME"); d && *d) return std::string(d) + "/hybridsim";
  if (const char* h = std::getenv("HOME"); h && *h) return std::string(h) + "/.cache/hybridsim";
  return {};
}

/// The ridge file: --ridge, else the cached paper-size ridge; InputError with the recipe if absent.
std::string ridge_path(const BenchOptions& opt) {
  if (!opt.ridge.empty()) {
    if (!std::filesystem::exists(opt.ridge))
      throw InputError("/bench/ridge", "cannot find ridge file '" + opt.ridge + "'; make one with `hybridsim ridge`");
    return opt.ridge;
  }
  const std::string dir = bench_cache_dir();
  const std::string path = (dir.empty() ? std::string(".") : dir) + "/ridge_paper_size_ridge.h5";
  if (!std::filesystem::exists(path))
    throw InputError("/bench/ridge",
                     "bench hybrid needs the paper-size ridge (" + path +
                         " is missing). Make it once (~15 min of one core):\n  mkdir -p " +
                         (dir.empty() ? std::string(".") : dir) +
                         " && hybridsim ridge scenes/ridge_paper_size.json -o " + path +
                         "\n(the cache directory is $HYBRIDSIM_CACHE_DIR, else $XDG_CACHE_HOME/hybridsim, else "
                         "~/.cache/hybridsim), or give another ridge file with --ridge FILE");
  return path;
}

nlohmann::json vec(const Vec3& v) { return {v.x(), v.y(), v.z()}; }

/// The bench scene (see the top of this file) for the ridge in `r` (file `path`).
nlohmann::json bench_scene(const rigid::RidgeResult& r, const std::string& path, bool far_sleep, bool idle) {
  double ymin = 1e30, ymax = -1e30;
  for (const auto& b : r.blocks) {
    ymin = std::min(ymin, b.position.y());
    ymax = std::max(ymax, b.position.y());
  }
  const double yc = std::round(0.5 * (ymin + ymax));
  const double away = idle ? -300.0 : 0.0;        // --idle: sheet and pier far from the ridge
  const double x0 = -26.5 + away, x1 = 0.0 + away, w = 16.0;  // the particle sheet (the keel cone scene's)
  const double y0 = yc - 0.5 * w, y1 = yc + 0.5 * w;
  const double gap = 0.5;                          // between the sheet and the fixed ice cover
  // The ridge's own world: the blocks where the file has them (no offset), with the density,
  // friction and water they were settled with, so that the ridge is at rest as generated and far
  // sleep keeps its far part asleep (with the file's 910 / 0.5 run at 920 / 0.3, every block the
  // sheet's motion woke slid and woke its neighbours: 12,700 of 29,064 awake).
  const double rho = r.def.ice_density, mu = r.def.settle.friction, rho_w = r.def.water_density;
  nlohmann::json list = nlohmann::json::array();
  // The ridge's ice cover, fixed, minus the sheet's footprint (grown by the gap).
  auto add_box = [&](double xa, double xb, double ya, double yb, double zc, double hz) {
    if (!(xb - xa > 1e-6) || !(yb - ya > 1e-6)) return;
    list.push_back({{"half_extents", {0.5 * (xb - xa), 0.5 * (yb - ya), hz}},
                    {"position", vec(Vec3(0.5 * (xa + xb), 0.5 * (ya + yb), zc))},
                    {"fixed", true}});
  };
  const double hx0 = x0 - gap, hx1 = x1 + gap, hy0 = y0 - gap, hy1 = y1 + gap;
  for (const auto& box : r.ice) {
    const double xa = box.position.x() - box.half_extents.x(), xb = box.position.x() + box.half_extents.x();
    const double ya = box.position.y() - box.half_extents.y(), yb = box.position.y() + box.half_extents.y();
    const double zc = box.position.z(), hz = box.half_extents.z();
    add_box(xa, xb, ya, std::min(yb, hy0), zc, hz);                            // below the hole in y
    add_box(xa, xb, std::max(ya, hy1), yb, zc, hz);                            // above it
    add_box(xa, std::min(xb, hx0), std::max(ya, hy0), std::min(yb, hy1), zc, hz);  // beside it in x
    add_box(std::max(xa, hx1), xb, std::max(ya, hy0), std::min(yb, hy1), zc, hz);
  }
  nlohmann::json blocks = {{"ridge_file", std::filesystem::absolute(path).string()},
                           {"keep_sail", true},
                           {"density", rho},
                           {"friction", mu},
                           {"conversion", "hybrid"},
                           {"region", {{"shape", "cylinder"}, {"radius", 13.0}, {"z_min", -12}, {"z_max", 4}}},
                           {"safety_factor", 1.0},
                           // The step's cost is timed, not the ridge's rest: no relaxation before
                           // the freeze (on by default with a ridge file; up to 30 s simulated).
                           {"relax", false},
                           {"list", list}};
  if (far_sleep) blocks["far_sleep"] = {{"start_asleep", true}};
  return {
      {"name", "bench_hybrid"},
      {"time", {{"duration", 1.0}, {"output_interval", 0.02}}},
      {"material",
       {{"density", rho}, {"youngs_modulus", 1e7}, {"poisson_ratio", 0.3}, {"particle_diameter", 0.25},
        {"restitution", 0.3}, {"friction", mu}, {"stiffness_model", "calibrated"},
        // the keel scenes' strength: at 5e4 Pa the sheet breaks under the keel's buoyancy
        {"flexural_strength", 5e5}}},
      {"bonds", {{"damping_ratio", 0.1}, {"freeze_strength_fraction", 0.1}}},
      {"water", {{"level", 0.0}, {"density", rho_w}, {"linear_drag_per_area", 1000}, {"drag_coefficient", 1.0}}},
      {"ice",
       {{"thickness", r.def.level_ice_thickness},
        {"length", x1 - x0},
        {"width", w},
        {"origin", {x0, y0}},
        {"consolidated_layer",
         {{"thickness", r.def.consolidated_layer_thickness},
          {"width", r.def.consolidated_layer_width},
          {"center_x", 0.0 + away}}}}},
      {"walls", {{{"name", "far_end"}, {"point", {x1, 0, 0}}, {"normal", {-1, 0, 0}}, {"friction", 0.1}}}},
      {"structure",
       {{"name", "pier"}, {"type", "pier"}, {"position", {-34.0 + away, yc, 0}}, {"velocity", {idle ? 0.0 : 0.4, 0, 0}}, {"friction", 0.1}}},
      {"blocks", blocks}};
}

}  // namespace

nlohmann::json hybrid_benchmark(const par::Comm& comm, const BenchOptions& opt) {
  const auto t0 = Clock::now();
  const std::string path = ridge_path(opt);
  const rigid::RidgeResult ridge = io::load_ridge(path);
  scene::Scene s = scene::parse_scene(bench_scene(ridge, path, !opt.no_far_sleep, opt.idle));
  // The paper-size ridge is a standalone one (generated under fixed boxes, not this sheet): timed
  // here, not asked to be at rest, so the run's refusal of such a file is waived.
  s.blocks.check_ridge_generation = false;
  sim::Simulation sim = sim::build_simulation(s, comm);
  const double setup = std::chrono::duration<double>(Clock::now() - t0).count();
  auto& hy = sim.hybrid();
  const rigid::RigidWorld& world = *hy.world();
  std::size_t dynamic = 0;
  for (const rigid::BlockId id : world.blocks()) dynamic += !world.fixed(id);
  const bridge::HybridReport r0 = hy.report();
  const std::uint64_t steps = opt.steps > 0 ? opt.steps : 200;
  double awake_sum = 0.0, moving_sum = 0.0;
  std::size_t awake_max = 0, awake_samples = 0;
  std::uint64_t rigid_before = hy.report().rigid_steps;
  const std::size_t woken0 = world.sleepers_woken_by_solve(), repeated0 = world.solves_repeated();
  const auto t1 = Clock::now();
  for (std::uint64_t k = 0; k < steps; ++k) {
    sim.step();
    if (hy.report().rigid_steps != rigid_before) {
      rigid_before = hy.report().rigid_steps;
      const std::size_t a = world.awake_count();
      awake_sum += static_cast<double>(a);
      // awake blocks faster than the far-sleep speed: what keeps the rest of the ridge awake
      moving_sum += static_cast<double>(world.moving_count());
      awake_max = std::max(awake_max, a);
      ++awake_samples;
    }
  }
  const double wall = comm.max(std::chrono::duration<double>(Clock::now() - t1).count());
  const bridge::HybridReport& r = hy.report();
  const double rigid_s = comm.max(r.seconds_rigid - r0.seconds_rigid);
  const double dem_s = comm.max(r.seconds_bonded - r0.seconds_bonded);
  const double bridge_s = comm.max(r.seconds_bridge - r0.seconds_bridge);
  const auto rigid_steps = static_cast<double>(r.rigid_steps - r0.rigid_steps);
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  nlohmann::json j;
  j["name"] = "hybrid";
  j["ridge_file"] = path;
  j["blocks"] = dynamic;
  j["fixed_blocks"] = world.block_count() - dynamic;
  j["blocks_in_file"] = ridge.blocks.size();
  j["joints"] = world.joint_count();
  j["particles"] = sim.engine().global_particle_count();
  j["far_sleep"] = !opt.no_far_sleep;
  j["idle"] = opt.idle;
  // the world's ice and water: the ridge file's own (its generation's), so that it is at rest
  j["ice_density"] = s.material.density;
  j["friction"] = s.material.friction;
  j["water_density"] = s.water.density;
  // Whether the generator left the ridge at rest: a ridge that was still creeping when its settle
  // time ran out (settled false) wakes by itself, and the awake and moving counts, the rigid share
  // with them, measure that, not far sleep (docs/rigid.md, "Far sleep").
  j["ridge_settled"] = ridge.stats.settled;
  j["ridge_final_kinetic_energy_per_block_J"] = ridge.stats.final_kinetic_energy_per_block;
  j["ridge_final_asleep_blocks"] = ridge.stats.final_asleep_blocks;
  j["ridge_max_final_overlap_m"] = ridge.stats.max_final_overlap;
  if (!ridge.stats.settled && comm.rank() == 0)
    std::fprintf(stderr,
                 "warning: bench hybrid: the ridge file '%s' was not settled when its generation stopped "
                 "(ridge.settle.max_time %.4g s reached: %zu of %zu blocks asleep, kinetic energy %.3g J per block, "
                 "criterion %.3g J): its blocks still creep and wake the ridge, so the awake and moving counts "
                 "and the rigid share measure that as well as far sleep. A longer ridge.settle.max_time "
                 "need not help (the paper-size ridge's settle energy wanders between 0.009 and 0.08 J per "
                 "block at the settle step of 1/30 s); a smaller ridge.settle.dt leaves it closer to rest, "
                 "at more cost (docs/rigid.md, \"Far sleep\")\n",
                 path.c_str(), ridge.def.settle.max_time, ridge.stats.final_asleep_blocks, ridge.blocks.size(),
                 ridge.stats.final_kinetic_energy_per_block, ridge.def.settle.kinetic_energy_per_block);
  j["steps"] = steps;
  j["rigid_steps"] = rigid_steps;
  j["steps_per_rigid_step"] = r.steps_per_rigid_step;
  j["dt_s"] = sim.engine().dt();
  j["rigid_dt_s"] = r.rigid_dt;
  j["wall_s"] = wall;
  j["rigid_ms_per_rigid_step"] = rigid_steps > 0 ? 1e3 * rigid_s / rigid_steps : 0.0;
  j["dem_ms_per_step"] = 1e3 * dem_s / static_cast<double>(steps);
  j["bridge_ms_per_step"] = 1e3 * bridge_s / static_cast<double>(steps);
  j["hybrid_ms_per_step"] = 1e3 * wall / static_cast<double>(steps);
  j["rigid_share"] = rigid_s / wall;
  j["dem_share"] = dem_s / wall;
  j["bridge_share"] = bridge_s / wall;
  j["awake_blocks_mean"] = awake_samples ? awake_sum / static_cast<double>(awake_samples) : 0.0;
  j["awake_blocks_max"] = awake_max;
  j["moving_blocks_mean"] = awake_samples ? moving_sum / static_cast<double>(awake_samples) : 0.0;
  j["conversions"] = r.conversions - r0.conversions;
  // Far sleep: sleeping blocks a change of their load woke, and the sub-step solves done again for them.
  j["sleepers_woken_by_solve"] = world.sleepers_woken_by_solve() - woken0;
  j["solves_repeated"] = world.solves_repeated() - repeated0;
  j["setup_s"] = setup;
  j["peak_rss_mb"] = comm.max(u.ru_maxrss / 1024.0);
  j["ranks"] = comm.size();
  // For tools/run_benchmarks.sh's CSV (`tools/run_benchmarks.sh hybrid`, with the ridge cached).
  j["particle_steps_per_s"] =
      static_cast<double>(sim.engine().global_particle_count()) * static_cast<double>(steps) / wall;
  {
    std::ifstream in("/proc/cpuinfo");
    std::string line, cpu = "unknown";
    while (std::getline(in, line))
      if (line.rfind("model name", 0) == 0) {
        cpu = line.substr(line.find(':') + 2);
        break;
      }
    j["cpu"] = cpu;
  }
  j["version"] = HYBRIDSIM_VERSION;
  return j;
}

}  // namespace hs::app
