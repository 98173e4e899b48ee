#include "demfem/io/file_hash.hpp"

#include <fstream>
#include <stdexcept>
#include <string>

namespace demfem::io {

namespace {
constexpr std::uint64_t kOffsetBasis = 14695981039346656037ULL;  // FNV-1a 64
std::uint64_t fnv1a64_continue(std::uint64_t h, const char* bytes, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) {
    h ^= static_cast<unsigned char>(bytes[i]);
    h *= 1099511628211ULL;  // FNV-1a 64 prime
  }
  return h;
}
}  // namespace

std::uint64_t fnv1a64(std::string_view bytes) {
  return fnv1a64_continue(kOffsetBasis, bytes.data(), bytes.size());
}

std::uint64_t fnv1a64_file(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw std::runtime_error(file.string() + ": cannot read");
  std::uint64_t h = kOffsetBasis;
  char buf[1 << 16];
  while (in) {
    in.read(buf, sizeof(buf));
    h = fnv1a64_continue(h, buf, static_cast<std::size_t>(in.gcount()));
  }
  if (in.bad()) throw std::runtime_error(file.string() + ": read error");
  return h;
}

}  // namespace demfem::io
