#pragma once
// The one place where the launcher turns what ended a run early (an exception out of the
// solvers' start or the coupling loop) into its exit status (demfem/interface/exit_status.hpp)
// and the message it prints: kExitBlowUp for a blow-up, kExitRecoveryExhausted for a solver
// that kept dying, kExitBadInput for a model or checkpoint found bad after the start,
// 128 + N after a stop signal N, kExitFailed for the rest.

#include <exception>
#include <filesystem>

#include "launch/run_outcome.hpp"
#include "launch/run_solvers.hpp"

namespace demfem::coupling::launch {

/// @brief Records `error` in `outcome` (RunOutcome::fail) with its exit status. `solvers`:
/// the processes, looked at for a solver that ended before it attached (and killed when it
/// hangs); `out_dir` is named in the messages of a run that wrote output; `hello_timeout`
/// (s, --hello-timeout) in the message of a solver that never attached.
void fail_with_exit_status(std::exception_ptr error, RunSolvers& solvers,
                           const std::filesystem::path& out_dir, double hello_timeout,
                           RunOutcome& outcome);

}  // namespace demfem::coupling::launch
