#pragma once
// Child solver processes of a run and the coupler's signal handling. The launcher starts
// each solver as a SolverProcess (posix_spawn), watches it, and on SIGINT/SIGTERM/SIGHUP/SIGPIPE
// sets the stop flag and forwards SIGTERM to every live child so that all three processes
// end cleanly. A SolverProcess keeps its executable and arguments so that a crashed solver
// can be started again (from a checkpoint, a later addition) with the same command line.

#include <atomic>
#include <chrono>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <sys/types.h>

namespace demfem::coupling {

/// @brief One child solver process.
class SolverProcess {
 public:
  SolverProcess(std::string label, std::filesystem::path executable,
                std::vector<std::string> arguments);
  ~SolverProcess();
  SolverProcess(const SolverProcess&) = delete;
  SolverProcess& operator=(const SolverProcess&) = delete;

  /// Starts the process (throws std::runtime_error naming the executable on failure) and
  /// registers it for signal forwarding.
  pid_t start();
  pid_t pid() const { return pid_; }
  /// Adds an argument for the next start() (e.g. --resume for a restarted solver), once.
  void add_argument(const std::string& argument);
  /// Start the process in a session of its own (setsid; demfem_run --solver-sessions). Under
  /// Linux's autogroup scheduling (sched_autogroup_enabled = 1, the default of desktop
  /// kernels) the processes of one session share one CPU share against other sessions: two
  /// solvers in the launcher's session then get one core between them as soon as another
  /// session keeps the CPUs busy, which the concurrent scheme cannot afford. In a session of
  /// its own each gets its share. The process then no longer receives the terminal's signals
  /// or a signal to the launcher's process group: the launcher forwards SIGTERM, and a
  /// solver whose launcher is gone leaves by itself (docs/reliability.md).
  void set_own_session(bool own) { own_session_ = own; }
  /// Sets an environment variable of the process (on top of the launcher's own environment),
  /// for this and every later start().
  void set_environment(const std::string& name, const std::string& value);
  /// The folder the process starts in (empty, the default: the launcher's own).
  void set_working_directory(std::filesystem::path dir) { working_directory_ = std::move(dir); }
  const std::filesystem::path& executable() const { return executable_; }
  /// The command line, for messages: "python3 backend.py --scene ...".
  std::string command_text() const;
  const std::string& label() const { return label_; }
  /// True while the process runs (reaps it when it has ended).
  bool running();
  /// Sends `sig` when running.
  void signal(int sig);
  /// Waits up to `timeout` for the process to end; returns its exit code (128 + signal
  /// number when a signal ended it), or nullopt while it still runs.
  std::optional<int> wait_for(std::chrono::milliseconds timeout);
  /// Waits up to `grace`, then SIGTERM, another `grace`, then SIGKILL. Returns the exit code.
  int stop(std::chrono::milliseconds grace);
  /// Exit code once ended.
  std::optional<int> exit_code() const { return exit_code_; }
  /// Called each time the process has ended and been reaped (on every path: a crash seen by
  /// running(), stop(), the destructor), e.g. to remove what its job left behind.
  void set_after_end(std::function<void()> hook) { after_end_ = std::move(hook); }

 private:
  void reaped(int status);
  std::string label_;
  std::filesystem::path executable_;
  std::vector<std::string> arguments_;
  std::filesystem::path working_directory_;
  std::vector<std::pair<std::string, std::string>> environment_;
  pid_t pid_ = -1;
  int slot_ = -1;
  bool own_session_ = false;
  std::optional<int> exit_code_;
  std::function<void()> after_end_;
};

/// @brief Process-wide stop request from SIGINT/SIGTERM/SIGHUP/SIGPIPE.
class SignalGuard {
 public:
  /// How long the handlers stay: until the destructor restores the previous ones, or, for
  /// the launcher's run, until the process exits. A stop signal after the run record said
  /// "completed" then changes nothing; restored handlers let it kill the finished process
  /// on its way out (exit 130 after "completed": a sweep counted the run as stopped).
  enum class Scope { guard, process };
  /// Installs the handlers.
  explicit SignalGuard(Scope scope = Scope::guard);
  ~SignalGuard();
  SignalGuard(const SignalGuard&) = delete;
  SignalGuard& operator=(const SignalGuard&) = delete;

  /// Set by the handler; the run loop polls it between steps.
  static const std::atomic<bool>& stop_flag();
  /// The signal that set it (0 = none).
  static int signal_number();

  /// A checkpoint request: SIGUSR1 (take a checkpoint at the next coupling-step boundary and
  /// go on) or SIGUSR2 (take it, then stop as for SIGTERM); 0 = none. Taking it clears it.
  /// These signals are not forwarded to the solvers, which ignore them (protocol serve()).
  static int take_checkpoint_request();
  /// Stops the run as the stop signal `sig` would: sets the flag, SIGTERM to the children.
  static void request_stop(int sig);
  /// The solvers were told Shutdown and write their end state: a stop signal from now on
  /// sets the flag but sends them no SIGTERM (they exit on their own; the coupler's bounded
  /// wait ends a hung one). A Ctrl-C as a run ends cut the end state short and turned the
  /// finished run into a failed one (and left a series a resume refused).
  static void solvers_ending();

 private:
  Scope scope_;
};

}  // namespace demfem::coupling
