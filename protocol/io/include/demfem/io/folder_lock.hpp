#pragma once
// An exclusive lock on an output folder, so that two runs never write the same files: flock()
// on <folder>/.demfem.lock, held for the lifetime of the object. The kernel drops the lock
// when the holding process ends in any way (exit, crash, SIGKILL), so a killed run never
// leaves a stale lock behind; the file itself stays (removing it would race with a process
// that has just opened it) and says who holds or last held the lock. The descriptor is
// close-on-exec: processes the holder starts (the solvers) do not hold the lock.

#include <sys/types.h>

#include <filesystem>
#include <stdexcept>
#include <string>

namespace demfem::io {

/// @brief The folder is locked by another process; what() names the folder and the holder.
class FolderBusy : public std::runtime_error {
 public:
  FolderBusy(const std::string& text, pid_t holder) : std::runtime_error(text), holder_(holder) {}
  /// The holder's pid as it wrote it in the lock file (0 when not known yet).
  pid_t holder() const { return holder_; }

 private:
  pid_t holder_;
};

/// @brief An exclusive flock() on <folder>/.demfem.lock.
class FolderLock {
 public:
  /// Name of the lock file inside the folder.
  static constexpr const char* kFileName = ".demfem.lock";

  FolderLock() = default;
  /// Creates `folder` (and its parents) if needed and takes the lock without waiting; writes
  /// "pid N", the host and `description` into the lock file. Throws FolderBusy when another
  /// process holds it, std::runtime_error naming the folder and the system's reason (e.g.
  /// "Permission denied", "No space left on device") when the folder or file cannot be
  /// created or written.
  FolderLock(const std::filesystem::path& folder, const std::string& description);
  ~FolderLock();
  FolderLock(FolderLock&& other) noexcept;
  FolderLock& operator=(FolderLock&& other) noexcept;
  FolderLock(const FolderLock&) = delete;
  FolderLock& operator=(const FolderLock&) = delete;

  bool held() const { return fd_ >= 0; }
  /// The lock still guards the folder: <folder>/.demfem.lock is the file this object locked.
  /// False once the file or the folder was removed or replaced (rm -rf of the folder while
  /// the run writes it): a new run there would take a lock of its own, and both would write
  /// the same files. A stat() of the path; call it now and then, not per message.
  bool intact() const;
  const std::filesystem::path& folder() const { return folder_; }
  /// Releases the lock (the destructor does too).
  void release();

 private:
  std::filesystem::path folder_;
  int fd_ = -1;
};

}  // namespace demfem::io
