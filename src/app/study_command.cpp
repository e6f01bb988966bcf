#include "app/study_command.h"

#include "app/run.h"
#include "app/study_runner.h"
#include "app/text.h"
#include "common/error.h"
#include "io/run_file_read.h"
#include "io/table_file.h"
#include "json/reader.h"
#include "scene/scene.h"
#include "sim/build_identity.h"
#include "sim/metrics.h"
#include "study/study.h"
#include "study/summary.h"
#include "study/table.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

namespace hs::app {

namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using study::Member;
using study::MemberRecord;
using study::StudyDef;

constexpr const char* kStateFile = "study_state.json";

// ---------------------------------------------------------------- members

/// The run of a member without --restart: the arguments the state file keeps and compares.
std::vector<std::string> run_args(const StudyDef& d, const Member& m) {
  std::vector<std::string> a = {"run", fs::absolute(d.base_scene).lexically_normal().string(), "-o",
                                fs::absolute(d.output_dir / m.output_rel()).lexically_normal().string()};
  for (const std::string& o : m.overrides) {
    a.push_back("--set");
    a.push_back(o);
  }
  return a;
}

/// Every variant's scene loads with its overrides (the first seed of each), before anything runs.
void check_member_scenes(const StudyDef& d, const std::vector<Member>& members) {
  std::string seen;
  for (const Member& m : members) {
    if (m.variant == seen) continue;
    seen = m.variant;
    try {
      (void)scene::load_scene_file(d.base_scene.string(), m.overrides);
    } catch (const InputError& e) {
      throw InputError(d.study_file.string(), "member " + m.id() + " (base " + d.base_scene.string() +
                                                  "): " + e.what() + "; fix the study's \"set\", \"variants\" or "
                                                  "\"grid\" entry that gives it");
    }
  }
}

// ---------------------------------------------------------------- state file

json load_state(const fs::path& path) {
  if (!fs::exists(path)) return json{{"members", json::object()}};
  try {
    json j = read_json_file(path.string(), "study state file");
    if (j.is_object() && j.contains("members") && j["members"].is_object()) return j;
  } catch (const InputError&) {
  }
  throw InputError(path.string(), "is not a study state file; move it away to start the study afresh (every "
                                  "member then runs again)");
}

/// Written to a temporary file, flushed to disk and renamed: a reader sees the old or the new file.
void save_state(const fs::path& path, const json& state) {
  const fs::path tmp = path.string() + ".tmp-" + std::to_string(::getpid());
  {
    std::ofstream f(tmp);
    f << state.dump(2) << "\n";
    f.flush();
    if (!f) throw std::runtime_error("cannot write the study state file '" + tmp.string() + "'");
  }
  const int fd = ::open(tmp.c_str(), O_RDONLY);
  if (fd >= 0) {
    ::fsync(fd);
    ::close(fd);
  }
  fs::rename(tmp, path);
}

MemberRecord record_of(const Member& m, const json& entry) {
  MemberRecord r;
  r.id = m.id();
  r.variant = m.variant;
  r.seed = m.seed;
  r.output = m.output_rel().string();
  if (entry.is_null()) return r;
  r.status = entry.value("status", "pending");
  r.exit_code = entry.value("exit_code", -1);
  r.runs = entry.value("runs", 0);
  r.wall_seconds = entry.value("wall_seconds", 0.0);
  r.core_seconds = entry.value("core_seconds", 0.0);
  r.max_rss_mib = entry.value("max_rss_mib", 0.0);
  r.commit = entry.value("commit", "");
  return r;
}

json entry_of(const MemberRecord& r, const std::vector<std::string>& args) {
  return {{"status", r.status},       {"exit_code", r.exit_code},       {"runs", r.runs},
          {"wall_seconds", r.wall_seconds}, {"core_seconds", r.core_seconds}, {"max_rss_mib", r.max_rss_mib},
          {"commit", r.commit},       {"args", args}};
}

/// A member recorded with other run arguments (the study file changed under it) is refused.
void check_recorded_args(const json& entry, const std::vector<std::string>& args, const Member& m,
                         const fs::path& state_path) {
  if (entry.is_null() || !entry.contains("args") || entry["args"] == json(args)) return;
  throw InputError(state_path.string(), "member " + m.id() + " was run with other arguments (" +
                                            json_show(entry["args"]) + ") than the study now gives it; restore the "
                                            "study file, or give the study another \"output_dir\"");
}

/// Held while the study runs: a second `hybridsim study` on the same output directory is refused.
class StudyLock {
 public:
  explicit StudyLock(const fs::path& dir) : path_(dir / "study.lock") {
    fd_ = ::open(path_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd_ < 0) throw InputError("/output_dir", "cannot create '" + path_.string() + "'; check the permissions");
    if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
      std::ifstream in(path_);
      std::string pid;
      in >> pid;
      ::close(fd_);
      throw InputError("/output_dir", "another `hybridsim study` (process " + pid + ") is running in '" +
                                          path_.parent_path().string() + "'; wait for it, or give this study "
                                          "another \"output_dir\"");
    }
    const std::string pid = std::to_string(::getpid()) + "\n";
    if (::ftruncate(fd_, 0) == 0 && ::write(fd_, pid.data(), pid.size()) < 0) {
    }
  }
  ~StudyLock() { ::close(fd_); }
  StudyLock(const StudyLock&) = delete;
  StudyLock& operator=(const StudyLock&) = delete;

 private:
  fs::path path_;
  int fd_ = -1;
};

// ---------------------------------------------------------------- one member's run

/// Its run: `hybridsim run ...` (under mpirun -np K when mpi_ranks > 1), with --restart when its
/// checkpoint exists (the run file it continues: the output, or the newest partial file of a killed run).
StudyJob member_job(const StudyDef& d, std::size_t index, const Member& m, const std::string& exe,
                    std::string& how) {
  const fs::path out = d.output_dir / m.output_rel();
  const fs::path ckpt = fs::path(out).replace_extension(".ckpt.h5");
  StudyJob job{index, {}, fs::path(out).replace_extension(".log").string()};
  if (d.mpi_ranks > 1) {
    std::istringstream words(d.mpirun);  // the launcher and its own options, split at spaces
    for (std::string w; words >> w;) job.argv.push_back(w);
    job.argv.insert(job.argv.end(), {"-np", std::to_string(d.mpi_ranks)});
  }
  job.argv.push_back(exe);
  for (const std::string& a : run_args(d, m)) job.argv.push_back(a);
  how = "fresh";
  if (!fs::exists(ckpt)) return job;
  fs::path from = out;
  if (!fs::exists(out)) {
    from.clear();
    const std::string stem = out.stem().string() + ".partial-";
    fs::file_time_type newest{};
    for (const auto& e : fs::directory_iterator(out.parent_path()))
      if (e.path().filename().string().rfind(stem, 0) == 0 && e.path().extension() == ".h5" &&
          (from.empty() || e.last_write_time() > newest)) {
        from = e.path();
        newest = e.last_write_time();
      }
  }
  if (from.empty()) return job;
  job.argv.push_back("--restart");
  job.argv.push_back(fs::absolute(from).lexically_normal().string());
  how = "restart from " + ckpt.filename().string();
  return job;
}

/// Stand-in metric for a run file without /analysis/metrics and /load_per_step (written before the
/// run metrics existed): the peak over the output rows of the horizontal magnitude of /series/force.
std::vector<study::Quantity> stand_in_metrics(const io::RunFileReader& f) {
  if (!f.has("/series/force") || f.width("/series/force") != 3) return {};
  const std::vector<double> v = f.doubles("/series/force");
  double peak = 0.0;
  for (std::size_t i = 0; i + 2 < v.size(); i += 3) peak = std::max(peak, std::hypot(v[i], v[i + 1]));
  return {{"peak_fh_rows", "N", "peak of the horizontal magnitude of /series/force over the output rows", peak}};
}

/// A finished member's figures from its run file: version, peak particles and metrics (those the
/// file holds; with the study's windows, computed from the file with them).
void add_run_facts(MemberRecord& r, const fs::path& file, const std::vector<sim::MetricWindow>& windows) {
  const io::RunFileReader f(file.string());
  r.program_version = f.string_attribute("/", "program_version").value_or("");
  if (f.has("/series/particles")) {
    const std::vector<double> p = f.doubles("/series/particles");
    if (!p.empty()) r.peak_particles = *std::max_element(p.begin(), p.end());
  }
  const bool stored = f.has(sim::kMetricsGroup);
  if (!stored && !f.has("/load_per_step")) {
    r.metrics = stand_in_metrics(f);
    return;
  }
  const std::vector<analysis::Metric> m = windows.empty() && stored
                                              ? sim::read_run_metrics(file.string())
                                              : sim::compute_run_metrics(file.string(), {.windows = windows});
  for (const analysis::Metric& x : m) r.metrics.push_back({x.name, x.unit, x.description, x.value});
}

// ---------------------------------------------------------------- outputs

void write_text(const fs::path& path, const std::string& text) {
  const fs::path tmp = path.string() + ".tmp-" + std::to_string(::getpid());
  std::ofstream(tmp) << text;
  fs::rename(tmp, path);
}

void write_table_h5(const fs::path& path, const std::vector<study::Column>& columns, const std::string& name) {
  io::TableFileWriter w(path.string());
  w.set_root_attribute("study", name);
  w.set_root_attribute("description", "one row per member of the study; columns in docs/study.md");
  for (const study::Column& c : columns)
    if (c.text)
      w.add_texts(c.name, c.texts, c.description);
    else
      w.add_numbers(c.name, c.numbers, c.unit, c.description);
  w.close();
}

/// The metric the front plots: the study's primary_metric, else (or when no member has it, with a
/// warning naming the metrics there are) the first metric in name order.
std::string front_metric(const StudyDef& d, const std::vector<study::SummaryRow>& rows, std::FILE* progress) {
  std::vector<std::string> names;
  for (const study::SummaryRow& r : rows)
    if (r.quantity != "core_hours" && std::find(names.begin(), names.end(), r.quantity) == names.end())
      names.push_back(r.quantity);
  if (names.empty() || d.primary_metric.empty()) return names.empty() ? "" : names.front();
  if (std::find(names.begin(), names.end(), d.primary_metric) != names.end()) return d.primary_metric;
  std::string all;
  for (const std::string& n : names) all += (all.empty() ? "" : ", ") + n;
  std::fprintf(progress, "warning: /primary_metric: no member has the metric \"%s\"; the front plots \"%s\". The "
                         "metrics are: %s\n", d.primary_metric.c_str(), names.front().c_str(), all.c_str());
  return names.front();
}

/// front.png by tools/plot_study.py when python3 with matplotlib is there, else the command to run.
void draw_front(const StudyDef& d, const std::string& metric, std::FILE* progress) {
  const std::string script = HYBRIDSIM_SOURCE_DIR "/tools/plot_study.py";
  const std::string python = fs::exists("/usr/bin/python3") ? "/usr/bin/python3" : "python3";
  const std::string cmd = python + " '" + script + "' '" + d.output_dir.string() + "'" +
                          (metric.empty() ? "" : " --metric '" + metric + "'");
  const bool have = fs::exists(script) &&
                    std::system((python + " -c 'import matplotlib' > /dev/null 2>&1").c_str()) == 0;
  if (have && std::system((cmd + " > /dev/null").c_str()) == 0) {
    std::fprintf(progress, "study: front: %s\n", (d.output_dir / "front.png").c_str());
    return;
  }
  std::fprintf(progress, "study: front.png not drawn (needs python3 with matplotlib); to draw it: %s\n", cmd.c_str());
}

/// table.csv, table.h5, summary.csv, summary.md and front.png from the members' records.
void write_outputs(const StudyDef& d, std::vector<MemberRecord> records, bool plot, std::FILE* progress) {
  const std::vector<sim::MetricWindow> windows =
      d.windows.is_null() ? std::vector<sim::MetricWindow>{} : sim::metric_windows_from_json(d.windows, "/windows");
  std::vector<study::MemberFigures> figures;
  for (MemberRecord& r : records) {
    if (r.status != "done") continue;
    add_run_facts(r, d.output_dir / r.output, windows);
    study::MemberFigures f{r.variant, r.metrics};
    f.quantities.push_back({"core_hours", "h", "core-hours of the member", r.core_seconds / 3600.0});
    figures.push_back(std::move(f));
  }
  const std::vector<study::Column> columns = study::table_columns(records);
  write_text(d.output_dir / "table.csv", study::table_csv(columns));
  write_table_h5(d.output_dir / "table.h5", columns, d.name);
  std::vector<std::string> variants;
  for (const study::Variant& v : d.variants) variants.push_back(v.name);
  const auto rows = study::summarise(figures, variants, d.reference);
  const std::string metric = front_metric(d, rows, progress);
  write_text(d.output_dir / "summary.csv", study::summary_csv(rows));
  write_text(d.output_dir / "summary.md", study::summary_markdown(rows, d.name, d.reference, metric));
  std::fprintf(progress, "study: table: %s (+ table.h5), summary: %s (+ summary.md)\n",
               (d.output_dir / "table.csv").c_str(), (d.output_dir / "summary.csv").c_str());
  if (plot && !rows.empty()) draw_front(d, metric, progress);
}

// ---------------------------------------------------------------- the command

/// --dry-run: every member with its state and estimated core-hours (check's estimate, per variant).
int dry_run(const StudyDef& d, const std::vector<Member>& members, const std::vector<MemberRecord>& records,
            std::ostream& out) {
  std::map<std::string, double> hours;
  double total = 0.0;
  out << "study " << d.name << ": " << members.size() << " members, output in " << d.output_dir.string() << "\n";
  for (std::size_t k = 0; k < members.size(); ++k) {
    const Member& m = members[k];
    if (!hours.count(m.variant)) {
      RunOptions o;
      o.scene_path = d.base_scene.string();
      o.overrides = m.overrides;
      hours[m.variant] = estimated_core_seconds(o) / 3600.0;
    }
    const bool done = records[k].status == "done";
    if (!done) total += hours[m.variant];
    out << "  " << m.id() << "  " << records[k].status << "  ~" << sci(hours[m.variant], 3) << " core-h";
    if (d.mpi_ranks > 1) out << " (mpirun -np " << d.mpi_ranks << ")";
    out << "\n";
  }
  out << "estimated: ~" << sci(total, 3) << " core-hours for the members not done (one-core estimate of "
      << "`hybridsim check`; nothing run)\n";
  return 0;
}

}  // namespace

namespace {

/// "2 variants x 3 seeds", or "8 variants, 3 to 5 seeds each" when "variant_seeds" gives some their own.
std::string seeds_text(const StudyDef& d) {
  std::size_t lo = SIZE_MAX, hi = 0;
  for (const study::Variant& v : d.variants) {
    lo = std::min(lo, v.seeds.size());
    hi = std::max(hi, v.seeds.size());
  }
  const std::string n = std::to_string(d.variants.size()) + " variants";
  return lo == hi ? n + " x " + std::to_string(lo) + " seeds"
                  : n + ", " + std::to_string(lo) + " to " + std::to_string(hi) + " seeds each";
}

/// The members' records from the state file; each recorded member's arguments checked.
std::vector<MemberRecord> records_of(const StudyDef& d, const std::vector<Member>& members, const json& state,
                                     const fs::path& state_path) {
  std::vector<MemberRecord> records;
  for (const Member& m : members) {
    const json& all = state["members"];
    const json entry = all.contains(m.id()) ? all[m.id()] : json();
    check_recorded_args(entry, run_args(d, m), m, state_path);
    records.push_back(record_of(m, entry));
    if (records.back().status == "done" && !fs::exists(d.output_dir / m.output_rel()))
      records.back().status = "pending";  // its run file is gone: run it again
  }
  return records;
}

/// The record after one run of the member ended.
void record_end(MemberRecord& r, const StudyJobEnd& e) {
  ++r.runs;
  r.exit_code = e.exit_code;
  r.wall_seconds += e.wall_seconds;
  r.core_seconds += e.core_seconds;
  r.max_rss_mib = std::max(r.max_rss_mib, e.max_rss_mib);
  r.commit = sim::build_identity().at("commit").get<std::string>();
  // 130/143: a run stopped by a signal, resumable from its checkpoint; > 128: killed by one.
  const bool interrupted = e.stopped || e.exit_code == 130 || e.exit_code == 143 || e.exit_code > 128;
  r.status = e.exit_code == 0 ? "done" : interrupted ? "interrupted" : "failed";
}

/// Runs the members not done; returns the signal that stopped the study (0: none).
int run_members(const StudyDef& d, const std::vector<Member>& members, std::vector<MemberRecord>& records,
                const StudyOptions& opt, std::FILE* progress) {
  const fs::path state_path = d.output_dir / kStateFile;
  json state = load_state(state_path);
  const std::string exe = fs::read_symlink("/proc/self/exe").string();
  std::vector<StudyJob> queue;
  std::map<std::size_t, std::string> how;
  std::size_t done = 0;
  for (std::size_t k = 0; k < members.size(); ++k) {
    const MemberRecord& r = records[k];
    if (r.status == "done") ++done;
    if (r.status == "done" || (r.status == "failed" && !opt.retry_failed)) continue;
    fs::create_directories((d.output_dir / members[k].output_rel()).parent_path());
    queue.push_back(member_job(d, k, members[k], exe, how[k]));
  }
  std::fprintf(progress, "study %s: %zu members (%s): %zu done, %zu to run (-j %d)\n", d.name.c_str(), members.size(),
               seeds_text(d).c_str(), done, queue.size(), opt.jobs);
  for (std::size_t k = 0; k < members.size(); ++k)
    if (records[k].status == "failed" && !opt.retry_failed)
      std::fprintf(progress, "study: %s failed earlier (exit %d), not run again (--retry-failed runs it); log %s\n",
                   records[k].id.c_str(), records[k].exit_code,
                   fs::path(d.output_dir / members[k].output_rel()).replace_extension(".log").c_str());
  const auto started = [&](const StudyJob& j) {
    std::fprintf(progress, "study: start    %s (%s); log %s\n", records[j.member].id.c_str(), how[j.member].c_str(),
                 j.log.c_str());
  };
  const auto ended = [&](const StudyJob& j, const StudyJobEnd& e) {
    MemberRecord& r = records[j.member];
    record_end(r, e);
    state["members"][r.id] = entry_of(r, run_args(d, members[j.member]));
    save_state(state_path, state);
    if (r.status == "done") ++done;
    std::fprintf(progress, "study: %-8s %s in %s s wall, %s core-s (exit %d); %zu/%zu members done\n",
                 r.status.c_str(), r.id.c_str(), sci(e.wall_seconds, 3).c_str(), sci(e.core_seconds, 3).c_str(),
                 e.exit_code, done, members.size());
  };
  return run_study_jobs(queue, opt.jobs, started, ended);
}

}  // namespace

int study_command(const StudyOptions& opt, std::ostream& out, std::FILE* progress) {
  const StudyDef d = study::load_study_file(opt.study_file);
  const std::vector<Member> members = d.members();
  check_member_scenes(d, members);
  if (!d.windows.is_null()) (void)sim::metric_windows_from_json(d.windows, "/windows");
  const fs::path state_path = d.output_dir / kStateFile;
  if (opt.dry_run) return dry_run(d, members, records_of(d, members, load_state(state_path), state_path), out);
  std::error_code ec;
  fs::create_directories(d.output_dir, ec);
  if (ec || !fs::is_directory(d.output_dir))
    throw InputError("/output_dir", "cannot create the output directory '" + d.output_dir.string() + "' (" +
                                        ec.message() + "); give a writable \"output_dir\"");
  const StudyLock lock(d.output_dir);
  std::vector<MemberRecord> records = records_of(d, members, load_state(state_path), state_path);
  const int sig = run_members(d, members, records, opt, progress);
  write_outputs(d, records, !opt.no_plot, progress);
  std::size_t done = 0, failed = 0;
  for (const MemberRecord& r : records) {
    done += r.status == "done";
    failed += r.status == "failed";
  }
  std::fprintf(progress, "study %s: %zu/%zu members done%s\n", d.name.c_str(), done, records.size(),
               failed ? (", " + std::to_string(failed) + " failed (their logs beside their run files)").c_str() : "");
  if (sig != 0) {
    std::fprintf(progress, "study: stopped by %s; run the same command again to continue\n",
                 sig == SIGINT ? "SIGINT" : "SIGTERM");
    return 128 + sig;
  }
  return done == records.size() ? 0 : 1;
}

}  // namespace hs::app
