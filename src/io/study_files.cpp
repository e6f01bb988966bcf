#include "io/study_files.h"

#include "io/h5_handle.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <stdexcept>
#include <unistd.h>

namespace hs::io {

using h5::Handle;

namespace {

/// A string attribute of `obj` (fixed or variable length); "" when absent or not a string.
std::string string_attribute(hid_t obj, const char* name) {
  if (H5Aexists(obj, name) <= 0) return "";
  Handle a(H5Aopen(obj, name, H5P_DEFAULT), H5Aclose);
  Handle ft(H5Aget_type(a.get()), H5Tclose);
  if (!a.valid() || !ft.valid() || H5Tget_class(ft.get()) != H5T_STRING) return "";
  Handle mt(H5Tcopy(H5T_C_S1), H5Tclose);
  H5Tset_cset(mt.get(), H5Tget_cset(ft.get()));
  std::string s;
  if (H5Tis_variable_str(ft.get()) > 0) {
    H5Tset_size(mt.get(), H5T_VARIABLE);
    char* c = nullptr;
    if (H5Aread(a.get(), mt.get(), &c) >= 0 && c) s = c;
    H5free_memory(c);
  } else {
    H5Tset_size(mt.get(), H5Tget_size(ft.get()));
    s.assign(H5Tget_size(ft.get()), '\0');
    if (H5Aread(a.get(), mt.get(), s.data()) < 0) return "";
    s.resize(std::strlen(s.c_str()));
  }
  return s;
}

Handle open_read(const std::string& path) {
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  Handle f(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
  if (!f.valid()) h5::fail("H5Fopen", "/", path);
  return f;
}

SeriesValues read_values(hid_t file, const std::string& dataset) {
  SeriesValues out;
  if (H5Lexists(file, dataset.c_str(), H5P_DEFAULT) <= 0) return out;
  Handle d(H5Dopen2(file, dataset.c_str(), H5P_DEFAULT), H5Dclose);
  if (!d.valid()) return out;
  Handle s(H5Dget_space(d.get()), H5Sclose);
  const int rank = H5Sget_simple_extent_ndims(s.get());
  hsize_t dims[2] = {0, 1};
  if (rank < 0 || rank > 2) return out;
  H5Sget_simple_extent_dims(s.get(), dims, nullptr);
  out.width = rank == 2 ? dims[1] : 1;
  out.values.resize(static_cast<std::size_t>(H5Sget_simple_extent_npoints(s.get())));
  if (!out.values.empty() &&
      H5Dread(d.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.values.data()) < 0)
    out.values.clear();
  return out;
}

herr_t visit_metric(hid_t loc, const char* name, const H5O_info_t* info, void* data) {
  if (info->type != H5O_TYPE_DATASET) return 0;
  Handle d(H5Dopen2(loc, name, H5P_DEFAULT), H5Dclose);
  if (!d.valid()) return 0;
  Handle s(H5Dget_space(d.get()), H5Sclose);
  if (H5Sget_simple_extent_npoints(s.get()) != 1) return 0;  // scalar datasets only
  Handle t(H5Dget_type(d.get()), H5Tclose);
  const H5T_class_t c = H5Tget_class(t.get());
  if (c != H5T_FLOAT && c != H5T_INTEGER) return 0;
  RunMetric m{name, string_attribute(d.get(), "unit"), string_attribute(d.get(), "description"), 0.0};
  if (H5Dread(d.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, &m.value) < 0) return 0;
  static_cast<std::vector<RunMetric>*>(data)->push_back(std::move(m));
  return 0;
}

}  // namespace

RunFileFacts read_run_facts(const std::string& path) {
  const Handle f = open_read(path);
  RunFileFacts r;
  r.program_version = string_attribute(f.get(), "program_version");
  const SeriesValues p = read_values(f.get(), "/series/particles");
  r.peak_particles = p.values.empty() ? std::numeric_limits<double>::quiet_NaN()
                                      : *std::max_element(p.values.begin(), p.values.end());
  if (H5Lexists(f.get(), "/analysis", H5P_DEFAULT) > 0 && H5Lexists(f.get(), "/analysis/metrics", H5P_DEFAULT) > 0) {
    Handle g(H5Gopen2(f.get(), "/analysis/metrics", H5P_DEFAULT), H5Gclose);
    if (g.valid()) {
      r.has_metrics = true;
      H5Ovisit(g.get(), H5_INDEX_NAME, H5_ITER_INC, visit_metric, &r.metrics);
    }
  }
  return r;
}

SeriesValues read_series_values(const std::string& path, const std::string& dataset) {
  const Handle f = open_read(path);
  return read_values(f.get(), dataset);
}

struct TableFileWriter::Impl {
  std::string path, tmp;
  Handle file, group;
  void check(bool ok, const char* call, const std::string& object) const {
    if (!ok) h5::fail(call, object, tmp);
  }
  void attribute(hid_t obj, const std::string& name, const std::string& v) const {
    Handle t(H5Tcopy(H5T_C_S1), H5Tclose);
    H5Tset_size(t.get(), std::max<std::size_t>(1, v.size()));
    Handle sp(H5Screate(H5S_SCALAR), H5Sclose);
    Handle a(H5Acreate2(obj, name.c_str(), t.get(), sp.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
    check(a.valid() && H5Awrite(a.get(), t.get(), v.c_str()) >= 0, "H5Awrite", name);
  }
  Handle dataset(const std::string& name, hid_t type, std::size_t n) const {
    const hsize_t dims[1] = {static_cast<hsize_t>(n)};
    Handle sp(H5Screate_simple(1, dims, nullptr), H5Sclose);
    Handle d(H5Dcreate2(group.get(), name.c_str(), type, sp.get(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Dclose);
    check(d.valid(), "H5Dcreate2", "/members/" + name);
    return d;
  }
};

TableFileWriter::TableFileWriter(const std::string& path) : impl_(std::make_unique<Impl>()) {
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  Impl& m = *impl_;
  m.path = path;
  m.tmp = path + ".tmp-" + std::to_string(::getpid());
  m.file = Handle(H5Fcreate(m.tmp.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), H5Fclose);
  m.check(m.file.valid(), "H5Fcreate", "/");
  m.group = Handle(H5Gcreate2(m.file.get(), "/members", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose);
  m.check(m.group.valid(), "H5Gcreate2", "/members");
}

TableFileWriter::~TableFileWriter() {
  if (impl_->file.valid()) {
    impl_->group.reset();
    impl_->file.reset();
    std::remove(impl_->tmp.c_str());
  }
}

void TableFileWriter::add_numbers(const std::string& name, const std::vector<double>& v, const std::string& units,
                                  const std::string& description) {
  const Handle d = impl_->dataset(name, H5T_IEEE_F64LE, v.size());
  if (!v.empty())
    impl_->check(H5Dwrite(d.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()) >= 0, "H5Dwrite", name);
  impl_->attribute(d.get(), "units", units);
  impl_->attribute(d.get(), "description", description);
}

void TableFileWriter::add_texts(const std::string& name, const std::vector<std::string>& v,
                                const std::string& description) {
  Handle t(H5Tcopy(H5T_C_S1), H5Tclose);
  H5Tset_size(t.get(), H5T_VARIABLE);
  H5Tset_cset(t.get(), H5T_CSET_UTF8);
  const Handle d = impl_->dataset(name, t.get(), v.size());
  std::vector<const char*> ptrs;
  for (const std::string& s : v) ptrs.push_back(s.c_str());
  if (!v.empty())
    impl_->check(H5Dwrite(d.get(), t.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, ptrs.data()) >= 0, "H5Dwrite", name);
  impl_->attribute(d.get(), "units", "");
  impl_->attribute(d.get(), "description", description);
}

void TableFileWriter::set_root_attribute(const std::string& name, const std::string& value) {
  impl_->attribute(impl_->file.get(), name, value);
}

void TableFileWriter::close() {
  impl_->group.reset();
  impl_->check(H5Fclose(impl_->file.release()) >= 0, "H5Fclose", "/");
  std::error_code ec;
  std::filesystem::rename(impl_->tmp, impl_->path, ec);
  if (ec) throw std::runtime_error("cannot rename '" + impl_->tmp + "' to '" + impl_->path + "': " + ec.message());
}

}  // namespace hs::io
