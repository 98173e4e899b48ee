#pragma once
// Test double of a damaged checkpoint: one value of an existing HDF5 dataset replaced in
// place (demfem's H5File never rewrites a dataset), e.g. a NaN position in a state whose
// manifest is then recommitted to match, as a checkpoint saved just before a blow-up would.

#include <hdf5.h>

#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

namespace demfem::test {

// One value of a dataset of T (double: H5T_NATIVE_DOUBLE, std::int64_t: H5T_NATIVE_INT64,
// std::uint8_t: H5T_NATIVE_UINT8) replaced in place.
template <class T>
void overwrite_value(const std::filesystem::path& file, const std::string& dataset,
                     std::size_t index, T value, hid_t type) {
  const hid_t f = H5Fopen(file.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
  if (f < 0) throw std::runtime_error(file.string() + ": cannot open");
  const hid_t d = H5Dopen2(f, dataset.c_str(), H5P_DEFAULT);
  if (d < 0) {
    H5Fclose(f);
    throw std::runtime_error(file.string() + ": no dataset " + dataset);
  }
  const hid_t space = H5Dget_space(d);
  std::vector<T> v(static_cast<std::size_t>(H5Sget_simple_extent_npoints(space)));
  H5Sclose(space);
  const bool ok = index < v.size() && H5Dread(d, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()) >= 0;
  if (ok) v[index] = value;
  const bool written = ok && H5Dwrite(d, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()) >= 0;
  H5Dclose(d);
  H5Fclose(f);
  if (!written) throw std::runtime_error(file.string() + ": cannot rewrite " + dataset);
}

inline void overwrite_doubles(const std::filesystem::path& file, const std::string& dataset,
                              std::size_t index, double value) {
  overwrite_value(file, dataset, index, value, H5T_NATIVE_DOUBLE);
}

inline void overwrite_int64(const std::filesystem::path& file, const std::string& dataset,
                            std::size_t index, std::int64_t value) {
  overwrite_value(file, dataset, index, value, H5T_NATIVE_INT64);
}

inline void overwrite_uint8(const std::filesystem::path& file, const std::string& dataset,
                            std::size_t index, std::uint8_t value) {
  overwrite_value(file, dataset, index, value, H5T_NATIVE_UINT8);
}

}  // namespace demfem::test
