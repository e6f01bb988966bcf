#include "io/run_file_read.h"

#include "io/h5_handle.h"

#include <algorithm>
#include <cstdio>

namespace hs::io {

using h5::Handle;

struct RunFileReader::Impl : h5::FileCalls {
  Handle file;
  bool attribute_exists(const std::string& object, const std::string& name) const {
    return H5Aexists_by_name(file.get(), object.c_str(), name.c_str(), H5P_DEFAULT) > 0;
  }
  Handle open_attribute(const std::string& object, const std::string& name) const {
    return Handle(check_id(H5Aopen_by_name(file.get(), object.c_str(), name.c_str(), H5P_DEFAULT, H5P_DEFAULT),
                           "H5Aopen_by_name", object + "@" + name),
                  H5Aclose);
  }
};

RunFileReader::RunFileReader(const std::string& path) : impl_(std::make_unique<Impl>()) {
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  impl_->path = path;
  impl_->file = Handle(impl_->check_id(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), "H5Fopen", "/"), H5Fclose);
}

RunFileReader::~RunFileReader() = default;

bool RunFileReader::has(const std::string& object) const {
  if (object == "/") return true;
  std::size_t pos = 0;
  while ((pos = object.find('/', pos + 1)) != std::string::npos)
    if (H5Lexists(impl_->file.get(), object.substr(0, pos).c_str(), H5P_DEFAULT) <= 0) return false;
  return H5Lexists(impl_->file.get(), object.c_str(), H5P_DEFAULT) > 0;
}

std::vector<double> RunFileReader::doubles(const std::string& dataset) const {
  const Impl& m = *impl_;
  Handle d(m.check_id(H5Dopen2(m.file.get(), dataset.c_str(), H5P_DEFAULT), "H5Dopen2", dataset), H5Dclose);
  Handle space(m.check_id(H5Dget_space(d.get()), "H5Dget_space", dataset), H5Sclose);
  const hssize_t n = H5Sget_simple_extent_npoints(space.get());
  std::vector<double> v(static_cast<std::size_t>(std::max<hssize_t>(n, 0)));
  if (!v.empty()) m.check(H5Dread(d.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()), "H5Dread", dataset);
  return v;
}

int RunFileReader::width(const std::string& dataset) const {
  const Impl& m = *impl_;
  Handle d(m.check_id(H5Dopen2(m.file.get(), dataset.c_str(), H5P_DEFAULT), "H5Dopen2", dataset), H5Dclose);
  Handle space(m.check_id(H5Dget_space(d.get()), "H5Dget_space", dataset), H5Sclose);
  const int rank = H5Sget_simple_extent_ndims(space.get());
  if (rank < 2) return 1;
  std::vector<hsize_t> dims(static_cast<std::size_t>(rank));
  m.check(H5Sget_simple_extent_dims(space.get(), dims.data(), nullptr), "H5Sget_simple_extent_dims", dataset);
  return static_cast<int>(dims.back());
}

std::optional<std::string> RunFileReader::string_attribute(const std::string& object, const std::string& name) const {
  const Impl& m = *impl_;
  if (!has(object) || !m.attribute_exists(object, name)) return std::nullopt;
  const std::string where = object + "@" + name;
  const Handle a = m.open_attribute(object, name);
  Handle type(m.check_id(H5Aget_type(a.get()), "H5Aget_type", where), H5Tclose);
  if (H5Tget_class(type.get()) != H5T_STRING) return std::nullopt;
  if (H5Tis_variable_str(type.get()) > 0) {
    char* s = nullptr;
    Handle mem(m.check_id(H5Tget_native_type(type.get(), H5T_DIR_ASCEND), "H5Tget_native_type", where), H5Tclose);
    m.check(H5Aread(a.get(), mem.get(), &s), "H5Aread", where);
    std::string out = s ? s : "";
    H5free_memory(s);
    return out;
  }
  std::string s(H5Tget_size(type.get()), '\0');
  m.check(H5Aread(a.get(), type.get(), s.data()), "H5Aread", where);
  s.erase(std::find(s.begin(), s.end(), '\0'), s.end());
  return s;
}

std::optional<double> RunFileReader::double_attribute(const std::string& object, const std::string& name) const {
  const Impl& m = *impl_;
  if (!has(object) || !m.attribute_exists(object, name)) return std::nullopt;
  const Handle a = m.open_attribute(object, name);
  double v = 0.0;
  m.check(H5Aread(a.get(), H5T_NATIVE_DOUBLE, &v), "H5Aread", object + "@" + name);
  return v;
}

namespace {
herr_t collect_name(hid_t, const char* name, const H5L_info_t*, void* out) {
  static_cast<std::vector<std::string>*>(out)->emplace_back(name);
  return 0;
}
}  // namespace

std::vector<std::string> RunFileReader::members(const std::string& group) const {
  std::vector<std::string> names;
  if (!has(group)) return names;
  const Impl& m = *impl_;
  Handle g(m.check_id(H5Gopen2(m.file.get(), group.c_str(), H5P_DEFAULT), "H5Gopen2", group), H5Gclose);
  m.check(H5Literate(g.get(), H5_INDEX_NAME, H5_ITER_INC, nullptr, collect_name, &names), "H5Literate", group);
  return names;
}

}  // namespace hs::io
