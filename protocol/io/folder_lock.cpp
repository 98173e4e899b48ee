#include "demfem/io/folder_lock.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>
#include <system_error>

namespace demfem::io {

namespace {

std::string reason(int err) {
  return std::strerror(err);
}

// The holder's pid from the lock file's "pid N" line (0 when absent or not yet written).
pid_t holder_pid(const std::string& text) {
  std::istringstream in(text);
  std::string key;
  long pid = 0;
  while (in >> key) {
    if (key == "pid" && (in >> pid)) return static_cast<pid_t>(pid);
  }
  return 0;
}

}  // namespace

FolderLock::FolderLock(const std::filesystem::path& folder, const std::string& description)
    : folder_(folder) {
  std::error_code ec;
  std::filesystem::create_directories(folder, ec);
  if (ec) {
    throw std::runtime_error(folder.string() +
                             ": cannot create the output folder: " + ec.message());
  }
  const auto file = folder / kFileName;
  const int fd = ::open(file.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) {
    const int err = errno;
    throw std::runtime_error(
        file.string() + ": cannot create the lock file: " + reason(err) +
        (err == EACCES || err == EROFS ? " (the folder is not writable)" : ""));
  }
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    const int err = errno;
    std::string text;
    if (err == EWOULDBLOCK) {
      char buf[1024];
      const ssize_t n = ::pread(fd, buf, sizeof(buf) - 1, 0);
      if (n > 0) text.assign(buf, static_cast<std::size_t>(n));
    }
    ::close(fd);
    if (err != EWOULDBLOCK) {
      throw std::runtime_error(file.string() + ": cannot lock: " + reason(err));
    }
    const pid_t pid = holder_pid(text);
    // The lock file's lines (pid, host, what the holder runs) on one line.
    std::string info;
    for (char c : text) info += c == '\n' ? "; " : std::string(1, c);
    while (info.size() >= 2 && info.compare(info.size() - 2, 2, "; ") == 0)
      info.resize(info.size() - 2);
    throw FolderBusy(folder.string() + " is in use by " +
                         (pid > 0 ? "process " + std::to_string(pid) : "another process") +
                         (info.empty() ? std::string() : " (" + info + ")"),
                     pid);
  }
  // Who holds it, for the message a second run gets.
  char host[256] = {};
  ::gethostname(host, sizeof(host) - 1);
  std::ostringstream info;
  info << "pid " << ::getpid() << "\nhost " << host << "\n" << description << "\n";
  const std::string s = info.str();
  if (::ftruncate(fd, 0) != 0 ||
      ::pwrite(fd, s.data(), s.size(), 0) != static_cast<ssize_t>(s.size())) {
    const int err = errno;
    ::close(fd);
    throw std::runtime_error(file.string() + ": cannot write the lock file: " + reason(err));
  }
  fd_ = fd;
}

bool FolderLock::intact() const {
  if (fd_ < 0) return false;
  struct stat locked {
  }, now{};
  if (::fstat(fd_, &locked) != 0) return false;
  if (::stat((folder_ / kFileName).c_str(), &now) != 0) return false;
  return locked.st_dev == now.st_dev && locked.st_ino == now.st_ino;
}

FolderLock::~FolderLock() {
  release();
}

FolderLock::FolderLock(FolderLock&& other) noexcept
    : folder_(std::move(other.folder_)), fd_(other.fd_) {
  other.fd_ = -1;
}

FolderLock& FolderLock::operator=(FolderLock&& other) noexcept {
  if (this != &other) {
    release();
    folder_ = std::move(other.folder_);
    fd_ = other.fd_;
    other.fd_ = -1;
  }
  return *this;
}

void FolderLock::release() {
  if (fd_ >= 0) {
    ::flock(fd_, LOCK_UN);
    ::close(fd_);
    fd_ = -1;
  }
}

}  // namespace demfem::io
