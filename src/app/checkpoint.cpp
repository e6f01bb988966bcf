#include "app/checkpoint.h"

#include "common/error.h"
#include "json/reader.h"
#include "io/run_file.h"
#include "parallel/comm.h"
#include "scene/scene.h"
#include "sim/recorder.h"
#include "sim/simulation.h"

#include <cstdio>
#include <filesystem>
#include <limits>
#include <regex>

namespace hs::app {

namespace {

namespace fs = std::filesystem;

/// The scene JSON a checkpoint is tied to. `legacy`: with /stability, as checkpoints written
/// before the limits could change on a restart were hashed (they still restart).
nlohmann::json identity_json(const nlohmann::json& j, bool legacy = false) {
  nlohmann::json c = j;
  if (c.is_object()) {
    c.erase("output");
    if (!legacy) c.erase("stability");  // checks, not physics: a restart may move a limit (docs/output.md)
    if (c.contains("time") && c["time"].is_object()) c["time"].erase("checkpoint_interval");
  }
  return c;
}

/// "/stability/<key>: <was> -> <now>" for each stability limit whose value the restart changes
/// (a limit the scene leaves out has its default; the values are compared as numbers).
std::vector<std::string> stability_changes(const nlohmann::json& saved, const nlohmann::json& now) {
  const scene::Scene defaults;
  const std::pair<const char*, double> limits[] = {{"max_speed", defaults.stability.max_speed},
                                                   {"max_overlap_ratio", defaults.stability.max_overlap_ratio}};
  const auto value = [](const nlohmann::json& j, const char* k, double def) {
    if (j.is_object() && j.contains("stability") && j["stability"].is_object() && j["stability"].contains(k) &&
        j["stability"][k].is_number())
      return j["stability"][k].get<double>();
    return def;
  };
  std::vector<std::string> out;
  for (const auto& [k, def] : limits) {
    const double a = value(saved, k, def), b = value(now, k, def);
    if (a == b) continue;
    char line[160];
    std::snprintf(line, sizeof line, "/stability/%s: %.10g -> %.10g", k, a, b);
    out.push_back(line);
  }
  return out;
}

}  // namespace

std::string scene_identity(const scene::Scene& s, std::string* canonical_text) {
  const std::string text = identity_json(s.json).dump();
  if (canonical_text) *canonical_text = text;
  return io::text_hash(text);
}

RestartFiles restart_files(const std::string& arg) {
  RestartFiles r;
  const fs::path p(arg);
  static const std::regex ckpt(R"((.*)\.ckpt)");
  std::smatch m;
  const std::string stem = p.stem().string();
  if (std::regex_match(stem, m, ckpt)) {  // the checkpoint file itself: its run file beside it
    r.checkpoint_file = arg;
    fs::path run = p;
    run.replace_filename(m[1].str() + p.extension().string());
    r.run_file = run.string();
  } else {
    r.run_file = arg;
    r.checkpoint_file = io::checkpoint_path(arg);
  }
  return r;
}

Restart read_restart(const std::string& arg, const scene::Scene& s, const par::Comm& comm) {
  Restart r;
  const RestartFiles files = restart_files(arg);
  r.run_file = files.run_file;
  r.checkpoint_file = files.checkpoint_file;
  if (!fs::exists(r.run_file) && r.run_file != arg)
    throw InputError("--restart", "no run file '" + r.run_file + "' beside the checkpoint '" + arg + "'");
  if (!fs::exists(r.checkpoint_file))
    throw InputError("--restart", "'" + arg + "' has no checkpoint: '" + r.checkpoint_file +
                                      "' does not exist (the run wrote none: time.checkpoint_interval was 0 and it was "
                                      "not stopped by SIGINT/SIGTERM)");
  r.meta = io::read_checkpoint_meta(r.checkpoint_file);
  std::string mine;
  const std::string hash = scene_identity(s, &mine);
  if (hash != r.meta.scene_hash && io::text_hash(identity_json(s.json, true).dump()) != r.meta.scene_hash) {
    std::string where, legacy;
    try {
      const nlohmann::json saved = nlohmann::json::parse(r.meta.scene_text);
      where = json_first_difference(identity_json(saved), nlohmann::json::parse(mine));
      if (where.empty()) {  // only /stability differs, and the checkpoint's hash includes it
        where = json_first_difference(identity_json(saved, true), identity_json(s.json, true));
        legacy = " (this checkpoint was written before the stability limits could change on a restart: keep "
                 "its /stability values)";
      }
    } catch (const std::exception&) {
    }
    throw InputError("--restart", "the scene differs from the one the checkpoint '" + r.checkpoint_file +
                                      "' was written for (scene hash " + hash + " vs " + r.meta.scene_hash + ")" +
                                      (where.empty() ? std::string() : ", first at " + where) + legacy +
                                      "; restart with the same scene file and --set options");
  }
  // The limits this restart moves, after those of the restarts that led to the checkpoint's state
  // (the checkpoint carries them, so that they always match the state restored).
  if (!r.meta.restart_changes.empty()) {
    try {
      r.changes = nlohmann::json::parse(r.meta.restart_changes).get<std::vector<std::string>>();
    } catch (const std::exception& e) {
      throw InputError("--restart", "the checkpoint '" + r.checkpoint_file +
                                        "' has an unreadable restart_changes record (" + e.what() + ")");
    }
  }
  r.carried_changes = r.changes.size();
  char at[96];
  std::snprintf(at, sizeof at, "at step %llu (t = %.6g s) ", static_cast<unsigned long long>(r.meta.step), r.meta.time);
  for (const std::string& c : stability_changes(nlohmann::json::parse(r.meta.scene_text), s.json))
    r.changes.push_back(at + c);
  if (r.meta.ranks == comm.size())
    r.state = io::read_checkpoint_rank(r.checkpoint_file, comm.rank());
  else
    for (int k = 0; k < r.meta.ranks; ++k) r.all.push_back(io::read_checkpoint_rank(r.checkpoint_file, k));
  r.series = io::read_series_rows(r.run_file, r.meta.series_rows);
  // The per-step load: one row per step up to the checkpoint's.
  for (auto& rows : io::read_series_rows(r.run_file, r.meta.step, sim::kLoadPerStepGroup))
    r.series.push_back(std::move(rows));
  // The pile clock: its rows up to the checkpoint are counted once the schedule is built (apply_restart).
  for (auto& rows : io::read_series_rows(r.run_file, io::kAllRows, sim::kPileClockGroup))
    r.series.push_back(std::move(rows));
  return r;
}

namespace {
/// Float series added to the run file after checkpoints existed: a run file without one still
/// restarts (its rows up to the checkpoint NaN). Any other missing series is refused.
bool added_later(const std::string& path) {
  static const char* const kAddedLater[] = {"/series/max_overlap_ratio",   "/load_per_step/time",
                                            "/load_per_step/force",        "/pile_per_clock/time",
                                            "/pile_per_clock/height_top", "/pile_per_clock/height_mean",
                                            "/pile_per_clock/slope_deg",   "/pile_per_clock/porosity"};
  for (const char* p : kAddedLater)
    if (path == p) return true;
  return false;
}
}  // namespace

std::uint64_t apply_restart(Restart& r, sim::Simulation& sim, sim::Recorders& rec, io::RunFile& file,
                            std::FILE* progress) {
  try {
    std::size_t lost = 0;
    if (r.all.empty()) {  // same rank count: each rank its own state, exactly
      lost = sim.load_checkpoint(r.state, rec);
    } else {  // another rank count: the union of the saved ranks, spread over these ranks
      std::fprintf(progress,
                   "hybridsim: the checkpoint was written by %d rank(s), this run has %d: the particles are "
                   "redistributed (the same physics; sums in another order, round-off differences)\n",
                   r.meta.ranks, sim.comm().size());
      lost = sim.load_checkpoint(r.all, rec);
    }
    if (lost)
      std::fprintf(progress, "hybridsim: warning: %zu saved rigid contact points found no contact manifold after the "
                             "restore; the continuation may differ from the original run in the last bits\n", lost);
  } catch (const InputError&) {
    throw;
  } catch (const std::exception& e) {
    throw InputError("--restart", "the checkpoint '" + r.checkpoint_file + "' does not fit the scene as built: " +
                                      e.what());
  }
  // The snapshots written up to the checkpoint (a stop's extra snapshot is not counted), then the
  // rows up to it, series by series in the order the recorders declared them.
  io::copy_snapshots(r.run_file, r.meta.snapshots, file, sim.comm().rank(), sim.comm().size());
  // Rows up to the checkpoint: of /series, its series_rows; of the per-step load, one per step;
  // of the pile clock, one at t = 0 and one per tick.
  const auto rows_of = [&](const std::string& path) {
    const auto in = [&](const char* group) { return path.rfind(std::string(group) + "/", 0) == 0; };
    return in(sim::kLoadPerStepGroup)  ? r.meta.step
           : in(sim::kPileClockGroup) ? r.meta.step / sim::pile_clock_every(sim.schedule()) + 1
                                      : r.meta.series_rows;
  };
  for (int id = 0; id < file.series_count(); ++id) {
    const std::string& path = file.series_path(id);
    const std::uint64_t rows = rows_of(path);
    const io::SeriesRows* src = nullptr;
    for (const auto& s : r.series)
      if (s.path == path) src = &s;
    if (!src && added_later(path) && !file.series_is_integer(id)) {
      // A series this binary writes and the run file's binary did not: its rows up to the
      // checkpoint are unknown, NaN, so the file keeps one row count for every series.
      std::fprintf(progress, "hybridsim: the run file '%s' has no %s (an older hybridsim wrote it): its rows up to "
                             "the checkpoint are NaN\n", r.run_file.c_str(), path.c_str());
      const std::vector<double> nan(static_cast<std::size_t>(file.series_width(id)),
                                    std::numeric_limits<double>::quiet_NaN());
      for (std::uint64_t row = 0; row < rows; ++row) file.append(id, nan.data());
      continue;
    }
    if (!src || src->width != file.series_width(id) || src->integer != file.series_is_integer(id) || src->rows < rows)
      throw InputError("--restart", "the run file '" + r.run_file + "' has no series " + path +
                                        " of the kind and length this run writes (is it the run file of this "
                                        "checkpoint?)");
    for (std::uint64_t row = 0; row < rows; ++row) {
      const std::size_t o = row * static_cast<std::size_t>(src->width);
      if (src->integer)
        file.append(id, src->i64.data() + o);
      else
        file.append(id, src->f64.data() + o);
    }
  }
  file.flush();
  r.series.clear();
  r.state.entries.clear();
  r.all.clear();
  return sim.step_count();
}

void write_checkpoint(const std::string& ckpt_path, const scene::Scene& s, const sim::Simulation& sim,
                      const sim::Recorders& rec, io::RunFile& file, const par::Comm& comm,
                      const std::vector<std::string>& restart_changes) {
  io::CheckpointMeta identity;  // the scene it belongs to; the simulation adds its step, time and rows
  identity.scene_hash = scene_identity(s, nullptr);
  identity.scene_text = s.json.dump();
  if (!restart_changes.empty()) identity.restart_changes = nlohmann::json(restart_changes).dump();
  sim.save_checkpoint(ckpt_path, identity, rec, file, comm);
}

}  // namespace hs::app
