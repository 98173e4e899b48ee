#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>

#include "demfem/io/h5_file.hpp"

using demfem::io::H5Error;
using demfem::io::H5File;

TEST_CASE("HDF5 datasets and attributes round-trip exactly", "[io]") {
  const auto path = std::filesystem::temp_directory_path() / "demfem_test_h5.h5";
  const std::vector<double> x{0.1, 1.0 / 3.0, -2.5e-300, 7.0, 8.0, 9.0};
  const std::vector<std::int64_t> ids{1, -2, 3};
  {
    H5File f(path, H5File::Mode::create);
    f.write("/state/x", x, {2, 3});
    f.write("/state/ids", ids);
    f.set_attribute("/", "time", 0.125);
    f.set_attribute("/state", "step", std::int64_t{42});
    f.set_attribute("/", "kind", std::string("dem"));
  }
  H5File f(path, H5File::Mode::read);
  std::vector<std::size_t> dims;
  CHECK(f.read_doubles("/state/x", &dims) == x);
  CHECK(dims == std::vector<std::size_t>{2, 3});
  CHECK(f.read_int64("/state/ids") == ids);
  CHECK(f.attribute_double("/", "time") == 0.125);
  CHECK(f.attribute_int64("/state", "step") == 42);
  CHECK(f.attribute_string("/", "kind") == "dem");
  CHECK(f.exists("/state/x"));
  CHECK_FALSE(f.exists("/nothing/here"));
  CHECK_THROWS_AS(f.read_doubles("/nothing"), H5Error);
  std::filesystem::remove(path);
}

TEST_CASE("a truncated HDF5 file is refused with its name", "[io]") {
  const auto path = std::filesystem::temp_directory_path() / "demfem_test_trunc.h5";
  {
    H5File f(path, H5File::Mode::create);
    std::vector<double> big(10000, 1.0);
    f.write("/big", big);
  }
  std::filesystem::resize_file(path, std::filesystem::file_size(path) / 2);
  bool refused = false;
  try {
    H5File f(path, H5File::Mode::read);
    f.read_doubles("/big");
  } catch (const H5Error& e) {
    refused = std::string(e.what()).find(path.string()) != std::string::npos;
  }
  CHECK(refused);
  std::filesystem::remove(path);
}
