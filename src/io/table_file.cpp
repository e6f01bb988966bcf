#include "io/table_file.h"

#include "io/h5_handle.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <stdexcept>
#include <unistd.h>

namespace hs::io {

using h5::Handle;

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
