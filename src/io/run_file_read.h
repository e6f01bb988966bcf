// Reading a run file back (docs/output.md): its datasets as doubles, attributes, the members of
// a group; for the run metrics (sim/metrics.h), which work from the file alone.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace hs::io {

class RunFileReader {
 public:
  /// Opens an existing HDF5 file read-only. Throws std::runtime_error naming the file if it cannot
  /// be opened (a run still writing it holds a lock: HDF5_USE_FILE_LOCKING=FALSE reads its last flush).
  explicit RunFileReader(const std::string& path);
  ~RunFileReader();
  RunFileReader(const RunFileReader&) = delete;
  RunFileReader& operator=(const RunFileReader&) = delete;

  /// Whether a group or dataset exists at `object` (absolute path; every parent is checked).
  bool has(const std::string& object) const;
  /// Every value of the dataset (HDF5 converts integers), row-major; throws if it is missing.
  std::vector<double> doubles(const std::string& dataset) const;
  /// Values per row: 1 for a scalar or 1-D dataset, else the last dimension.
  int width(const std::string& dataset) const;
  /// A string attribute of `object`, or nothing when it is absent.
  std::optional<std::string> string_attribute(const std::string& object, const std::string& name) const;
  /// A numeric attribute of `object`, or nothing when it is absent.
  std::optional<double> double_attribute(const std::string& object, const std::string& name) const;
  /// The names of the members of the group, in name order (empty when it is missing).
  std::vector<std::string> members(const std::string& group) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace hs::io
