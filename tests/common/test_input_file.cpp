// io::read_regular_file: every way a path can fail to be a usable input file gives a message
// naming the file, what it is and what was expected, before a byte is read; the size limit
// holds for files that report their size and for those (FIFOs, /proc) that do not.
#include <catch2/catch.hpp>

#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <string>

#include "demfem/io/input_file.hpp"
#include "demfem_test/error_of.hpp"
#include "demfem_test/temp_dir.hpp"

using Catch::Contains;
using demfem::io::InputFileError;
using demfem::io::read_regular_file;

namespace {

std::string error_of(const std::filesystem::path& p, std::uint64_t limit = 1 << 20) {
  return demfem::test::error_of<InputFileError>([&] { read_regular_file(p, limit, "a test file"); },
                                                "no error");
}

}  // namespace

TEST_CASE("read_regular_file reads a regular file whole", "[io]") {
  demfem::test::TempDir dir;
  const std::string text = "line 1\nline 2\n\0binary\xff";
  std::ofstream(dir / "a.txt", std::ios::binary) << text;
  CHECK(read_regular_file(dir / "a.txt", 1 << 20, "x") == text);
  std::ofstream(dir / "empty.txt").close();
  CHECK(read_regular_file(dir / "empty.txt", 1 << 20, "x").empty());
  // Exactly at the limit is accepted, one byte more is not.
  std::ofstream(dir / "ten.txt") << "0123456789";
  CHECK(read_regular_file(dir / "ten.txt", 10, "x") == "0123456789");
  CHECK_THAT(error_of(dir / "ten.txt", 9),
             Contains("ten.txt: is 10 bytes, more than the limit of 9 bytes for a test file"));
}

TEST_CASE("read_regular_file refuses what is not a regular file, naming it", "[io]") {
  demfem::test::TempDir dir;
  CHECK_THAT(error_of(dir / "missing.txt"),
             Contains("missing.txt: cannot open: no such file; expected a test file"));
  CHECK_THAT(error_of(dir.path),
             Contains(dir.path.string() + ": is a directory, not a regular file; expected a "
                                          "test file"));
  // Devices: /dev/zero would otherwise be read until memory runs out.
  CHECK_THAT(error_of("/dev/zero"),
             Contains("/dev/zero: is a character device, not a regular file; expected a test "
                      "file"));
  CHECK_THAT(error_of("/dev/null"), Contains("character device"));
  // A FIFO without a writer: refused at once instead of blocking in open().
  const auto fifo = dir / "pipe";
  REQUIRE(::mkfifo(fifo.c_str(), 0600) == 0);
  const auto t0 = std::chrono::steady_clock::now();
  CHECK_THAT(error_of(fifo), Contains("pipe: is a FIFO (named pipe), not a regular file"));
  CHECK(std::chrono::steady_clock::now() - t0 < std::chrono::seconds(5));
  CHECK_THAT(error_of(""), Contains("empty file name"));
  CHECK_THAT(error_of(dir / "missing.txt" / "below"), Contains("cannot open"));
}

TEST_CASE("read_regular_file reports an unreadable file", "[io]") {
  if (::geteuid() == 0) {
    WARN("skipped: running as root, file permissions do not apply");
    return;
  }
  demfem::test::TempDir dir;
  std::ofstream(dir / "secret.txt") << "x";
  std::filesystem::permissions(dir / "secret.txt", std::filesystem::perms::none);
  CHECK_THAT(error_of(dir / "secret.txt"),
             Contains("secret.txt: cannot open: permission denied; expected a test file"));
}

TEST_CASE("read_regular_file bounds files whose size is not known upfront", "[io]") {
  // /proc files report size 0 and are read until EOF; the limit still applies.
  const std::string status = read_regular_file("/proc/self/status", 1 << 20, "x");
  CHECK(status.find("Name:") != std::string::npos);
  CHECK_THAT(error_of("/proc/self/status", 16),
             Contains("holds more than the limit of 16 bytes for a test file"));
  CHECK(demfem::io::describe_size(demfem::io::kSceneFileLimit) == "16 MiB");
  CHECK(demfem::io::describe_size(demfem::io::kMeshFileLimit) == "1 GiB");
}
