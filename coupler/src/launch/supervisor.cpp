#include "launch/supervisor.hpp"

#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <csignal>
#include <cstring>
#include <stdexcept>
#include <thread>

extern char** environ;

namespace demfem::coupling {

namespace {

// Pids to forward signals to. Lock-free atomics so that the handler may read them.
constexpr int kMaxChildren = 8;
std::array<std::atomic<pid_t>, kMaxChildren> g_children{};
std::atomic<bool> g_stop{false};
std::atomic<int> g_signal{0};
std::atomic<int> g_checkpoint_request{0};
std::atomic<bool> g_forward{true};  // false once the solvers were told Shutdown
static_assert(std::atomic<pid_t>::is_always_lock_free);

void on_signal(int sig) {
  g_signal.store(sig);
  g_stop.store(true);
  if (!g_forward.load()) return;
  for (auto& c : g_children) {
    const pid_t p = c.load();
    if (p > 0) ::kill(p, SIGTERM);
  }
}

// SIGPIPE too: `demfem run ... | head` closes our output; stop cleanly like Ctrl-C instead
// of dying at once and leaving the solvers to notice the lost coupler.
constexpr int kSignals[] = {SIGINT, SIGTERM, SIGHUP, SIGPIPE};
constexpr int kSignalCount = static_cast<int>(std::size(kSignals));
struct sigaction g_old[kSignalCount];

// A long run asked for a checkpoint (SIGUSR1) or for a checkpoint and a stop (SIGUSR2): a
// Slurm job near its time limit (`#SBATCH --signal=B:USR2@120`), a user who needs the machine.
void on_checkpoint_signal(int sig) {
  g_checkpoint_request.store(sig);
}
constexpr int kCheckpointSignals[] = {SIGUSR1, SIGUSR2};
struct sigaction g_old_checkpoint[std::size(kCheckpointSignals)];

void install(int sig, void (*handler)(int), int flags, struct sigaction* old) {
  struct sigaction sa {};
  sa.sa_handler = handler;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = flags;
  ::sigaction(sig, &sa, old);
}

}  // namespace

SolverProcess::SolverProcess(std::string label, std::filesystem::path executable,
                             std::vector<std::string> arguments)
    : label_(std::move(label)),
      executable_(std::move(executable)),
      arguments_(std::move(arguments)) {}

SolverProcess::~SolverProcess() {
  if (pid_ > 0 && !exit_code_) stop(std::chrono::milliseconds(2000));
  if (slot_ >= 0) g_children[slot_].store(0);
}

void SolverProcess::set_environment(const std::string& name, const std::string& value) {
  for (auto& [n, v] : environment_) {
    if (n == name) {
      v = value;
      return;
    }
  }
  environment_.emplace_back(name, value);
}

void SolverProcess::add_argument(const std::string& argument) {
  if (std::find(arguments_.begin(), arguments_.end(), argument) == arguments_.end()) {
    arguments_.push_back(argument);
  }
}

pid_t SolverProcess::start() {
  if (::access(executable_.c_str(), X_OK) != 0) {
    throw std::runtime_error("cannot start the " + label_ + ": " + executable_.string() +
                             " is missing or not executable (build it, or pass --bin-dir)");
  }
  std::vector<std::string> argv_store;
  argv_store.push_back(executable_.string());
  argv_store.insert(argv_store.end(), arguments_.begin(), arguments_.end());
  std::vector<char*> argv;
  for (auto& a : argv_store) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid = -1;
  posix_spawnattr_t attr;
  ::posix_spawnattr_init(&attr);
  if (own_session_) ::posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETSID);
  posix_spawn_file_actions_t actions;
  ::posix_spawn_file_actions_init(&actions);
  if (!working_directory_.empty())
    ::posix_spawn_file_actions_addchdir_np(&actions, working_directory_.c_str());
  // The environment: this process's, with the variables set_environment() gave replaced.
  std::vector<std::string> env_store;
  for (char** e = environ; e && *e; ++e) {
    const std::string entry = *e;
    const std::string name = entry.substr(0, entry.find('='));
    bool replaced = false;
    for (const auto& [n, v] : environment_) replaced = replaced || n == name;
    if (!replaced) env_store.push_back(entry);
  }
  for (const auto& [n, v] : environment_) env_store.push_back(n + "=" + v);
  std::vector<char*> envp;
  for (auto& e : env_store) envp.push_back(e.data());
  envp.push_back(nullptr);
  const int rc = ::posix_spawn(&pid, executable_.c_str(), &actions, &attr, argv.data(), envp.data());
  ::posix_spawn_file_actions_destroy(&actions);
  ::posix_spawnattr_destroy(&attr);
  if (rc != 0) {
    throw std::runtime_error("cannot start the " + label_ + " (" + executable_.string() +
                             "): " + std::strerror(rc));
  }
  pid_ = pid;
  exit_code_.reset();
  if (slot_ >= 0) g_children[slot_].store(0);  // a restart: the old process is gone
  slot_ = -1;
  for (int i = 0; i < kMaxChildren; ++i) {
    pid_t expected = 0;
    if (g_children[i].compare_exchange_strong(expected, pid)) {
      slot_ = i;
      break;
    }
  }
  return pid;
}

std::string SolverProcess::command_text() const {
  std::string text = executable_.string();
  for (const auto& a : arguments_) text += " " + a;
  return text;
}

void SolverProcess::reaped(int status) {
  exit_code_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  if (slot_ >= 0) {
    g_children[slot_].store(0);
    slot_ = -1;
  }
  if (after_end_) after_end_();
}

bool SolverProcess::running() {
  if (pid_ <= 0 || exit_code_) return false;
  int status = 0;
  const pid_t r = ::waitpid(pid_, &status, WNOHANG);
  if (r == pid_) {
    reaped(status);
    return false;
  }
  return r == 0;
}

void SolverProcess::signal(int sig) {
  if (running()) ::kill(pid_, sig);
}

std::optional<int> SolverProcess::wait_for(std::chrono::milliseconds timeout) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (running()) {
    if (std::chrono::steady_clock::now() >= end) return std::nullopt;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return exit_code_;
}

int SolverProcess::stop(std::chrono::milliseconds grace) {
  // Never started (its executable could not be spawned): nothing to wait for. waitpid(-1)
  // below would wait for any child, i.e. for the other solver, which waits for us: a hang.
  if (pid_ <= 0) return exit_code_.value_or(-1);
  if (auto c = wait_for(grace)) return *c;
  signal(SIGTERM);
  if (auto c = wait_for(grace)) return *c;
  signal(SIGKILL);
  int status = 0;
  if (::waitpid(pid_, &status, 0) == pid_) reaped(status);
  return exit_code_.value_or(128 + SIGKILL);
}

SignalGuard::SignalGuard(Scope scope) : scope_(scope) {
  g_stop.store(false);
  g_signal.store(0);
  g_forward.store(true);
  // No SA_RESTART for a stop: blocking calls return early with EINTR. A checkpoint request
  // interrupts nothing.
  for (int i = 0; i < kSignalCount; ++i) install(kSignals[i], on_signal, 0, &g_old[i]);
  g_checkpoint_request.store(0);
  for (std::size_t i = 0; i < std::size(kCheckpointSignals); ++i)
    install(kCheckpointSignals[i], on_checkpoint_signal, SA_RESTART, &g_old_checkpoint[i]);
}

SignalGuard::~SignalGuard() {
  if (scope_ == Scope::process) return;  // a late signal only sets the flag
  for (int i = 0; i < kSignalCount; ++i) ::sigaction(kSignals[i], &g_old[i], nullptr);
  for (std::size_t i = 0; i < std::size(kCheckpointSignals); ++i)
    ::sigaction(kCheckpointSignals[i], &g_old_checkpoint[i], nullptr);
}

const std::atomic<bool>& SignalGuard::stop_flag() {
  return g_stop;
}
int SignalGuard::signal_number() {
  return g_signal.load();
}
int SignalGuard::take_checkpoint_request() {
  return g_checkpoint_request.exchange(0);
}
void SignalGuard::request_stop(int sig) {
  on_signal(sig);
}
void SignalGuard::solvers_ending() {
  g_forward.store(false);
}

}  // namespace demfem::coupling
