// hybridsim command line.
//   hybridsim scene.json [-o out.h5] [--set path=value]... [--flush-interval S] [--fsync] [--restart run.h5]
//                                                             (same as `hybridsim run ...`)
//   hybridsim check scene.json [--set path=value]...          validate, print derived figures
//   hybridsim iso FILE.json                                   ISO 19906 estimate as JSON
//   hybridsim bench NAME                                      built-in benchmark (JSON line)
//   hybridsim ridge scene.json [-o ridge.h5]                  build a ridge of rigid blocks
//   hybridsim calibrate SCENE_OR_MATERIAL.json [--set ...]    virtual lab tests of the lattice
//   hybridsim metrics RUN.h5 [--json]                         the run metrics (docs/metrics.md)
//   hybridsim study STUDY.json [-j N] [--dry-run]             run a study's members, tables (docs/study.md)
//   hybridsim --version
//   mpirun -np N hybridsim scene.json ...                     the same run on N ranks (one output file)
// Exit codes: 0 ok, 1 internal error, 2 bad input (hs::InputError), 3 simulation unstable
// (hs::SimulationError; the output written so far and the last good state are kept),
// 130 / 143 stopped by SIGINT / SIGTERM (the step finished, the file written and closed).
// Under mpirun every rank runs the command; rank 0 alone prints (a rank with an error of its own
// prints it too). MPI is initialised only when an MPI launcher started the process.
#include "app/bench.h"
#include "app/calibrate_command.h"
#include "app/metrics_command.h"
#include "app/ridge_command.h"
#include "app/run.h"
#include "app/study_command.h"
#include "common/error.h"
#include "parallel/comm.h"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <iostream>
#include <string_view>

namespace {

int report_input_error(const hs::InputError& e) {
  // InputError::what() is "path: message"; print it as "error: <path>: <message>".
  std::fprintf(stderr, "error: %s\n", e.what());
  return 2;
}

/// The options every scene command shares (run with_output: -o, --flush-interval, --fsync, --restart).
void add_common(CLI::App* a, hs::app::RunOptions& opt, bool with_output) {
  a->add_option("scene", opt.scene_path, "scene file (JSON, see docs/scene.md)");
  if (with_output) {
    a->add_option("-o,--output", opt.output, "output HDF5 file (default: <name>.h5 of the scene)");
    a->add_option("--flush-interval", opt.flush_interval,
                  "wall-clock seconds between writes of the series to the file (default 60); what a killed "
                  "run keeps (docs/output.md)")
        ->check(CLI::PositiveNumber);
    a->add_flag("--fsync", opt.fsync, "fsync the output file after every flush (survives a machine crash)");
    a->add_option("--restart", opt.restart,
                  "continue the run in this run file (or its .ckpt.h5 checkpoint) from its last checkpoint; "
                  "the output (default: that run file) holds the whole series (docs/output.md, \"Checkpoints\")");
    CLI::Option* rel =
        a->add_option("--relaxation", opt.relaxation,
                      "the relaxation before the freeze from this file when it exists (refused when it holds another "
                      "scene's or build's), else relaxed and written there (docs/bridge.md, \"The relaxation cache\")");
    a->add_flag("--no-cache", opt.no_cache,
                "neither look up nor write the shared relaxation cache ($HYBRIDSIM_CACHE, else "
                "${XDG_CACHE_HOME:-$HOME/.cache}/hybridsim): the run relaxes")
        ->excludes(rel);
  }
  a->add_option("--set", opt.overrides,
                "override a scene field, e.g. --set ice.thickness=0.9 (value parsed as JSON, else a string); "
                "repeatable")
      ->allow_extra_args(false);
  a->add_flag("--ignore-memory-limit", opt.ignore_memory_limit,
              "build the scene even when its memory estimate exceeds the machine's available memory");
}

/// The subcommands as parsed, and the options of those that are not scene commands.
struct Commands {
  hs::app::RunOptions opt;
  CLI::App *run = nullptr, *check = nullptr, *iso = nullptr, *ridge = nullptr, *calibrate = nullptr,
           *bench = nullptr, *metrics = nullptr, *study = nullptr;
  std::string ridge_scene, ridge_out;
  std::string bench_name;
  hs::app::BenchOptions bench_opt;
  hs::app::MetricsCommandOptions metrics_opt;
  hs::app::StudyOptions study_opt;
};

void add_metrics(CLI::App& app, Commands& c) {
  c.metrics = app.add_subcommand("metrics", "print the run metrics of a run file (docs/metrics.md): stored in "
                                            "/analysis/metrics, or computed from the file when absent");
  hs::app::MetricsCommandOptions& m = c.metrics_opt;
  c.metrics->add_option("run", m.run_file, "run file (HDF5) written by hybridsim run")->required();
  c.metrics->add_flag("--json", m.json, "print JSON: {name: {value (null: no data), unit, description}}");
  c.metrics->add_option("--windows", m.windows_file,
                        "JSON file with an array of windows [{\"name\", \"t0\", \"t1\"} (s) or {\"name\", "
                        "\"x0\", \"x1\"} (m, the pier's waterline front)]: computed from the file with them")
      ->check(CLI::ExistingFile);
  c.metrics->add_option("--moving-window", m.moving_window,
                        "s, width of the moving mean of the peak load (default 1): computed from the file with it")
      ->check(CLI::PositiveNumber);
}

void add_ridge(CLI::App& app, Commands& c) {
  c.ridge = app.add_subcommand("ridge", "build a ridge (rigid blocks rise and settle under the ice), "
                                        "save it to HDF5 and print its report (docs/ridge.md)");
  c.ridge->add_option("scene", c.ridge_scene,
                      "ridge scene file (JSON with a \"ridge\" object), or a run scene with a \"ridge\" section: "
                      "then generated with the run's ice under its floating sheet (docs/ridge.md)")
      ->required();
  c.ridge->add_option("-o,--output", c.ridge_out,
                      "output HDF5 file (default: a run scene's blocks.ridge_file, else <name>_ridge.h5)");
  c.ridge->add_flag("--ignore-memory-limit", c.opt.ignore_memory_limit,
                    "generate even when the estimated block count exceeds the machine's available memory");
}

void add_calibrate(CLI::App& app, Commands& c) {
  c.calibrate = app.add_subcommand("calibrate", "virtual lab tests (tension, 3-point bending, floating "
                                                "strip) of the scene's lattice against its target ice: "
                                                "table and JSON (docs/engine.md, \"Calibrated ice\")");
  add_common(c.calibrate, c.opt, false);
  c.calibrate->add_option("--tests", c.opt.calibrate_tests,
                          "comma-separated subset of tension,bending,strip (default all)");
  c.calibrate->add_option("--max-strip-steps", c.opt.max_strip_steps,
                          "DEM steps of the floating-strip test above which its springs are softened and L_c scaled "
                          "back (default 6e4)")
      ->check(CLI::PositiveNumber);
  c.calibrate->add_flag("--scene-strength", c.opt.calibrate_scene_strength,
                        "run the bending test with the scene's bond strengths as they are, at its own sigma_f/E, "
                        "instead of scaled to sigma_f/E = 1.2e-4 (the linear regime the strength table holds for)");
}

void add_bench(CLI::App& app, Commands& c) {
  c.bench = app.add_subcommand("bench", "run a built-in benchmark and print one JSON line");
  c.bench->add_option("name", c.bench_name, "benchmark name")->required();
  hs::app::BenchOptions& b = c.bench_opt;
  c.bench->add_option("--lammps-data", b.lammps_data,
                      "granular: also write the settled pack as a LAMMPS data file (tools/bench/granular.lmp)");
  c.bench->add_option("--ridge", b.ridge,
                      "hybrid: ridge file (default: ridge_paper_size_ridge.h5 in $HYBRIDSIM_CACHE_DIR; see "
                      "docs/rigid.md)");
  c.bench->add_option("--steps", b.steps, "hybrid: DEM steps timed (default 200)");
  c.bench->add_flag("--no-far-sleep", b.no_far_sleep,
                    "hybrid: step every block at every rigid step (the far-sleep rule off), for comparison");
  c.bench->add_flag("--idle", b.idle,
                    "hybrid: pier and particle sheet 300 m from the ridge, every block asleep: the cost of holding "
                    "the ridge while nothing happens near it");
  c.bench->add_option("--pier-x", b.pier_x,
                      "hybrid: the pier's axis x, m (default: 3 m outside the keel's toe; -34 stands it 33 m "
                      "into the paper-size keel)");
  c.bench->add_flag("--as-generated", b.as_generated,
                    "hybrid: the ridge as generated, not settled again under the bench's sheet and pier first "
                    "(that ridge is in motion in the bench's world; docs/rigid.md)");
}

void add_study(CLI::App& app, Commands& c) {
  c.study = app.add_subcommand("study", "run a study: a base scene's variants x seeds as members, resumably; "
                                        "member table, summary with bootstrap 95 % intervals and the error-against-"
                                        "core-hours front (docs/study.md)");
  hs::app::StudyOptions& s = c.study_opt;
  c.study->add_option("study", s.study_file, "study file (JSON, see docs/study.md)")->required();
  c.study->add_option("-j,--jobs", s.jobs, "members run at once (default 1)")->check(CLI::PositiveNumber);
  c.study->add_flag("--dry-run", s.dry_run, "list the members and their estimated core-hours; run nothing");
  c.study->add_flag("--retry-failed", s.retry_failed, "run the members whose last run failed again");
  c.study->add_flag("--no-plot", s.no_plot, "write the tables only, not front.png");
}

/// Every subcommand and option, bound to `c`.
void add_commands(CLI::App& app, Commands& c) {
  app.set_version_flag("--version", std::string("hybridsim ") + HYBRIDSIM_VERSION);
  app.require_subcommand(0, 1);
  add_common(&app, c.opt, true);
  c.run = app.add_subcommand("run", "run a scene (the default command)");
  add_common(c.run, c.opt, true);
  c.check = app.add_subcommand("check", "validate a scene and print particle and bond counts, dt, "
                                        "memory and run-time estimates");
  add_common(c.check, c.opt, false);
  c.iso = app.add_subcommand("iso", "print the ISO 19906 cone load (JSON, N) for a scene (its ice and pier) "
                                    "or for a plain object of ISO inputs (docs/iso19906.md)");
  add_common(c.iso, c.opt, false);
  add_ridge(app, c);
  add_calibrate(app, c);
  add_bench(app, c);
  add_metrics(app, c);
  add_study(app, c);
}

/// Runs the parsed command (exceptions go to main).
int dispatch(CLI::App& app, const Commands& c, const hs::par::Comm& world, std::ostream& out, std::FILE* progress) {
  const bool root = world.rank() == 0;
  const hs::app::RunOptions& opt = c.opt;
  if (*c.bench) return hs::app::run_benchmark(c.bench_name, out, std::cerr, world, c.bench_opt);
  // Ridge building is serial (a replicated rigid world gains nothing from more ranks): rank 0.
  if (*c.study) {
    if (world.parallel()) {
      std::fprintf(stderr, "error: study: run `hybridsim study` without mpirun; \"mpi_ranks\" in the study file "
                           "runs each member under mpirun\n");
      return 2;
    }
    return hs::app::study_command(c.study_opt, out, progress);
  }
  if (*c.ridge) return root ? hs::app::ridge_command(c.ridge_scene, c.ridge_out, std::cout, opt.ignore_memory_limit) : 0;
  if (*c.metrics) return root ? hs::app::metrics_command(c.metrics_opt, out) : 0;
  if (opt.scene_path.empty()) {
    std::fprintf(stderr, "error: no scene file given\n%s", app.help().c_str());
    return 2;
  }
  if (*c.iso) return hs::app::iso_command(opt, out);
  if (*c.calibrate) return root ? hs::app::calibrate_command(opt, std::cout, stderr) : 0;
  if (*c.check) return hs::app::check_scene(opt, out, std::cerr);
  return hs::app::run_scene(opt, out, progress);
}

}  // namespace

int main(int argc, char** argv) {
  hs::par::Session session(&argc, &argv);
  const hs::par::Comm& world = session.world();
  const bool root = world.rank() == 0;
  // Ranks other than 0 stay quiet: their summaries and progress lines go nowhere.
  std::ostream null_out(nullptr);
  std::FILE* progress = root ? stderr : std::fopen("/dev/null", "w");
  std::ostream& out = root ? std::cout : null_out;

  CLI::App app{"hybridsim " HYBRIDSIM_VERSION
               " - bonded-particle DEM of sea ice against structures.\n"
               "Usage: hybridsim SCENE.json [-o OUT.h5] [--set path=value]...  (same as `hybridsim run`)",
               "hybridsim"};
  Commands c;
  c.opt.comm = &world;
  add_commands(app, c);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int rc = root ? app.exit(e) : (e.get_exit_code() == 0 ? 0 : 2);
    return rc == 0 ? 0 : 2;
  }

  try {
    return dispatch(app, c, world, out, progress);
  } catch (const hs::InputError& e) {
    // Every rank reads the same scene, so every rank fails the same way: one message.
    return root ? report_input_error(e) : 2;
  } catch (const hs::SimulationError& e) {
    // Instability is agreed by all ranks (collective check); the rank that saw it names it.
    const bool other = std::string_view(e.what()).find("on another rank") != std::string_view::npos;
    if (root || !other)
      std::fprintf(stderr, "error: simulation unstable%s: %s\n",
                   world.parallel() ? (" (rank " + std::to_string(world.rank()) + ")").c_str() : "", e.what());
    return 3;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error%s: %s\n",
                 world.parallel() ? (" (rank " + std::to_string(world.rank()) + ")").c_str() : "", e.what());
    // An internal error may have hit one rank only; the others would wait for it forever.
    if (world.parallel()) session.abort(1);
    return 1;
  }
}
