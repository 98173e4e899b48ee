#include "demfem/coupling/progress.hpp"

#include <cmath>

namespace demfem::coupling {

Progress::Progress(std::FILE* out, bool terminal, bool quiet)
    : out_(out), terminal_(terminal), quiet_(quiet), start_(Clock::now()), last_print_(start_) {}

std::string Progress::line(std::int64_t step, std::int64_t total, double time, double end_time,
                           double elapsed_s) {
  const double done = total > 0 ? static_cast<double>(step + 1) / static_cast<double>(total) : 1.0;
  const double rate = elapsed_s > 0 ? static_cast<double>(step + 1) / elapsed_s : 0.0;
  const double eta = rate > 0 ? static_cast<double>(total - step - 1) / rate : 0.0;
  const long e = std::lround(eta);
  char text[200];
  std::snprintf(text, sizeof(text),
                "t = %.6g s / %.6g s (%5.1f %%), %.4g steps/s, ETA %ld:%02ld:%02ld", time, end_time,
                100.0 * done, rate, e / 3600, (e / 60) % 60, e % 60);
  return text;
}

void Progress::update(std::int64_t step, std::int64_t total, double time, double end_time) {
  if (quiet_) return;
  const auto now = Clock::now();
  const double elapsed = std::chrono::duration<double>(now - start_).count();
  const bool last = step + 1 >= total;
  if (terminal_) {
    // At most ten updates a second: a terminal that redraws every step costs real time.
    if (!last && now - last_print_ < std::chrono::milliseconds(100)) return;
    std::fprintf(out_, "\r\033[K%s", line(step, total, time, end_time, elapsed).c_str());
    std::fflush(out_);
    line_open_ = true;
  } else {
    const int decile = total > 0 ? static_cast<int>(10 * (step + 1) / total) : 10;
    if (decile == last_decile_ && !last && now - last_print_ < std::chrono::seconds(30)) return;
    last_decile_ = decile;
    std::fprintf(out_, "progress: %s\n", line(step, total, time, end_time, elapsed).c_str());
    std::fflush(out_);
  }
  last_print_ = now;
}

void Progress::finish() {
  if (line_open_) {
    std::fprintf(out_, "\n");
    std::fflush(out_);
    line_open_ = false;
  }
}

}  // namespace demfem::coupling
