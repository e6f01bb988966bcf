#include "io/run_file_edit.h"

#include "io/h5_handle.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <stdexcept>
#include <string>

namespace hs::io {

using h5::Handle;

struct RunFileEditor::Impl : h5::FileCalls {
  Handle file;
  Handle open_object(const std::string& object) const {
    return Handle(check_id(H5Oopen(file.get(), object.c_str(), H5P_DEFAULT), "H5Oopen", object), H5Oclose);
  }
  void attribute(hid_t obj, const std::string& object, const std::string& name, hid_t type, const void* value) const {
    Handle space(check_id(H5Screate(H5S_SCALAR), "H5Screate", object), H5Sclose);
    Handle a(check_id(H5Acreate2(obj, name.c_str(), type, space.get(), H5P_DEFAULT, H5P_DEFAULT), "H5Acreate2",
                      object + "@" + name),
             H5Aclose);
    check(H5Awrite(a.get(), type, value), "H5Awrite", object + "@" + name);
  }
  void string_attribute(hid_t obj, const std::string& object, const std::string& name, const std::string& v) const {
    Handle t(check_id(H5Tcopy(H5T_C_S1), "H5Tcopy", object), H5Tclose);
    check(H5Tset_size(t.get(), std::max<std::size_t>(1, v.size())), "H5Tset_size", object);
    attribute(obj, object, name, t.get(), v.c_str());
  }
  void vector(const std::string& path, hid_t mem_type, hid_t file_type, const void* data, std::size_t n,
              const std::string& units, const std::string& description) const {
    const hsize_t dims[1] = {static_cast<hsize_t>(n)};
    Handle sp(check_id(H5Screate_simple(1, dims, nullptr), "H5Screate_simple", path), H5Sclose);
    Handle d(check_id(H5Dcreate2(file.get(), path.c_str(), file_type, sp.get(), H5P_DEFAULT, H5P_DEFAULT,
                                 H5P_DEFAULT),
                      "H5Dcreate2", path),
             H5Dclose);
    if (n) check(H5Dwrite(d.get(), mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data), "H5Dwrite", path);
    string_attribute(d.get(), path, "units", units);
    string_attribute(d.get(), path, "description", description);
  }
};

RunFileEditor::RunFileEditor(const std::string& path) : impl_(std::make_unique<Impl>()) {
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  Impl& m = *impl_;
  m.path = path;
  Handle fapl(m.check_id(H5Pcreate(H5P_FILE_ACCESS), "H5Pcreate", "/"), H5Pclose);
  m.check(H5Pset_file_locking(fapl.get(), 1, 1), "H5Pset_file_locking", "/");  // as RunFile creates it
  m.file = Handle(m.check_id(H5Fopen(path.c_str(), H5F_ACC_RDWR, fapl.get()), "H5Fopen", "/"), H5Fclose);
}

RunFileEditor::~RunFileEditor() {
  if (!impl_ || !impl_->file.valid()) return;
  const hid_t id = impl_->file.release();
  if (H5Fclose(id) < 0)
    std::fprintf(stderr, "error: HDF5 H5Fclose failed for '%s' (%s)\n", impl_->path.c_str(),
                 h5::error_stack_text().c_str());
}

void RunFileEditor::add_group(const std::string& path) {
  Handle g(impl_->check_id(H5Gcreate2(impl_->file.get(), path.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
                           "H5Gcreate2", path),
           H5Gclose);
}

void RunFileEditor::set_attribute(const std::string& object, const std::string& name, double value) {
  if (!std::isfinite(value))  // a figure that is not defined is omitted (with a note), never written as inf/NaN
    throw std::invalid_argument("refusing to write the non-finite value " + std::to_string(value) + " to attribute '" +
                                name + "' of '" + object + "' in '" + impl_->path +
                                "': omit a figure that is not defined and say why");
  const Handle o = impl_->open_object(object);
  impl_->attribute(o.get(), object, name, H5T_NATIVE_DOUBLE, &value);
}

void RunFileEditor::set_attribute(const std::string& object, const std::string& name, const std::string& value) {
  const Handle o = impl_->open_object(object);
  impl_->string_attribute(o.get(), object, name, value);
}

void RunFileEditor::add_vector(const std::string& path, const std::vector<double>& v, const std::string& units,
                               const std::string& description) {
  for (std::size_t k = 0; k < v.size(); ++k)
    if (!std::isfinite(v[k]))
      throw std::invalid_argument("refusing to write the non-finite value " + std::to_string(v[k]) + " at index " +
                                  std::to_string(k) + " of '" + path + "' in '" + impl_->path + "'");
  impl_->vector(path, H5T_NATIVE_DOUBLE, H5T_IEEE_F64LE, v.data(), v.size(), units, description);
}

void RunFileEditor::add_vector(const std::string& path, const std::vector<std::int64_t>& v,
                               const std::string& units, const std::string& description) {
  impl_->vector(path, H5T_NATIVE_INT64, H5T_STD_I64LE, v.data(), v.size(), units, description);
}

void RunFileEditor::add_scalar(const std::string& path, double value, const std::string& unit,
                               const std::string& description) {
  const Impl& m = *impl_;
  Handle sp(m.check_id(H5Screate(H5S_SCALAR), "H5Screate", path), H5Sclose);
  Handle d(m.check_id(H5Dcreate2(m.file.get(), path.c_str(), H5T_IEEE_F64LE, sp.get(), H5P_DEFAULT, H5P_DEFAULT,
                                 H5P_DEFAULT),
                      "H5Dcreate2", path),
           H5Dclose);
  m.check(H5Dwrite(d.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, &value), "H5Dwrite", path);
  m.string_attribute(d.get(), path, "unit", unit);
  m.string_attribute(d.get(), path, "units", unit);  // as every other dataset of the file
  m.string_attribute(d.get(), path, "description", description);
}

void RunFileEditor::flush() { impl_->check(H5Fflush(impl_->file.get(), H5F_SCOPE_GLOBAL), "H5Fflush", "/"); }

}  // namespace hs::io
