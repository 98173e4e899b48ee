#include "launch/shutdown.hpp"

#include <csignal>
#include <cstdio>

#include "demfem/coupling/local_solvers.hpp"
#include "demfem/interface/exit_status.hpp"
#include "launch/supervisor.hpp"

namespace demfem::coupling::launch {

using protocol::Role;

void end_solvers(RunSolvers& solvers, RunOutcome& outcome) {
  SolverProcess* const dem_proc = solvers.process(Role::dem);
  SolverProcess* const fem_proc = solvers.process(Role::fem);
  // A lost folder: the solvers are stopped as by a signal, so that they write no end state
  // there. In process, the adapters are told so after a stop signal too: a solver process
  // stopped by SIGTERM writes none, and an end-state snapshot beyond the last checkpoint
  // would stay in the output series of a `--resume` (an extra fem_NNNNNN.h5).
  const bool stopping = SignalGuard::stop_flag().load() || outcome.folder_lost;
  if (outcome.folder_lost) {
    for (auto* p : {dem_proc, fem_proc})
      if (p) p->signal(SIGTERM);
  }
  if (auto* local = dynamic_cast<LocalLink*>(solvers.link()); local && stopping) {
    for (auto role : {Role::dem, Role::fem}) drop_end_state(local->backend(role));
  }
  // A solver given up as dead or silent (no reply within reply_timeout) is killed at once: a
  // hung one would answer neither Shutdown nor SIGTERM, and waiting on both costs seconds.
  if (SolverProcess* p = outcome.given_up ? solvers.process(*outcome.given_up) : nullptr;
      p && p->running()) {
    p->signal(SIGKILL);
    std::fprintf(stderr, "demfem run: the %s (pid %d) is not answering: killed\n",
                 p->label().c_str(), static_cast<int>(p->pid()));
  }
  if (solvers.link() && !stopping) {
    SignalGuard::solvers_ending();  // a Ctrl-C now must not cut their end state short
    solvers.link()->shutdown();
  }
  for (auto* p : {dem_proc, fem_proc}) {
    if (!p) continue;
    const int c = p->stop(std::chrono::milliseconds(stopping ? 1000 : 3000));
    if (c != 0 && outcome.code == 0 && SignalGuard::stop_flag().load()) {
      // A stop signal after the last step (a terminal's Ctrl-C reaches the solvers too): the
      // steps are done, the end state is not written; --resume writes it from the last
      // checkpoint. Interrupted, as a stop earlier would be, not failed.
      outcome.fail(128 + SignalGuard::signal_number(),
                   "stopped by signal " + std::to_string(SignalGuard::signal_number()) +
                       " as the run ended: the " + p->label() + " ended with status " +
                       std::to_string(c) + " before its end state was written");
    } else if (c != 0 && outcome.code == 0) {
      outcome.fail(kExitFailed, "the " + p->label() + " exited with status " + std::to_string(c));
    }
  }
  solvers.close_link();
}

}  // namespace demfem::coupling::launch
