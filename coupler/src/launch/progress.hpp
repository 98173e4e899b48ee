#pragma once
// Progress of a run: simulated time, coupling steps per second and ETA; one line updated in
// place on a terminal, plain log lines (every 10 % or 30 s) otherwise.

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <string>

namespace demfem::coupling {

struct RunSummary;

/// @brief The run's wall times on stdout: this session's shares, and for a resumed run the
/// whole run's (earlier sessions from the checkpoint, plus this one). `remote`: solver
/// processes (their times include the IPC round trip).
void print_timing(const RunSummary& summary, bool remote);
/// @brief timing.csv in `dir` (steps, time, wall times, coupling share), written atomically.
void write_timing(const std::filesystem::path& dir, const RunSummary& summary);

/// @brief Prints progress of a run to a stream.
class Progress {
 public:
  /// `terminal`: update one line in place; otherwise log lines. `quiet`: print nothing.
  Progress(std::FILE* out, bool terminal, bool quiet);
  /// After coupling step `step` (0-based) of `total`, at simulated time `time` of `end_time`.
  void update(std::int64_t step, std::int64_t total, double time, double end_time);
  /// Ends the in-place line.
  void finish();
  /// "t = 0.012 s / 0.1 s (12.0 %), 1234 steps/s, ETA 0:00:07". `first_step`: the first step
  /// of this session (a resumed run starts at its checkpoint's step), whose steps since, over
  /// `elapsed_s`, give the rate; the steps before it ran in earlier sessions.
  static std::string line(std::int64_t step, std::int64_t total, double time, double end_time,
                          double elapsed_s, std::int64_t first_step = 0);

 private:
  using Clock = std::chrono::steady_clock;
  std::FILE* out_;
  bool terminal_;
  bool quiet_;
  Clock::time_point start_;
  Clock::time_point last_print_;
  int last_decile_ = 0;
  std::int64_t first_step_ = -1;  ///< the step of the first update (-1: none yet)
  bool line_open_ = false;
};

}  // namespace demfem::coupling
