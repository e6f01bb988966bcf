// Reading run files back in the CLI tests: one helper instead of a copy per test file.
#pragma once

#include <gtest/gtest.h>
#include <hdf5.h>

#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace hs::testing {

/// Every value of a dataset as doubles (HDF5 converts), empty when the file or dataset is missing.
inline std::vector<double> read_doubles(const std::filesystem::path& file, const std::string& dataset) {
  std::vector<double> v;
  const hid_t f = H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (f < 0) return v;
  const hid_t d = H5Dopen2(f, dataset.c_str(), H5P_DEFAULT);
  if (d >= 0) {
    const hid_t s = H5Dget_space(d);
    v.resize(static_cast<std::size_t>(H5Sget_simple_extent_npoints(s)));
    if (!v.empty()) H5Dread(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data());
    H5Sclose(s);
    H5Dclose(d);
  }
  H5Fclose(f);
  return v;
}

inline herr_t collect_dataset_names(hid_t loc, const char* name, const H5L_info_t*, void* data) {
  H5O_info_t info;
  if (H5Oget_info_by_name(loc, name, &info, H5P_DEFAULT) >= 0 && info.type == H5O_TYPE_DATASET)
    static_cast<std::vector<std::string>*>(data)->push_back(name);
  return 0;
}

/// Every dataset under `group` of `file` as raw bytes (native type of the file), by name.
inline std::map<std::string, std::string> datasets(const std::filesystem::path& file, const std::string& group) {
  std::map<std::string, std::string> out;
  const hid_t f = H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (f < 0) return out;
  const hid_t g = H5Gopen2(f, group.c_str(), H5P_DEFAULT);
  if (g >= 0) {
    std::vector<std::string> names;
    H5Lvisit(g, H5_INDEX_NAME, H5_ITER_INC, collect_dataset_names, &names);
    for (const auto& n : names) {
      const hid_t d = H5Dopen2(g, n.c_str(), H5P_DEFAULT);
      const hid_t t = H5Dget_type(d);
      const hid_t nt = H5Tget_native_type(t, H5T_DIR_ASCEND);
      const hid_t s = H5Dget_space(d);
      std::string bytes(static_cast<std::size_t>(H5Sget_simple_extent_npoints(s)) * H5Tget_size(nt), '\0');
      if (!bytes.empty()) H5Dread(d, nt, H5S_ALL, H5S_ALL, H5P_DEFAULT, bytes.data());
      out[n] = bytes;
      H5Sclose(s);
      H5Tclose(nt);
      H5Tclose(t);
      H5Dclose(d);
    }
    H5Gclose(g);
  }
  H5Fclose(f);
  return out;
}

/// Every /series dataset and every /load_per_step dataset (the structure's load of every step,
/// the run metrics' source) of a and b bit-identical, and the same set of them.
inline void expect_same_series(const std::filesystem::path& a, const std::filesystem::path& b) {
  for (const std::string group : {"/series", "/load_per_step"}) {
    const auto sa = datasets(a, group), sb = datasets(b, group);
    ASSERT_FALSE(sa.empty()) << a << " " << group;
    ASSERT_EQ(sa.size(), sb.size()) << group;
    for (const auto& [name, bytes] : sa) {
      ASSERT_TRUE(sb.count(name)) << name;
      EXPECT_TRUE(sb.at(name) == bytes) << group << "/" << name << " differs between " << a << " and " << b;
    }
  }
}

}  // namespace hs::testing
