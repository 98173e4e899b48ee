#include "launch/progress.hpp"

#include <cmath>

#include "demfem/coupling/coupling_run.hpp"
#include "demfem/io/atomic_file.hpp"

namespace demfem::coupling {

Progress::Progress(std::FILE* out, bool terminal, bool quiet)
    : out_(out), terminal_(terminal), quiet_(quiet), start_(Clock::now()), last_print_(start_) {}

std::string Progress::line(std::int64_t step, std::int64_t total, double time, double end_time,
                           double elapsed_s, std::int64_t first_step) {
  const double done = total > 0 ? static_cast<double>(step + 1) / static_cast<double>(total) : 1.0;
  const double rate = elapsed_s > 0 ? static_cast<double>(step + 1 - first_step) / elapsed_s : 0.0;
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
  if (first_step_ < 0) first_step_ = step;
  const double elapsed = std::chrono::duration<double>(now - start_).count();
  const bool last = step + 1 >= total;
  if (terminal_) {
    // At most ten updates a second: a terminal that redraws every step costs real time.
    if (!last && now - last_print_ < std::chrono::milliseconds(100)) return;
    std::fprintf(out_, "\r\033[K%s",
                 line(step, total, time, end_time, elapsed, first_step_).c_str());
    std::fflush(out_);
    line_open_ = true;
  } else {
    const int decile = total > 0 ? static_cast<int>(10 * (step + 1) / total) : 10;
    if (decile == last_decile_ && !last && now - last_print_ < std::chrono::seconds(30)) return;
    last_decile_ = decile;
    std::fprintf(out_, "progress: %s\n",
                 line(step, total, time, end_time, elapsed, first_step_).c_str());
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

// Shares are of the same wall time: this session's parts of this session's total, and for a
// resumed run the whole run's parts (earlier sessions from the checkpoint, plus this one) of
// the whole run's total.
void print_timing(const RunSummary& s, bool remote) {
  auto line = [](const char* what, const WallTimes& w, const char* tail) {
    const double total = w.total > 0 ? w.total : 1.0;
    std::printf(
        "%s: total %.3f s; DEM %.3f s (%.1f %%), FEM %.3f s (%.1f %%), coupling %.4f s "
        "(%.2f %%)%s\n",
        what, w.total, w.dem, 100 * w.dem / total, w.fem, 100 * w.fem / total, w.coupling,
        100 * w.coupling / total, tail);
  };
  const WallTimes session{s.wall_total, s.wall_dem, s.wall_fem, s.wall_coupling};
  const char* ipc = remote ? "; DEM/FEM times include the IPC round trip" : "";
  if (s.earlier.total <= 0.0) {
    line("wall time", session, ipc);
    return;
  }
  line("wall time of this session", session, ipc);
  const WallTimes whole{s.earlier.total + s.wall_total, s.earlier.dem + s.wall_dem,
                        s.earlier.fem + s.wall_fem, s.earlier.coupling + s.wall_coupling};
  line("wall time of the whole run (earlier sessions up to the checkpoint, and this one)", whole,
       "");
}

void write_timing(const std::filesystem::path& dir, const RunSummary& s) {
  char text[512];
  std::snprintf(text, sizeof(text),
                "steps,time,wall_total,wall_dem,wall_fem,wall_coupling,coupling_share\n"
                "%lld,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g\n",
                static_cast<long long>(s.steps), s.time, s.wall_total, s.wall_dem, s.wall_fem,
                s.wall_coupling, s.wall_total > 0 ? s.wall_coupling / s.wall_total : 0.0);
  io::write_file_atomic(dir / "timing.csv", text);
}

}  // namespace demfem::coupling
