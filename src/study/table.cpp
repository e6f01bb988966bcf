#include "study/table.h"

#include <limits>
#include <map>
#include <sstream>

namespace hs::study {

namespace {

Column text(const std::string& name, const std::string& description) { return {name, "", description, true, {}, {}}; }
Column number(const std::string& name, const std::string& unit, const std::string& description) {
  return {name, unit, description, false, {}, {}};
}

}  // namespace

std::vector<Column> table_columns(const std::vector<MemberRecord>& records) {
  std::vector<Column> c = {
      text("member", "member id <variant>/seed<k>"),
      text("variant", "variant name"),
      number("seed", "1", "the member's seed (scene field seed)"),
      text("status", "done, failed, interrupted or pending"),
      number("exit_code", "1", "exit status of the member's last run (-1: not run)"),
      text("output", "run file, relative to the output directory"),
      text("program_version", "program_version of the run file"),
      text("commit", "source commit of the build that ran the study (git describe --always --dirty)"),
      number("runs", "1", "processes started for the member (a restart counts one more)"),
      number("wall_seconds", "s", "wall time of the member's runs, summed"),
      number("core_seconds", "s", "user + system CPU time of the member's runs (wait4), summed"),
      number("core_hours", "h", "core_seconds / 3600"),
      number("max_rss_mib", "MiB", "peak resident memory of one process of the member's runs (ru_maxrss)"),
      number("peak_particles", "1", "largest particle count of the run (/series/particles)"),
  };
  for (const MemberRecord& r : records) {
    c[0].texts.push_back(r.id);
    c[1].texts.push_back(r.variant);
    c[2].numbers.push_back(static_cast<double>(r.seed));
    c[3].texts.push_back(r.status);
    c[4].numbers.push_back(r.exit_code);
    c[5].texts.push_back(r.output);
    c[6].texts.push_back(r.program_version);
    c[7].texts.push_back(r.commit);
    c[8].numbers.push_back(r.runs);
    c[9].numbers.push_back(r.wall_seconds);
    c[10].numbers.push_back(r.core_seconds);
    c[11].numbers.push_back(r.core_seconds / 3600.0);
    c[12].numbers.push_back(r.max_rss_mib);
    c[13].numbers.push_back(r.peak_particles);
  }
  std::map<std::string, Column> metrics;
  for (const MemberRecord& r : records)
    for (const Quantity& q : r.metrics) metrics.emplace(q.name, number(q.name, q.unit, q.description));
  for (auto& [name, col] : metrics) {
    for (const MemberRecord& r : records) {
      double v = std::numeric_limits<double>::quiet_NaN();
      for (const Quantity& q : r.metrics)
        if (q.name == name) v = q.value;
      col.numbers.push_back(v);
    }
    c.push_back(std::move(col));
  }
  return c;
}

std::string table_csv(const std::vector<Column>& columns) {
  std::ostringstream s;
  std::size_t rows = 0;
  for (std::size_t k = 0; k < columns.size(); ++k) {
    s << (k ? "," : "") << csv_cell(columns[k].name);
    rows = columns[k].text ? columns[k].texts.size() : columns[k].numbers.size();
  }
  s << "\n";
  for (std::size_t i = 0; i < rows; ++i) {
    for (std::size_t k = 0; k < columns.size(); ++k)
      s << (k ? "," : "") << (columns[k].text ? csv_cell(columns[k].texts[i]) : number_text(columns[k].numbers[i]));
    s << "\n";
  }
  return s.str();
}

}  // namespace hs::study
