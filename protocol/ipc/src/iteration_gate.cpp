// Iterated steps (implicit coupling): the rules between the Step messages and a backend's
// save point, the same for serve() and for the coupler's in-process link.
#include <chrono>
#include <string>

#include "demfem/protocol/protocol.hpp"

namespace demfem::protocol {

StepResult IterationGate::step(SolverBackend& backend, const StepCommand& cmd,
                               InterfaceBuffers& buffers) {
  const bool iterate = (cmd.flags & kStepIterate) != 0;
  const bool redo = (cmd.flags & kStepRedo) != 0;
  if (redo && !iterate) {
    throw ProtocolError("step " + std::to_string(cmd.step) +
                        ": kStepRedo without kStepIterate (a redo is an iteration)");
  }
  if (iterate && !backend.supports_iteration()) {
    throw ProtocolError("step " + std::to_string(cmd.step) + ": the solver '" + backend.name() +
                        "' does not support iterated steps (implicit coupling), but was sent one");
  }
  const auto t0 = std::chrono::steady_clock::now();
  if (redo) {
    if (!tentative_ || saved_step_ != cmd.step) {
      throw ProtocolError("step " + std::to_string(cmd.step) + ": kStepRedo, but " +
                          (saved_step_ < 0
                               ? std::string("no step start was saved")
                               : "the saved start is of step " + std::to_string(saved_step_)) +
                          (tentative_ ? "" : " and no iteration is held back"));
    }
    backend.restore_iteration_state();
  } else {
    accept(backend);
    saved_step_ = -1;
    if (iterate) {
      backend.save_iteration_state();
      saved_step_ = cmd.step;
    }
  }
  // From here until step() returns, a failure leaves nothing to accept.
  tentative_ = false;
  StepResult r = backend.step(cmd, buffers);
  tentative_ = iterate;
  r.compute_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

void IterationGate::accept(SolverBackend& backend) {
  if (!tentative_) return;
  tentative_ = false;
  backend.accept_step();
}

void IterationGate::discard() {
  tentative_ = false;
  saved_step_ = -1;
}

}  // namespace demfem::protocol
