#include "demfem/io/atomic_file.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <string>

namespace demfem::io {

namespace {

// "<path>: <what>: <the system's reason>", with what to do for a full disk or a folder that
// cannot be written (issue 19: a full disk said only "write failed").
[[noreturn]] void fail(const std::filesystem::path& path, const std::string& what, int err) {
  std::string hint;
  if (err == ENOSPC || err == EDQUOT || err == EFBIG) {
    hint = "; free space (or choose another output folder) and run again";
  } else if (err == EACCES || err == EPERM || err == EROFS) {
    hint = "; the folder is not writable";
  }
  throw std::runtime_error(path.string() + ": " + what + ": " + std::strerror(err) + hint);
}

}  // namespace

std::filesystem::path partial_path(const std::filesystem::path& final_path) {
  return final_path.string() + ".part";
}

void commit_partial(const std::filesystem::path& final_path) {
  const auto part = partial_path(final_path);
  const int fd = ::open(part.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) fail(part, "cannot open to commit", errno);
  // A file system that allocates late (NFS, delayed allocation) reports a full disk here.
  if (::fsync(fd) != 0 && errno != EINVAL && errno != EROFS) {
    const int err = errno;
    ::close(fd);
    fail(part, "cannot write to the disk", err);
  }
  ::close(fd);
  if (std::rename(part.c_str(), final_path.c_str()) != 0) {
    fail(part, "cannot rename to " + final_path.string(), errno);
  }
}

void write_file_atomic(const std::filesystem::path& final_path, const std::string& text) {
  const auto part = partial_path(final_path);
  const int fd = ::open(part.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) fail(part, "cannot create", errno);
  std::size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int err = n < 0 ? errno : EIO;
      ::close(fd);
      ::unlink(part.c_str());  // never leave a half-written file behind
      fail(part, "write failed", err);
    }
    done += static_cast<std::size_t>(n);
  }
  if (::close(fd) != 0) {
    const int err = errno;
    ::unlink(part.c_str());
    fail(part, "write failed", err);
  }
  commit_partial(final_path);
}

}  // namespace demfem::io
