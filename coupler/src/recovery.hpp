#pragma once
// Recovery from a solver that died in a coupling run (docs/reliability.md): the launcher's
// supervisor starts a fresh process for it, and every process rolls back to the last
// committed checkpoint; at most checkpoint.max_retries restarts per checkpoint step, then
// RecoveryExhausted names the solver, the checkpoint and every failure. Private to the
// coupling library.

#include <atomic>
#include <cstdint>
#include <map>
#include <string>

#include "run_checkpoints.hpp"

namespace demfem::coupling {

/// @brief The restarts of one run and what failed.
class Recovery {
 public:
  /// `stop`: polled between restarts (a signal ends the recovery with Interrupted).
  Recovery(RunSession& session, RunCheckpoints& checkpoints, const std::atomic<bool>* stop)
      : run_(session), checkpoints_(checkpoints), stop_(stop) {}

  /// Whether `failure` is recovered from: a solver that died (an error it reported would
  /// repeat from the checkpoint), with a supervisor to restart it and a checkpoint to go back
  /// to, and no stop asked for.
  bool can_recover(const SolverFailure& failure) const;
  /// Restarts the failed solver (and any that dies while restoring) and restores the last
  /// checkpoint; returns its step.
  std::int64_t recover(const SolverFailure& first);

 private:
  RunSession& run_;
  RunCheckpoints& checkpoints_;
  const std::atomic<bool>* stop_;
  std::map<std::int64_t, std::int64_t> tries_;  // restarts per checkpoint step
  std::string failures_;                        // every failure so far, one per line
};

}  // namespace demfem::coupling
