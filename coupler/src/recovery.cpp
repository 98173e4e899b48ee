#include "recovery.hpp"

#include "run_text.hpp"

namespace demfem::coupling {

bool Recovery::can_recover(const SolverFailure& failure) const {
  return run_.control.restart_solver && checkpoints_.last() && failure.died() &&
         !(stop_ && stop_->load());
}

std::int64_t Recovery::recover(const SolverFailure& first) {
  const auto t0 = RunClock::now();
  const std::int64_t max_retries = run_.settings.checkpoint.max_retries;
  Role role = first.role();
  std::string why = first.what();
  for (;;) {
    const std::int64_t n = ++tries_[checkpoints_.last_step()];
    const std::string checkpoint = checkpoints_.last()->string();
    failures_ += "\n  " + why;
    if (n > max_retries) {
      throw RecoveryExhausted(role, first.step(), first.time(),
                              "the " + std::string(role_label(role)) +
                                  " solver kept failing: " + std::to_string(max_retries) +
                                  " restarts from checkpoint " + checkpoint + " (step " +
                                  std::to_string(checkpoints_.last_step()) +
                                  ") did not get past it (checkpoint.max_retries = " +
                                  std::to_string(max_retries) + "); failures:" + failures_);
    }
    run_.report("the " + std::string(role_label(role)) + " solver failed (" + why + "); restart " +
                std::to_string(n) + " of " + std::to_string(max_retries) +
                ", rolling back to checkpoint " + checkpoint);
    try {
      run_.control.restart_solver(role);
      const std::int64_t at = checkpoints_.restore(*checkpoints_.last(), false);
      ++run_.stats.recoveries;
      run_.stats.recovery_wall += seconds_between(t0, RunClock::now());
      run_.report("recovered: every process is back at step " + std::to_string(at) +
                  " (t = " + format_number(run_.summary.time) + " s), " +
                  format_number(seconds_between(t0, RunClock::now())) + " s after the failure");
      return at;
    } catch (const protocol::PeerDied& e) {
      role = e.role();
      why = e.what();
    }
    if (stop_ && stop_->load()) throw Interrupted("stopped by a signal during recovery");
  }
}

}  // namespace demfem::coupling
