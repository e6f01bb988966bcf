// HDF5 plumbing shared by the files of src/io (the only module that includes <hdf5.h>):
// one owning handle for every kind of HDF5 identifier, and the error text of a failed call.
// Internal to src/io: other modules use run_file.h, run_file_edit.h and ridge_file.h.
#pragma once

#include <hdf5.h>

#include <string>
#include <utility>

namespace hs::io::h5 {

/// Owns one HDF5 identifier; closes it with the matching H5?close.
class Handle {
 public:
  using Closer = herr_t (*)(hid_t);
  Handle() = default;
  Handle(hid_t id, Closer closer) : id_(id), closer_(closer) {}
  Handle(Handle&& o) noexcept : id_(std::exchange(o.id_, H5I_INVALID_HID)), closer_(o.closer_) {}
  Handle& operator=(Handle&& o) noexcept {
    if (this != &o) {
      reset();
      id_ = std::exchange(o.id_, H5I_INVALID_HID);
      closer_ = o.closer_;
    }
    return *this;
  }
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  ~Handle() { reset(); }
  hid_t get() const { return id_; }
  bool valid() const { return id_ >= 0; }
  /// Gives up ownership without closing.
  hid_t release() { return std::exchange(id_, H5I_INVALID_HID); }
  void reset() {
    if (id_ >= 0 && closer_ != nullptr) closer_(id_);
    id_ = H5I_INVALID_HID;
  }

 private:
  hid_t id_ = H5I_INVALID_HID;
  Closer closer_ = nullptr;
};

/// The current HDF5 error stack as one line (its outermost few frames), then cleared.
std::string error_stack_text();

/// Throws std::runtime_error "HDF5 <call> failed for '<object>' in '<file>' (<error stack>)".
[[noreturn]] void fail(const char* call, const std::string& object, const std::string& file);

/// The checks of the HDF5 calls on one file: a negative identifier or status throws (fail) with the
/// call, the object and this file's path.
struct FileCalls {
  std::string path;
  hid_t check_id(hid_t id, const char* call, const std::string& object) const {
    if (id < 0) fail(call, object, path);
    return id;
  }
  void check(herr_t e, const char* call, const std::string& object) const {
    if (e < 0) fail(call, object, path);
  }
};

}  // namespace hs::io::h5
