#pragma once
// How a run ended, as the launcher collects it: the exit status (exit_status.hpp) and the
// reason printed, the steps done, the summary of a run that reached its end, the solver given
// up (killed at shutdown), whether the output folder was lost. The run record (run.json) is
// written from it at the end.

#include <cstdint>
#include <optional>
#include <string>

#include "demfem/coupling/coupling_run.hpp"
#include "demfem/protocol/protocol.hpp"
#include "launch/progress.hpp"
#include "launch/run_folder.hpp"

namespace demfem::coupling::launch {

/// @brief The end of one run.
class RunOutcome {
 public:
  explicit RunOutcome(Progress& progress) : progress_(progress) {}

  /// The run failed: ends the progress line, prints "demfem run: <text>" on stderr and keeps
  /// `code` and `text` (the reason in run.json).
  void fail(int code, const std::string& text);
  /// The stop signal's status: "stopped by signal N (<what>)" with 128 + N.
  void fail_stopped(const std::string& what);
  /// Writes run.json from the outcome (completed, interrupted or failed; a lost folder's
  /// run.json is another run's now, or gone: it is left alone). Returns the exit status.
  int record_end(RunFolder& folder);

  int code = 0;
  std::string reason;
  bool folder_lost = false;           ///< OutputFolderLost: nothing more is written into the folder
  std::optional<RunSummary> summary;  ///< the run reached its end
  std::optional<protocol::Role> given_up;  ///< a solver that died or stopped answering
  std::int64_t steps_done = -1;            ///< from the step observer, until a summary
  double time_reached = -1.0;

 private:
  Progress& progress_;
};

}  // namespace demfem::coupling::launch
