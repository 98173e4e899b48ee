#pragma once
// Shared by the test executables: a temporary folder that is removed with its contents when
// the test ends, and reading a whole file.

#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <system_error>

namespace demfem::test {

/// A fresh, empty folder under the system's temporary folder, unique per process and object.
struct TempDir {
  explicit TempDir(const std::string& tag = "test") : path(make_path(tag)) {
    std::filesystem::remove_all(path);
    std::filesystem::create_directories(path);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  std::filesystem::path operator/(const std::string& name) const { return path / name; }

  const std::filesystem::path path;

 private:
  static std::filesystem::path make_path(const std::string& tag) {
    static std::atomic<int> counter{0};
    return std::filesystem::temp_directory_path() /
           ("demfem_" + tag + "_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
  }
};

/// The whole content of a file ("" when it cannot be read).
inline std::string read_text(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

}  // namespace demfem::test
