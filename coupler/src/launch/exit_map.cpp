#include "launch/exit_map.hpp"

#include <csignal>
#include <cstdio>
#include <string>

#include "demfem/coupling/coupling_run.hpp"
#include "demfem/coupling/solver_link.hpp"
#include "demfem/interface/exit_status.hpp"
#include "demfem/scene/scene_reader.hpp"
#include "launch/supervisor.hpp"

namespace demfem::coupling::launch {
namespace {

// The solver says what kind of error it found (protocol::ErrorKind): a model that cannot be
// solved (a mechanism, displacements larger than the model) is bad input, found late; a
// non-finite or unstable state is a blow-up. Errors of a solver that does not classify them
// are blow-ups when their text says so ("... is not finite", "blew up").
void fail_solver(const SolverFailure& e, const std::string& output_note, RunOutcome& outcome) {
  if (e.died()) outcome.given_up = e.role();
  if (SignalGuard::stop_flag().load()) {
    outcome.fail_stopped(e.what());
  } else if (e.kind() == protocol::ErrorKind::bad_input) {
    outcome.fail(kExitBadInput,
                 "bad model: " + std::string(e.what()) +
                     "\n  (found by the solver after the run started; output so far is in " +
                     output_note + ")");
  } else if (e.kind() == protocol::ErrorKind::blow_up ||
             (e.kind() == protocol::ErrorKind::failure && is_blow_up_report(e.what()))) {
    outcome.fail(kExitBlowUp,
                 "blow-up: " + std::string(e.what()) + "\n  output so far is in " + output_note);
  } else {
    outcome.fail(kExitFailed, std::string(e.what()) + "\n  output so far is in " + output_note);
  }
}

// Only the start (Hello, mesh exchange) lets PeerDied through unwrapped: a solver that ended
// before it attached, or never attached.
void fail_unattached(const protocol::PeerDied& e, RunSolvers& solvers, double hello_timeout,
                     RunOutcome& outcome) {
  SolverProcess* p = solvers.process(e.role());
  const std::string& name = solvers.program(e.role());
  if (SignalGuard::stop_flag().load()) {
    outcome.fail_stopped(e.what());
  } else if (p && !p->wait_for(std::chrono::milliseconds(1000)) && p->running()) {
    // (A process seen gone may not be reapable for a moment: the wait tells a death from
    // a hang.)
    p->signal(SIGKILL);
    const int c = p->stop(std::chrono::milliseconds(1000));
    char limit[32];
    std::snprintf(limit, sizeof(limit), "%g", hello_timeout);
    outcome.fail(kExitFailed, "the " + p->label() + " (" + name + ", pid " +
                                  std::to_string(p->pid()) + ") did not attach within " + limit +
                                  " s (--hello-timeout); it was killed (status " +
                                  std::to_string(c) + "). " + e.what());
  } else if (p) {
    const int c = p->exit_code().value_or(-1);
    outcome.fail(c == kExitBadInput ? kExitBadInput : kExitFailed,
                 "the " + p->label() + " (" + name + ", pid " + std::to_string(p->pid()) +
                     ") ended with status " + std::to_string(c) +
                     " before it attached; its message is above (" + e.what() + ")");
  } else {
    outcome.fail(kExitFailed, e.what());
  }
}

}  // namespace

void fail_with_exit_status(std::exception_ptr error, RunSolvers& solvers,
                           const std::filesystem::path& out_dir, double hello_timeout,
                           RunOutcome& outcome) {
  const std::string output_note = out_dir.string();
  try {
    std::rethrow_exception(error);
  } catch (const BlowUp& e) {
    outcome.fail(kExitBlowUp, std::string(e.what()) + "\n  output so far is in " + output_note);
  } catch (const RecoveryExhausted& e) {
    outcome.given_up = e.role();
    outcome.fail(kExitRecoveryExhausted,
                 std::string(e.what()) + "\n  output so far is in " + output_note);
  } catch (const SolverFailure& e) {
    fail_solver(e, output_note, outcome);
  } catch (const OutputFolderLost& e) {
    outcome.fail(kExitFailed, e.what());
    outcome.folder_lost = true;
  } catch (const Interrupted& e) {
    outcome.fail(128 + SignalGuard::signal_number(), e.what());
  } catch (const ResumeRefused& e) {
    outcome.fail(kExitBadInput, e.what());
  } catch (const InterfaceMismatch& e) {
    outcome.fail(kExitBadInput, e.what());
  } catch (const HandshakeFailed& e) {
    outcome.fail(e.bad_input() ? kExitBadInput : kExitFailed, e.what());
  } catch (const scene::SceneError& e) {
    outcome.fail(kExitBadInput, std::string("scene error: ") + e.what());
  } catch (const protocol::PeerDied& e) {
    fail_unattached(e, solvers, hello_timeout, outcome);
  } catch (const protocol::BackendError& e) {
    // In process, a solver's set-up found it (the FEM's model check before the first step).
    if (e.kind() == protocol::ErrorKind::bad_input) {
      outcome.fail(kExitBadInput, std::string("bad model: ") + e.what());
    } else {
      outcome.fail(e.kind() == protocol::ErrorKind::blow_up ? kExitBlowUp : kExitFailed, e.what());
    }
  } catch (const std::exception& e) {
    if (SignalGuard::stop_flag().load()) {
      outcome.fail_stopped(e.what());
    } else {
      outcome.fail(kExitFailed, e.what());
    }
  }
}

}  // namespace demfem::coupling::launch
