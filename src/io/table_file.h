// A study's table.h5 (docs/study.md, "Member table"): one column per dataset.
#pragma once

#include <memory>
#include <string>
#include <vector>

namespace hs::io {

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
