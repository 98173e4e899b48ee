#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "demfem/io/csv_writer.hpp"

TEST_CASE("CSV rows keep full precision and resume truncates to the checkpoint", "[io]") {
  const auto path = std::filesystem::temp_directory_path() / "demfem_test.csv";
  {
    demfem::io::CsvWriter w(path, {"t", "x"});
    w.row({0.1, 1.0 / 3.0});
    w.row({0.2, 2.0});
    w.row({0.3, 3.0});
  }
  {
    auto w = demfem::io::CsvWriter::resume(path, 2);
    w.row({0.3, 4.0});
  }
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  CHECK(s.str() == "t,x\n0.10000000000000001,0.33333333333333331\n0.20000000000000001,2\n"
                   "0.29999999999999999,4\n");
  CHECK_THROWS(demfem::io::CsvWriter::resume(path, 10));
  std::filesystem::remove(path);
}
