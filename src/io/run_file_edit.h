// Adding to a finished run file: groups, scalar attributes and small 1-D datasets, e.g. the
// end-of-run /analysis (docs/output.md). Serial: one process opens the file after every
// rank's RunFile has been closed.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace hs::io {

class RunFileEditor {
 public:
  /// Reopens an existing HDF5 file read-write (with file locking, as RunFile creates it).
  /// Throws std::runtime_error naming the file if it cannot be opened.
  explicit RunFileEditor(const std::string& path);
  ~RunFileEditor();  ///< closes the file; errors are reported on stderr, not thrown
  RunFileEditor(const RunFileEditor&) = delete;
  RunFileEditor& operator=(const RunFileEditor&) = delete;

  /// Creates the group at `path` (absolute, e.g. "/analysis/iso"); its parent must exist.
  void add_group(const std::string& path);
  /// Scalar attribute `name` on the group or dataset at `object`: a double, or a
  /// fixed-length ASCII string. A non-finite double is refused (std::invalid_argument): a
  /// figure that is not defined is left out and explained, never written as inf or NaN.
  void set_attribute(const std::string& object, const std::string& name, double value);
  void set_attribute(const std::string& object, const std::string& name, const std::string& value);
  /// A 1-D dataset at `path` (little-endian float64 / int64) with "units" and "description"
  /// string attributes.
  void add_vector(const std::string& path, const std::vector<double>& values, const std::string& units,
                  const std::string& description);
  void add_vector(const std::string& path, const std::vector<std::int64_t>& values, const std::string& units,
                  const std::string& description);
  /// A scalar float64 dataset at `path` with "units" and "description" string attributes.
  void add_scalar(const std::string& path, double value, const std::string& units, const std::string& description);
  /// Writes everything to the file (H5Fflush).
  void flush();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace hs::io
