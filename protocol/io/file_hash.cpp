#include "demfem/io/file_hash.hpp"

#include <fstream>
#include <stdexcept>
#include <string>

namespace demfem::io {

std::uint64_t fnv1a64_file(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw std::runtime_error(file.string() + ": cannot read");
  std::uint64_t h = 14695981039346656037ULL;  // FNV-1a 64 offset basis
  char buf[1 << 16];
  while (in) {
    in.read(buf, sizeof(buf));
    const std::streamsize n = in.gcount();
    for (std::streamsize i = 0; i < n; ++i) {
      h ^= static_cast<unsigned char>(buf[i]);
      h *= 1099511628211ULL;
    }
  }
  if (in.bad()) throw std::runtime_error(file.string() + ": read error");
  return h;
}

}  // namespace demfem::io
