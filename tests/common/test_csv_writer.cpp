#include <catch2/catch.hpp>

#include <sys/stat.h>

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

TEST_CASE("keep_csv_rows cuts in place, and a row cut by a kill is no row", "[io]") {
  // A resume used to rewrite the kept rows: a process killed meanwhile left fewer rows than
  // its checkpoint needs, and the run could not be resumed any more. Now one truncate.
  const auto path = std::filesystem::temp_directory_path() / "demfem_test_keep.csv";
  {
    std::ofstream out(path, std::ios::binary);
    out << "t,x\n0,1\n1,2\n2,3\n3,4";  // the last row lost its end to a kill
  }
  CHECK(demfem::io::read_csv_rows(path) == std::vector<std::string>{"0,1", "1,2", "2,3"});
  const auto inode = [&] {
    struct stat st {};
    ::stat(path.c_str(), &st);
    return st.st_ino;
  };
  const auto before = inode();
  demfem::io::keep_csv_rows(path, 2);
  CHECK(inode() == before);  // the same file, cut: not a rewritten copy
  {
    std::ifstream in(path, std::ios::binary);
    std::stringstream s;
    s << in.rdbuf();
    CHECK(s.str() == "t,x\n0,1\n1,2\n");
  }
  // Asking for more rows than there are names the file and both counts; nothing is cut.
  try {
    demfem::io::keep_csv_rows(path, 3);
    FAIL("no error");
  } catch (const std::runtime_error& e) {
    CHECK(std::string(e.what()) ==
          path.string() + ": has 2 rows, the checkpoint expects at least 3");
  }
  CHECK(std::filesystem::file_size(path) == 12);
  // A resumed writer appends after the kept rows.
  {
    auto w = demfem::io::CsvWriter::resume(path, 1);
    CHECK(w.rows() == 1);
    w.row({5.0, 6.0});
  }
  CHECK(demfem::io::read_csv_rows(path) == std::vector<std::string>{"0,1", "5,6"});
  std::filesystem::remove(path);
}
