// A study's member table (table.csv, table.h5; docs/study.md "Member table"): one row per member
// with its run record (output, build, cost, exit status) and every metric of its run file.
#pragma once

#include "study/summary.h"

#include <cstdint>
#include <string>
#include <vector>

namespace hs::study {

/// What one member's runs cost and how the last one ended (the study state file keeps it).
struct MemberRecord {
  std::string id, variant;
  std::int64_t seed = 0;
  std::string status = "pending";  ///< pending, done, failed, interrupted
  int exit_code = -1;              ///< of the last run; -1 before any
  std::string output;              ///< run file, relative to the output directory
  std::string program_version;     ///< the run file's program_version
  std::string commit;              ///< the source commit of the study's build (git describe)
  int runs = 0;                    ///< processes started for it (a restart is one more)
  double wall_seconds = 0.0;       ///< summed over its runs
  double core_seconds = 0.0;       ///< user + system CPU of its runs (wait4), summed
  double max_rss_mib = 0.0;        ///< largest resident set of one process of its runs
  double peak_particles = 0.0;     ///< max of /series/particles; NaN when unknown
  std::vector<Quantity> metrics;   ///< the run file's metrics (finished members)
};

/// One column of the table: numbers or text, with unit and description.
struct Column {
  std::string name, unit, description;
  bool text = false;
  std::vector<std::string> texts;
  std::vector<double> numbers;
};

/// The columns: the record's (documented in docs/study.md), then one per metric name found in any
/// record, in name order (NaN where a member lacks it).
std::vector<Column> table_columns(const std::vector<MemberRecord>& records);

/// CSV text: a header of the column names, one line per row; NaN as an empty cell; a text cell with
/// a comma or quote is quoted.
std::string table_csv(const std::vector<Column>& columns);

}  // namespace hs::study
