#pragma once
// Starting demfem_run (or any program) as a child process in a folder of its own, with its
// stdout and stderr in files there, for tests that signal or kill it while it runs.

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cerrno>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "demfem_test/temp_dir.hpp"

extern char** environ;

namespace demfem::test {

struct Launched {
  pid_t pid = -1;
  std::filesystem::path dir;  ///< working folder; stdout.txt and stderr.txt are here
};

struct Ended {
  int status = -1;  ///< exit code, or 128 + signal
  std::string out, err;
};

/// Starts `argv` in `dir` (relative paths of the program land there); in a process group of
/// its own when `group` (so that a test can signal the group, as Ctrl-C on a terminal does).
inline Launched launch(const std::filesystem::path& dir, std::vector<std::string> argv_s,
                       bool group = false) {
  std::vector<char*> argv;
  for (auto& a : argv_s) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  const std::string out = (dir / "stdout.txt").string(), err = (dir / "stderr.txt").string();
  posix_spawn_file_actions_addopen(&fa, 1, out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_addopen(&fa, 2, err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawnattr_t attr;
  posix_spawnattr_init(&attr);
  if (group) {
    posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETPGROUP);
    posix_spawnattr_setpgroup(&attr, 0);
  }
  const auto old = std::filesystem::current_path();
  std::filesystem::current_path(dir);  // the child inherits it
  pid_t pid = -1;
  const int rc = posix_spawn(&pid, argv[0], &fa, &attr, argv.data(), environ);
  std::filesystem::current_path(old);
  posix_spawn_file_actions_destroy(&fa);
  posix_spawnattr_destroy(&attr);
  if (rc != 0) throw std::runtime_error("cannot start " + argv_s[0]);
  return {pid, dir};
}

/// Waits for the process and reads its output.
inline Ended wait_for(const Launched& l) {
  int st = 0;
  if (waitpid(l.pid, &st, 0) != l.pid) throw std::runtime_error("waitpid failed");
  Ended e;
  e.status = WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
  e.out = read_text(l.dir / "stdout.txt");
  e.err = read_text(l.dir / "stderr.txt");
  return e;
}

/// True once `pid` has ended: it no longer exists, or it is a zombie (ended, not yet reaped
/// by its parent; an orphan's new parent, init, may take seconds to reap it).
inline bool gone(pid_t pid) {
  if (::kill(pid, 0) != 0) return errno == ESRCH;
  std::ifstream stat("/proc/" + std::to_string(pid) + "/stat");
  std::string line;
  if (!std::getline(stat, line)) return true;
  const auto paren = line.rfind(')');
  return paren != std::string::npos && paren + 2 < line.size() &&
         (line[paren + 2] == 'Z' || line[paren + 2] == 'X');
}

/// Polls `ready` every 10 ms for at most `limit`; returns whether it became true.
template <class F>
bool eventually(F&& ready, std::chrono::milliseconds limit) {
  const auto end = std::chrono::steady_clock::now() + limit;
  while (!ready()) {
    if (std::chrono::steady_clock::now() > end) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return true;
}

}  // namespace demfem::test
