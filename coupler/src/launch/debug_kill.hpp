#pragma once
// --debug-kill dem:17, fem:5:always, coupler:30, job:12:usr2 (docs/reliability.md): fault
// injection for the tests. ROLE job: the signal (SIGUSR1/SIGUSR2, a checkpoint request) goes
// to every process of the run, the launcher and both solvers, as Slurm's --signal sends it to
// a job's processes.

#include <cstdint>
#include <optional>
#include <string>

namespace demfem::coupling::launch {

/// @brief One parsed --debug-kill.
struct DebugKill {
  std::string role;  ///< dem, fem, coupler or job
  std::int64_t step = -1;
  bool always = false;  ///< :always: in every attempt of the step, not only the first
  bool stop = false;    ///< :stop: SIGSTOP (a hung process, found by its stale heartbeat)
  int job_signal = 0;   ///< job:STEP:usr1|usr2: SIGUSR1 or SIGUSR2
  bool fired = false;
};

/// @brief Parses ROLE:STEP[:always|:stop] (ROLE dem, fem or coupler) or job:STEP:usr1|usr2;
/// nullopt for "" (no --debug-kill). Throws std::invalid_argument for anything else.
std::optional<DebugKill> parse_debug_kill(const std::string& text);

}  // namespace demfem::coupling::launch
