// Reading run files back in the CLI tests: one helper instead of a copy per test file.
#pragma once

#include <hdf5.h>

#include <filesystem>
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

}  // namespace hs::testing
