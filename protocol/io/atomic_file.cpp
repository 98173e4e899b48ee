#include "demfem/io/atomic_file.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <stdexcept>
#include <string>

namespace demfem::io {

std::filesystem::path partial_path(const std::filesystem::path& final_path) {
  return final_path.string() + ".part";
}

void commit_partial(const std::filesystem::path& final_path) {
  const auto part = partial_path(final_path);
  const int fd = ::open(part.c_str(), O_RDONLY);
  if (fd < 0) throw std::runtime_error(part.string() + ": cannot open to commit");
  ::fsync(fd);
  ::close(fd);
  if (std::rename(part.c_str(), final_path.c_str()) != 0) {
    throw std::runtime_error(part.string() + ": cannot rename to " + final_path.string());
  }
}

void write_file_atomic(const std::filesystem::path& final_path, const std::string& text) {
  {
    std::ofstream out(partial_path(final_path), std::ios::trunc | std::ios::binary);
    if (!out) throw std::runtime_error(partial_path(final_path).string() + ": cannot create");
    out << text;
    if (!out.flush()) throw std::runtime_error(partial_path(final_path).string() + ": write failed");
  }
  commit_partial(final_path);
}

}  // namespace demfem::io
