// The HDF5 side of `hybridsim study` (docs/study.md): what the study reads from a member's run
// file, and its table.h5.
#pragma once

#include <memory>
#include <string>
#include <vector>

namespace hs::io {

/// One scalar metric of a run file (/analysis/metrics/<name>, attributes unit and description).
struct RunMetric {
  std::string name, unit, description;
  double value = 0.0;
};

/// What a study records of one finished run file.
struct RunFileFacts {
  std::string program_version;      ///< root attribute program_version ("" when absent)
  double peak_particles = 0.0;      ///< max of /series/particles; NaN without the series
  bool has_metrics = false;         ///< the file has /analysis/metrics
  std::vector<RunMetric> metrics;   ///< every scalar dataset under /analysis/metrics, by path below it
};

/// Reads the facts; throws std::runtime_error naming the file when it cannot be opened.
RunFileFacts read_run_facts(const std::string& path);

/// A /series dataset as doubles, row-major, with its row width (1 for a 1-D series); empty when absent.
struct SeriesValues {
  std::vector<double> values;
  std::size_t width = 1;
};
SeriesValues read_series_values(const std::string& path, const std::string& dataset);

/// table.h5: one 1-D dataset per column under /members (float64, or variable-length UTF-8
/// strings), each with string attributes "units" and "description". Written to a temporary file
/// and renamed over `path` by close() (the destructor drops an unclosed file).
class TableFileWriter {
 public:
  explicit TableFileWriter(const std::string& path);
  ~TableFileWriter();
  TableFileWriter(const TableFileWriter&) = delete;
  TableFileWriter& operator=(const TableFileWriter&) = delete;
  void add_numbers(const std::string& name, const std::vector<double>& v, const std::string& units,
                   const std::string& description);
  void add_texts(const std::string& name, const std::vector<std::string>& v, const std::string& description);
  /// A string attribute on the root group (e.g. the study name).
  void set_root_attribute(const std::string& name, const std::string& value);
  void close();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace hs::io
