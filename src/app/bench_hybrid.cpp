// `hybridsim bench hybrid`: the rigid world at the paper's scale (docs/rigid.md, "Far sleep" and
// "The bench's ridge at rest").
//
// The scene: the paper-size ridge (scenes/ridge_paper_size.json: ~28,000 keel and ~1,500 sail blocks,
// ~78,000 freeze joints, 200 m along y) with the parametric pier half-way along it (y = 100 m), its
// axis 3 m outside the keel's -x toe (x = -70.1 m on the paper-size ridge; --pier-x moves it; x = -34 m
// is 33 m into the keel), moving into the ridge at 0.4 m/s; a bonded
// particle sheet (the keel cone scene's: 0.6 m level ice, with the 0.9 m consolidated layer where it
// reaches the band, D = 0.25 m, calibrated E = 1e7 Pa) 26.5 m long from the pier's waterline on,
// y = 100 +- 8 m; everywhere else the ridge's own ice cover (the fixed boxes it was generated under)
// as fixed rigid boxes; the conversion region a 13 m cylinder about the pier; hybrid mode. Every
// block of the file is present (those the pier would reach into aside). Ice, blocks and water have
// the density and friction the ridge was generated with (the file's). The blocks lie where the
// ridge settled again in this world (ridge_at_rest below: under the floating sheet and around the
// pier), unless --as-generated. Far sleep as at scale: every block starts asleep, the particles'
// steady loads are held, no wake box over the conversion region, the pier's zone keeps only its own
// blocks awake, no wake hops (the solve carries an impact across sleeping blocks).
// With --idle the sheet and the pier lie 300 m further along -x (the pier parked): nothing touches a
// block, far sleep keeps every block asleep, and the rigid world's time is what holding the ridge
// costs by itself (the work over every block, pair, manifold and joint per rigid step).
// Timed: `steps` DEM steps after set-up and a warm-up up to the second rigid step (reported apart);
// reported: the rigid world's ms per rigid step, the DEM's ms per step, the bridge's, the rigid
// world's share of the wall time of a hybrid step, and the awake blocks and those of them moving
// faster than the far-sleep speed.
//
// The ridge takes ~15 min of one core to generate; the bench looks for it in the cache directory
// ($HYBRIDSIM_CACHE_DIR, else $XDG_CACHE_HOME/hybridsim, else ~/.cache/hybridsim) as
// ridge_paper_size_ridge.h5 and says how to make it when it is missing; --ridge FILE takes another
// ridge file (e.g. scenes/ridge_keel_8m.json's for a quick run: the sheet is then placed at its
// middle along y). The ridge settled in the bench's world is made once (~30 s) and kept in the
// same cache directory.
#include "app/bench.h"

#include "common/error.h"
#include "io/ridge_file.h"
#include "mesh/tri_mesh.h"
#include "ridge/ridge.h"
#include "ridge/ridge_json.h"
#include "scene/scene.h"
#include "sim/blocks.h"
#include "sim/build.h"
#include "sim/ridge_sheet.h"
#include "sim/simulation.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdio>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <exception>
#include <functional>
#include <limits>
#include <sstream>
#include <string>
#include <sys/resource.h>
#include <unistd.h>

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

/// The ridge's ice cover (the fixed boxes it was generated under) minus the hole [hx0, hx1] x
/// [hy0, hy1] where the bench floats its particle sheet.
std::vector<rigid::IceBox> cover_boxes(const rigid::RidgeResult& r, double hx0, double hx1, double hy0, double hy1) {
  std::vector<rigid::IceBox> out;
  auto add_box = [&](double xa, double xb, double ya, double yb, double zc, double hz, int part) {
    if (!(xb - xa > 1e-6) || !(yb - ya > 1e-6)) return;
    rigid::IceBox b;
    b.half_extents = Vec3(0.5 * (xb - xa), 0.5 * (yb - ya), hz);
    b.position = Vec3(0.5 * (xa + xb), 0.5 * (ya + yb), zc);
    b.part = part;
    out.push_back(b);
  };
  for (const auto& box : r.ice) {
    const double xa = box.position.x() - box.half_extents.x(), xb = box.position.x() + box.half_extents.x();
    const double ya = box.position.y() - box.half_extents.y(), yb = box.position.y() + box.half_extents.y();
    const double zc = box.position.z(), hz = box.half_extents.z();
    add_box(xa, xb, ya, std::min(yb, hy0), zc, hz, box.part);                               // below the hole in y
    add_box(xa, xb, std::max(ya, hy1), yb, zc, hz, box.part);                               // above it
    add_box(xa, std::min(xb, hx0), std::max(ya, hy0), std::min(yb, hy1), zc, hz, box.part);  // beside it in x
    add_box(std::max(xa, hx1), xb, std::max(ya, hy0), std::min(yb, hy1), zc, hz, box.part);
  }
  return out;
}

/// The pier's default place: its axis 3 m outside the keel's -x toe (the least x of a keel
/// block's centre), so that its cone, 10.1 m in radius at its base, reaches under the toe's first
/// blocks: the pier at the ridge, as a ridge interaction starts. (With --pier-x -34 it stands 33 m
/// into the paper-size keel: the 376 blocks it would reach into are left out, and the keel slumps
/// into their space for as long as it is settled, docs/rigid.md.)
double default_pier_x(const rigid::RidgeResult& r) {
  double toe = std::numeric_limits<double>::infinity();
  for (const auto& b : r.blocks)
    if (b.part == 0) toe = std::min(toe, b.position.x());
  return std::isfinite(toe) ? toe - 3.0 : -34.0;  // (no keel block: x = -34 m)
}

/// The bench scene (see the top of this file) for the ridge in `r` (file `path`).
nlohmann::json bench_scene(const rigid::RidgeResult& r, const std::string& path, bool far_sleep, bool idle,
                           double pier_x) {
  double ymin = 1e30, ymax = -1e30;
  for (const auto& b : r.blocks) {
    ymin = std::min(ymin, b.position.y());
    ymax = std::max(ymax, b.position.y());
  }
  const double yc = std::round(0.5 * (ymin + ymax));
  const double away = idle ? -300.0 : 0.0;        // --idle: sheet and pier far from the ridge
  // The particle sheet (the keel cone scene's size) from the pier's waterline on, 26.5 m long.
  const double x1 = pier_x + 34.0 + away, x0 = x1 - 26.5, w = 16.0;
  const double y0 = yc - 0.5 * w, y1 = yc + 0.5 * w;
  const double gap = 0.5;                          // between the sheet and the fixed ice cover
  // The ridge's own world: the blocks where the file has them (no offset), with the density,
  // friction and water they were settled with, so that the ridge is at rest as generated and far
  // sleep keeps its far part asleep (with the file's 910 / 0.5 run at 920 / 0.3, every block the
  // sheet's motion woke slid and woke its neighbours: 12,700 of 29,064 awake).
  const double rho = r.def.ice_density, mu = r.def.settle.friction, rho_w = r.def.water_density;
  nlohmann::json list = nlohmann::json::array();
  for (const rigid::IceBox& b : cover_boxes(r, x0 - gap, x1 + gap, y0 - gap, y1 + gap))
    list.push_back({{"half_extents", vec(b.half_extents)}, {"position", vec(b.position)}, {"fixed", true}});
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
  // The rule at scale (docs/rigid.md, "Far sleep"): every block starts asleep; the particles'
  // steady loads are held, not a reason to step a block; the conversion region is not kept awake
  // as a whole; the pier's wake zone keeps its own blocks awake, not their neighbours.
  if (far_sleep)
    blocks["far_sleep"] = {{"start_asleep", true},
                           {"loads_held", true},
                           {"region_awake", false},
                           {"zone_wakes_neighbours", false},
                           {"wake_hops", 0}};
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
       {{"name", "pier"}, {"type", "pier"}, {"position", {pier_x + away, yc, 0}}, {"velocity", {idle ? 0.0 : 0.4, 0, 0}}, {"friction", 0.1}}},
      {"blocks", blocks}};
}

/// The bench's ridge at rest (docs/rigid.md, "The bench's ridge at rest"): the
/// ridge was generated under fixed boxes, but the bench floats a particle sheet in a
/// hole of that cover and stands the pier at (or in) the keel, the blocks it would reach into left
/// out. Under the sheet the keel's buoyancy, which the boxes held, lifts the sheet and the keel with
/// it, and around the pier the blocks slide into the space of those left out: a ridge in motion,
/// which wakes far sleep's blocks for reasons of its own. So the ridge is settled once more in the
/// bench's world, rigid only: the cover as fixed boxes, in the hole joined heave-only plates with
/// the sheet's contact surfaces (as `hybridsim ridge` settles a run scene's keel, docs/ridge.md
/// "Floating plates"), the pier held, the blocks within 8 m of the hole and of the pier free, every
/// other block held where it is; 30 s at the generator's settle step and 3 s at 1/240 s, both
/// damped as the generator's settle phase. The run then lifts its sheet by the plates' lift. Made
/// once and kept in the cache directory as <stem>.bench_rest_<key>.h5, the key a hash of the ridge
/// file (absolute path, size, modification time), the bench's world and the settle's parameters.
struct RestedRidge {
  std::string path;
  bool made = false;  ///< made by this call (else: found in the cache)
  rigid::RidgeResettleStats stats;
};

RestedRidge ridge_at_rest(const par::Comm& comm, const std::string& path, const rigid::RidgeResult& r,
                          const scene::Scene& s) {
  namespace fs = std::filesystem;
  RestedRidge out;
  const std::string dir = bench_cache_dir();
  const double margin = 8.0, gap = 0.5;  // (gap: as bench_scene)
  const std::vector<rigid::RidgeResettleDef::Phase> phases = {{1.0 / 30.0, 30.0, 20, 5.0}, {1.0 / 240.0, 3.0, 20, 5.0}};
  {
    std::error_code ec;
    std::ostringstream key;
    key.precision(17);
    key << "bench_rest v2|" << fs::absolute(path).string() << "|" << fs::file_size(path, ec) << "|"
        << fs::last_write_time(path, ec).time_since_epoch().count() << "|" << s.structure.position.transpose() << "|"
        << s.ice.origin[0] << " " << s.ice.origin[1] << " " << s.ice.length << " " << s.ice.width << " "
        << s.material.particle_diameter << "|" << margin << " " << gap;
    for (const auto& ph : phases) key << "|" << ph.dt << " " << ph.time << " " << ph.solver_iterations << " " << ph.damping;
    char tag[48];
    std::snprintf(tag, sizeof tag, ".bench_rest_%016zx.h5", std::hash<std::string>{}(key.str()));
    out.path = (dir.empty() ? std::string(".") : dir) + "/" + fs::path(path).stem().string() + tag;
    if (fs::exists(out.path, ec)) return out;
  }
  out.made = true;
  // Rank 0 settles and writes it; every rank learns whether that worked (an error on rank 0 alone
  // would leave the others waiting).
  std::exception_ptr failure;
  if (comm.rank() == 0) try {
    rigid::RidgeResettleDef rd;
    rd.phases = phases;
    const double x0 = s.ice.origin[0], x1 = x0 + s.ice.length, y0 = s.ice.origin[1], y1 = y0 + s.ice.width;
    rd.fixed_boxes = cover_boxes(r, x0 - gap, x1 + gap, y0 - gap, y1 + gap);
    // The hole's plates: the sheet's contact surfaces at rest (sim::sheet_geometry), level ice and
    // the consolidated layer's band (its spheres reach D/2 beyond the band).
    const sim::SheetGeometry g = sim::sheet_geometry(s);
    const double D = s.material.particle_diameter;
    const auto& cl = s.ice.consolidated_layer;
    const double b0 = std::max(x0, cl.center_x - 0.5 * cl.width - 0.5 * D), b1 = std::min(x1, cl.center_x + 0.5 * cl.width + 0.5 * D);
    auto plate = [&](double xa, double xb, double top, double under, int part) {
      if (!(xb - xa > 1e-6)) return;
      rigid::IceBox b;
      b.half_extents = Vec3(0.5 * (xb - xa) - 5e-4, 0.5 * (y1 - y0), 0.5 * (top - under));
      b.position = Vec3(0.5 * (xa + xb), 0.5 * (y0 + y1), 0.5 * (top + under));
      b.part = part;
      rd.plates.push_back(b);
    };
    plate(x0, std::min(b0, x1), g.level_top, g.level_underside, 0);
    plate(b0, b1, g.layer_top, g.layer_underside, 1);
    plate(std::max(b1, x0), x1, g.level_top, g.level_underside, 0);
    const mesh::TriMesh m = sim::structure_mesh(s);
    rd.obstacle_vertices = m.vertices;
    rd.obstacle_triangles = m.triangles;
    rd.obstacle_position = s.structure.position;
    rd.keep.assign(r.blocks.size(), 1);
    for (std::size_t k = 0; k < r.blocks.size(); ++k)
      rd.keep[k] = !sim::block_reaches_into_pier(s.structure, r.blocks[k].half_extents, r.blocks[k].position);
    const mesh::Aabb pb = mesh::bounding_box(m);
    rd.region_lo = Vec3(std::min(x0, s.structure.position.x() + pb.lo.x()) - margin,
                        std::min(y0, s.structure.position.y() + pb.lo.y()) - margin, -1e9);
    rd.region_hi = Vec3(std::max(x1, s.structure.position.x() + pb.hi.x()) + margin,
                        std::max(y1, s.structure.position.y() + pb.hi.y()) + margin, 1e9);
    std::fprintf(stderr, "bench hybrid: settling the ridge in the bench's world once (%s)...\n", out.path.c_str());
    double next = 0.0;
    const rigid::RidgeResult rested = rigid::resettle_ridge(r, rd, &out.stats, [&](const rigid::RidgeProgress& q) {
      if (q.time + 1e-9 < next) return;
      next = q.time + 1.0;
      std::fprintf(stderr, "  %5.2f / %.2f s, %zu blocks free, kinetic energy %.3g J per block\n", q.time, q.max_time,
                   q.blocks, q.kinetic_energy_per_block);
    });
    std::error_code ec;
    fs::create_directories(fs::path(out.path).parent_path(), ec);
    if (ec)
      throw InputError("/bench/ridge", "cannot make the cache directory '" + fs::path(out.path).parent_path().string() +
                                           "' for the bench's ridge at rest: " + ec.message() +
                                           " (set HYBRIDSIM_CACHE_DIR to a writable directory)");
    const std::string tmp = out.path + ".tmp" + std::to_string(::getpid());
    io::save_ridge(tmp, rested);
    fs::rename(tmp, out.path);
  } catch (...) {
    failure = std::current_exception();
  }
  double failed = failure ? 1.0 : 0.0;
  comm.max(&failed, 1);
  if (failure) std::rethrow_exception(failure);
  if (failed > 0.0) throw InputError("/bench/ridge", "rank 0 could not settle the ridge in the bench's world (see its error)");
  return out;
}

/// The bench's world before it is built: the ridge file, the pier's place and the scene (its
/// blocks from the ridge settled again in this world unless idle or --as-generated).
struct HybridBench {
  std::string path;         ///< the ridge file
  rigid::RidgeResult ridge;
  double pier_x = 0.0;
  RestedRidge rest;         ///< the ridge settled again in the bench's world; empty path: as generated
  scene::Scene s;
};

HybridBench hybrid_bench_scene(const par::Comm& comm, const BenchOptions& opt) {
  HybridBench b;
  b.path = ridge_path(opt);
  b.ridge = io::load_ridge(b.path);
  b.pier_x = std::isnan(opt.pier_x) ? default_pier_x(b.ridge) : opt.pier_x;
  nlohmann::json sj = bench_scene(b.ridge, b.path, !opt.no_far_sleep, opt.idle, b.pier_x);
  if (!opt.idle && !opt.as_generated) {  // (idle: nothing touches the ridge, which is left as generated)
    scene::Scene s0 = scene::parse_scene(sj);
    b.rest = ridge_at_rest(comm, b.path, b.ridge, s0);
    sj["blocks"]["ridge_file"] = std::filesystem::absolute(b.rest.path).string();
  }
  b.s = scene::parse_scene(sj);
  // The paper-size ridge is a standalone one (generated under fixed boxes, not this sheet): timed
  // here, not asked to be at rest, so the run's refusal of such a file is waived.
  b.s.blocks.check_ridge_generation = false;
  return b;
}

/// The blocks of the world that are not fixed; InputError when the pier left none.
std::size_t dynamic_blocks(const rigid::RigidWorld& world, const HybridBench& b) {
  std::size_t dynamic = 0;
  for (const rigid::BlockId id : world.blocks()) dynamic += !world.fixed(id);
  if (dynamic == 0)
    throw InputError("/bench/pier_x", "no block of '" + b.path + "' is left in the bench's world: the pier at x = " +
                                          std::to_string(b.pier_x) +
                                          " m reaches every block (a ridge smaller than the pier); place it with "
                                          "--pier-x, e.g. 30 m from the ridge's axis");
  return dynamic;
}

/// What the warm-up and the timed steps measured (wall times the slowest rank's).
struct HybridTiming {
  std::uint64_t warmup_steps = 0;
  double warmup_wall = 0.0, warmup_rigid_s = 0.0;
  bridge::HybridReport r0;  ///< the report when the timed steps began
  double awake_sum = 0.0, moving_sum = 0.0;
  std::size_t awake_max = 0, awake_samples = 0;
  std::size_t woken0 = 0, repeated0 = 0;  ///< far sleep's counts when the timed steps began
  rigid::RigidWorld::SolverStats solver0;  ///< the block solver's counts then
  double wall = 0.0;
  sim::RunCost cost0, cost1;  ///< this rank's cost breakdown when the timed steps began and ended
};

/// Warm-up, untimed: the steps up to the second rigid step. The world's first sub-step does the
/// set-up's remaining work once (the broadphase's first pass over every pair of 29,000 blocks,
/// every block put to sleep): 350 ms on the paper-size ridge, then 40 ms, then ~2 ms per rigid
/// step; timed with the rest, it would dominate a short run's rigid share (docs/results/bench_hybrid.md).
/// Reported as warmup_rigid_ms. Then `steps` timed steps, the awake and moving blocks sampled at
/// every rigid step.
HybridTiming time_hybrid(sim::Simulation& sim, const par::Comm& comm, std::uint64_t steps) {
  HybridTiming t;
  const bridge::HybridSystem& hy = sim.hybrid();
  const rigid::RigidWorld& world = *hy.world();
  const double warm_rigid0 = hy.report().seconds_rigid;
  const auto tw = Clock::now();
  while (hy.report().rigid_steps < 2 && t.warmup_steps < 1000) {
    sim.step();
    ++t.warmup_steps;
  }
  t.warmup_wall = comm.max(std::chrono::duration<double>(Clock::now() - tw).count());
  t.warmup_rigid_s = comm.max(hy.report().seconds_rigid - warm_rigid0);
  t.r0 = hy.report();
  std::uint64_t rigid_before = hy.report().rigid_steps;
  t.woken0 = world.sleepers_woken_by_solve();
  t.repeated0 = world.solves_repeated();
  t.solver0 = world.solver_stats();
  t.cost0 = sim.cost();
  const auto t1 = Clock::now();
  for (std::uint64_t k = 0; k < steps; ++k) {
    sim.step();
    if (hy.report().rigid_steps != rigid_before) {
      rigid_before = hy.report().rigid_steps;
      const std::size_t a = world.awake_count();
      t.awake_sum += static_cast<double>(a);
      // awake blocks faster than the far-sleep speed: what keeps the rest of the ridge awake
      t.moving_sum += static_cast<double>(world.moving_count());
      t.awake_max = std::max(t.awake_max, a);
      ++t.awake_samples;
    }
  }
  t.cost1 = sim.cost();
  t.wall = comm.max(std::chrono::duration<double>(Clock::now() - t1).count());
  return t;
}

/// The run's cost breakdown (sim/cost.h) of the timed steps, with the set-up's phases (build,
/// relaxation) as they were when the timing began: "cost_s" in the line, the summary's table on
/// stderr (rank 0). Collective.
void add_cost_json(nlohmann::json& j, const HybridTiming& t, const par::Comm& comm) {
  sim::RunCost d = t.cost1;
  for (std::size_t k = 0; k < sim::kPhaseCount; ++k)
    d.seconds[k] = k < sim::kFirstStepPhase ? t.cost0.seconds[k] : t.cost1.seconds[k] - t.cost0.seconds[k];
  d.wall = t.cost1.wall - t.cost0.wall + t.cost0.setup();
  d.steps = t.cost1.steps - t.cost0.steps;
  d.rigid_steps = t.cost1.rigid_steps - t.cost0.rigid_steps;
  d.particle_steps = t.cost1.particle_steps - t.cost0.particle_steps;
  const sim::RunCost r = sim::reduce_cost(d, comm);
  nlohmann::json c;
  for (std::size_t k = 0; k < sim::kPhaseCount; ++k) c[sim::phase_info()[k].name] = r.seconds[k];
  j["cost_s"] = c;
  if (comm.rank() == 0)
    std::fprintf(stderr, "bench hybrid: the timed steps, with the set-up before them:\n%s", sim::cost_table(r).c_str());
}

/// The ridge's part of the bench's line: the file, its settling again in the bench's world, and
/// whether the generator left it at rest (with a warning when it did not).
void add_ridge_json(nlohmann::json& j, const HybridBench& b, const par::Comm& comm) {
  const rigid::RidgeResult& ridge = b.ridge;
  const RestedRidge& rest = b.rest;
  j["ridge_file"] = b.path;
  // The ridge settled again in the bench's world (ridge_at_rest); empty: the file as generated.
  j["ridge_at_rest_file"] = rest.path;
  if (rest.made) {
    j["ridge_at_rest_made_s"] = rest.stats.wall_time;
    j["ridge_at_rest_free_blocks"] = rest.stats.moving_blocks;
    j["ridge_at_rest_plate_lift_m"] = rest.stats.plate_lift;
    j["ridge_at_rest_max_displacement_m"] = rest.stats.max_displacement;
    j["ridge_at_rest_last_second_max_displacement_m"] = rest.stats.last_second_max_displacement;
    j["ridge_at_rest_kinetic_energy_per_block_J"] = rest.stats.final_kinetic_energy_per_block;
  }
  j["blocks_in_file"] = ridge.blocks.size();
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
                 "criterion %.3g J): its blocks still creep where they wake%s, so the awake and moving counts "
                 "and the rigid share measure that as well as far sleep. A longer ridge.settle.max_time "
                 "need not help (the paper-size ridge's settle energy wanders between 0.009 and 0.08 J per "
                 "block at the settle step of 1/30 s); a smaller ridge.settle.dt leaves it closer to rest, "
                 "at more cost (docs/rigid.md, \"Far sleep\")\n",
                 b.path.c_str(), ridge.def.settle.max_time, ridge.stats.final_asleep_blocks, ridge.blocks.size(),
                 ridge.stats.final_kinetic_energy_per_block, ridge.def.settle.kinetic_energy_per_block,
                 rest.path.empty() ? ""
                                   : " (the bench settled those near its sheet and pier again, ridge_at_rest; the "
                                     "rest lie as generated)");
}

/// The timed figures of the bench's line: per step, per rigid step, shares and far sleep's counts.
void add_timing_json(nlohmann::json& j, const HybridTiming& t, const sim::Simulation& sim, std::uint64_t steps,
                     const par::Comm& comm) {
  const bridge::HybridReport& r = sim.hybrid().report();
  const bridge::HybridReport& r0 = t.r0;
  const rigid::RigidWorld& world = *sim.hybrid().world();
  const double wall = t.wall;
  const double rigid_s = comm.max(r.seconds_rigid - r0.seconds_rigid);
  const double dem_s = comm.max(r.seconds_bonded - r0.seconds_bonded);
  const double bridge_s = comm.max(r.seconds_bridge - r0.seconds_bridge);
  const auto rigid_steps = static_cast<double>(r.rigid_steps - r0.rigid_steps);
  j["steps"] = steps;
  j["warmup_steps"] = t.warmup_steps;
  j["warmup_rigid_ms"] = 1e3 * t.warmup_rigid_s;
  // the share with the warm-up counted as timed (its one-time set-up work included)
  j["rigid_share_with_warmup"] = (rigid_s + t.warmup_rigid_s) / (wall + t.warmup_wall);
  j["rigid_steps"] = rigid_steps;
  j["steps_per_rigid_step"] = r.steps_per_rigid_step;
  j["dt_s"] = sim.dt();
  j["rigid_dt_s"] = r.rigid_dt;
  j["wall_s"] = wall;
  j["rigid_ms_per_rigid_step"] = rigid_steps > 0 ? 1e3 * rigid_s / rigid_steps : 0.0;
  j["dem_ms_per_step"] = 1e3 * dem_s / static_cast<double>(steps);
  j["bridge_ms_per_step"] = 1e3 * bridge_s / static_cast<double>(steps);
  j["hybrid_ms_per_step"] = 1e3 * wall / static_cast<double>(steps);
  j["rigid_share"] = rigid_s / wall;
  j["dem_share"] = dem_s / wall;
  j["bridge_share"] = bridge_s / wall;
  j["awake_blocks_mean"] = t.awake_samples ? t.awake_sum / static_cast<double>(t.awake_samples) : 0.0;
  j["awake_blocks_max"] = t.awake_max;
  j["moving_blocks_mean"] = t.awake_samples ? t.moving_sum / static_cast<double>(t.awake_samples) : 0.0;
  j["conversions"] = r.conversions - r0.conversions;
  // Far sleep: sleeping blocks a change of their load woke, and the sub-step solves done again for them.
  j["sleepers_woken_by_solve"] = world.sleepers_woken_by_solve() - t.woken0;
  j["solves_repeated"] = world.solves_repeated() - t.repeated0;
  // The block solver over the timed steps: velocity iterations per solve (blocks.solver_tolerance).
  const rigid::RigidWorld::SolverStats ss = world.solver_stats();
  const std::uint64_t solves = ss.solves - t.solver0.solves;
  j["solver_iterations_per_solve"] = solves ? static_cast<double>(ss.iterations - t.solver0.iterations) / solves : 0.0;
}

}  // namespace

nlohmann::json hybrid_benchmark(const par::Comm& comm, const BenchOptions& opt) {
  const auto t0 = Clock::now();
  const HybridBench b = hybrid_bench_scene(comm, opt);
  const scene::Scene& s = b.s;
  sim::Simulation sim = sim::build_simulation(s, comm);
  const double setup = std::chrono::duration<double>(Clock::now() - t0).count();
  const rigid::RigidWorld& world = *sim.hybrid().world();
  const std::size_t dynamic = dynamic_blocks(world, b);
  const std::uint64_t steps = opt.steps > 0 ? opt.steps : 200;
  const HybridTiming t = time_hybrid(sim, comm, steps);
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  nlohmann::json j;
  j["name"] = "hybrid";
  add_ridge_json(j, b, comm);
  j["blocks"] = dynamic;
  j["fixed_blocks"] = world.block_count() - dynamic;
  j["joints"] = world.joint_count();
  j["particles"] = sim.engine().global_particle_count();
  j["far_sleep"] = !opt.no_far_sleep;
  j["idle"] = opt.idle;
  j["pier_x_m"] = b.pier_x;
  // the world's ice and water: the ridge file's own (its generation's), so that it is at rest
  j["ice_density"] = s.material.density;
  j["friction"] = s.material.friction;
  j["water_density"] = s.water.density;
  add_timing_json(j, t, sim, steps, comm);
  add_cost_json(j, t, comm);
  j["setup_s"] = setup;
  j["peak_rss_mb"] = comm.max(u.ru_maxrss / 1024.0);
  j["ranks"] = comm.size();
  // For tools/run_benchmarks.sh's CSV (`tools/run_benchmarks.sh hybrid`, with the ridge cached).
  j["particle_steps_per_s"] =
      static_cast<double>(sim.engine().global_particle_count()) * static_cast<double>(steps) / t.wall;
  j["cpu"] = cpu_model();
  j["version"] = HYBRIDSIM_VERSION;
  return j;
}

}  // namespace hs::app
