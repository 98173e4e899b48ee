#include <catch2/catch.hpp>

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "demfem/io/atomic_file.hpp"
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

TEST_CASE("a full disk is reported with the system's reason, not as a corrupt file", "[io]") {
  // Issue 19, defect 9: a full disk said "cannot open (not an HDF5 file)". /dev/full refuses
  // every write with ENOSPC, as a full file system does.
  try {
    H5File f("/dev/full", H5File::Mode::create);
    std::vector<double> v(100000, 1.0);
    f.write("x", v);
    f.close();
    FAIL("writing to /dev/full did not fail");
  } catch (const H5Error& e) {
    CHECK_THAT(e.what(), Catch::Contains("/dev/full") &&
                             Catch::Contains("No space left on device") &&
                             Catch::Contains("free space"));
  }
  // A missing folder says so.
  CHECK_THROWS_WITH(H5File("/nonexistent-demfem/x.h5", H5File::Mode::create),
                    Catch::Contains("cannot create: No such file or directory"));
  // A file that is not HDF5 is still called that.
  const auto text = std::filesystem::temp_directory_path() / "demfem_test_not_h5.h5";
  std::ofstream(text) << "not hdf5";
  CHECK_THROWS_WITH(H5File(text, H5File::Mode::read), Catch::Contains("not an HDF5 file"));
  std::filesystem::remove(text);
}

TEST_CASE("a write cut short by the file size limit fails at the write or the close, with errno",
          "[io]") {
  // The data of a dataset reaches the disk at H5Dwrite or when the file is closed: a failure
  // at either must be an error naming the reason (here EFBIG from RLIMIT_FSIZE, in a child
  // process), never a silently incomplete file.
  const auto path = std::filesystem::temp_directory_path() /
                    ("demfem_test_fsize_" + std::to_string(::getpid()) + ".h5");
  const pid_t pid = ::fork();
  REQUIRE(pid >= 0);
  if (pid == 0) {
    ::signal(SIGXFSZ, SIG_IGN);
    struct rlimit limit {};
    limit.rlim_cur = limit.rlim_max = 64 * 1024;
    ::setrlimit(RLIMIT_FSIZE, &limit);
    int code = 3;
    try {
      H5File f(path, H5File::Mode::create);
      std::vector<double> v(1 << 20, 1.0);  // 8 MiB
      f.write("x", v);
      f.close();
      code = 1;  // no error
    } catch (const H5Error& e) {
      code = std::string(e.what()).find("File too large") != std::string::npos ? 0 : 2;
    }
    ::_exit(code);
  }
  int status = 0;
  REQUIRE(::waitpid(pid, &status, 0) == pid);
  REQUIRE(WIFEXITED(status));
  CHECK(WEXITSTATUS(status) == 0);  // 1: no error, 2: an error without the reason
  std::filesystem::remove(path);
}

TEST_CASE("a file whose close failed does not crash the process at exit", "[io]") {
  // Issue 19 (QA): on a full disk demfem_run printed its error and then died of SIGSEGV (exit
  // 139) in HDF5 1.10's exit handler, which closed the half-closed file again. The child ends
  // with std::exit, so that the library's exit handlers run (the test above uses _exit).
  const auto path = std::filesystem::temp_directory_path() /
                    ("demfem_test_close_" + std::to_string(::getpid()) + ".h5");
  const pid_t pid = ::fork();
  REQUIRE(pid >= 0);
  if (pid == 0) {
    ::signal(SIGXFSZ, SIG_IGN);
    struct rlimit limit {};
    limit.rlim_cur = limit.rlim_max = 4096;  // the data fits; the metadata at close does not
    ::setrlimit(RLIMIT_FSIZE, &limit);
    int code = 3;
    try {
      H5File f(path, H5File::Mode::create);
      const std::vector<double> values(100, 1.0);
      for (int k = 0; k < 50; ++k) f.write("/d" + std::to_string(k + 10), values);
      f.close();
      code = 1;  // no error: the limit did not bite, the test proves nothing
    } catch (const H5Error& e) {
      code = std::string(e.what()).find("File too large") != std::string::npos ? 0 : 2;
    }
    std::exit(code);
  }
  int status = 0;
  REQUIRE(::waitpid(pid, &status, 0) == pid);
  INFO("status " << status);
  REQUIRE_FALSE(WIFSIGNALED(status));  // SIGSEGV before the fix
  CHECK(WEXITSTATUS(status) == 0);
  std::filesystem::remove(path);
}

TEST_CASE("an atomic text file that cannot be written says why and leaves no part file", "[io]") {
  // Issue 19 (QA): run.json on a full disk said only "run.json.part: write failed".
  const auto dir =
      std::filesystem::temp_directory_path() / ("demfem_test_atomic_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const pid_t pid = ::fork();
  REQUIRE(pid >= 0);
  if (pid == 0) {
    ::signal(SIGXFSZ, SIG_IGN);
    struct rlimit limit {};
    limit.rlim_cur = limit.rlim_max = 100;
    ::setrlimit(RLIMIT_FSIZE, &limit);
    int code = 3;
    try {
      demfem::io::write_file_atomic(dir / "run.json", std::string(1000, 'x'));
      code = 1;
    } catch (const std::exception& e) {
      const std::string m = e.what();
      code = m.find("run.json.part: write failed: File too large; free space") != std::string::npos
                 ? 0
                 : 2;
    }
    ::_exit(code);
  }
  int status = 0;
  REQUIRE(::waitpid(pid, &status, 0) == pid);
  REQUIRE(WIFEXITED(status));
  CHECK(WEXITSTATUS(status) == 0);
  CHECK_FALSE(std::filesystem::exists(dir / "run.json.part"));
  CHECK_FALSE(std::filesystem::exists(dir / "run.json"));
  std::filesystem::remove_all(dir);
}
