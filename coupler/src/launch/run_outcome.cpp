#include "launch/run_outcome.hpp"

#include <cstdio>

#include "demfem/interface/exit_status.hpp"
#include "launch/supervisor.hpp"

namespace demfem::coupling::launch {

void RunOutcome::fail(int c, const std::string& text) {
  progress_.finish();
  std::fprintf(stderr, "demfem run: %s\n", text.c_str());
  code = c;
  reason = text;
}

void RunOutcome::fail_stopped(const std::string& what) {
  fail(128 + SignalGuard::signal_number(),
       "stopped by signal " + std::to_string(SignalGuard::signal_number()) + " (" + what + ")");
}

int RunOutcome::record_end(RunFolder& folder) {
  RunRecord& record = folder.record();
  record.exit_code = code;
  record.end_time = utc_now();
  if (summary) {
    steps_done = summary->steps;
    time_reached = summary->time;
  }
  record.steps_done = steps_done;
  record.time_reached = time_reached;
  if (code == 0) {
    record.status = "completed";
  } else if (code > 128 && SignalGuard::stop_flag().load()) {
    record.status = "interrupted";
    record.signal = SignalGuard::signal_number();
    record.reason = reason;
  } else {
    record.status = "failed";
    record.reason = reason;
  }
  try {
    // A lost folder's run.json is another run's now (or gone): it is left alone.
    if (!folder_lost) write_run_record(folder.output_dir(), record);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "demfem run: %s\n", e.what());
    if (code == 0) code = kExitFailed;
  }
  std::fflush(stdout);
  return code;
}

}  // namespace demfem::coupling::launch
