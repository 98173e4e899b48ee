#include "demfem/io/input_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <cerrno>
#include <cstring>

namespace demfem::io {

namespace {

std::string kind_of(mode_t mode) {
  if (S_ISDIR(mode)) return "a directory";
  if (S_ISFIFO(mode)) return "a FIFO (named pipe)";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISSOCK(mode)) return "a socket";
  return "not a regular file";
}

/// Closes the descriptor on every path out of read_regular_file.
struct Fd {
  int fd = -1;
  ~Fd() {
    if (fd >= 0) ::close(fd);
  }
};

}  // namespace

std::string describe_size(std::uint64_t bytes) {
  if (bytes >= (std::uint64_t{1} << 30) && bytes % (std::uint64_t{1} << 30) == 0)
    return std::to_string(bytes >> 30) + " GiB";
  if (bytes >= (std::uint64_t{1} << 20) && bytes % (std::uint64_t{1} << 20) == 0)
    return std::to_string(bytes >> 20) + " MiB";
  return std::to_string(bytes) + " bytes";
}

std::string read_regular_file(const std::filesystem::path& path, std::uint64_t max_bytes,
                              std::string_view what) {
  const std::string name = path.string();
  auto fail = [&](const std::string& problem) -> InputFileError {
    return InputFileError(name + ": " + problem + "; expected " + std::string(what));
  };
  if (name.empty()) throw InputFileError("empty file name; expected " + std::string(what));
  Fd f;
  // O_NONBLOCK: opening a FIFO for reading would otherwise wait for a writer.
  f.fd = ::open(path.c_str(), O_RDONLY | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (f.fd < 0) {
    const int e = errno;
    if (e == ENOENT) throw fail("cannot open: no such file");
    if (e == EACCES) throw fail("cannot open: permission denied");
    if (e == ENOTDIR) throw fail("cannot open: a component of the path is not a directory");
    throw fail(std::string("cannot open: ") + std::strerror(e));
  }
  struct stat st {};
  if (::fstat(f.fd, &st) != 0) throw fail(std::string("cannot stat: ") + std::strerror(errno));
  if (!S_ISREG(st.st_mode)) throw fail("is " + kind_of(st.st_mode) + ", not a regular file");
  const auto size = static_cast<std::uint64_t>(st.st_size);
  const std::string limit =
      "the limit of " + describe_size(max_bytes) + " for " + std::string(what);
  if (size > max_bytes) {
    throw InputFileError(name + ": is " + std::to_string(size) + " bytes, more than " + limit);
  }
  // Back to blocking reads (regular files never block; this only keeps read() plain).
  ::fcntl(f.fd, F_SETFL, ::fcntl(f.fd, F_GETFL) & ~O_NONBLOCK);
  std::string out;
  // A file may grow while it is read, and /proc files report size 0: read until EOF, but
  // never past the limit.
  out.resize(static_cast<std::size_t>(size) + 1);
  std::size_t used = 0;
  for (;;) {
    if (used == out.size()) {
      if (used > max_bytes) break;
      out.resize(static_cast<std::size_t>(std::min<std::uint64_t>(max_bytes + 1, 2 * used + 4096)));
    }
    const ssize_t n = ::read(f.fd, out.data() + used, out.size() - used);
    if (n < 0) {
      if (errno == EINTR) continue;
      throw fail(std::string("cannot read: ") + std::strerror(errno));
    }
    if (n == 0) break;
    used += static_cast<std::size_t>(n);
    if (used > max_bytes) break;
  }
  if (used > max_bytes) {
    throw InputFileError(name + ": holds more than " + limit + " (it grew while being read)");
  }
  out.resize(used);
  return out;
}

}  // namespace demfem::io
