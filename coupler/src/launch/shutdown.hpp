#pragma once
// The end of the solvers, whichever way the run ended: Shutdown, then a bounded wait, then
// signals. After a stop signal the solvers were sent SIGTERM already (no Shutdown, a short
// grace); a lost output folder stops them likewise, so that they write no end state there; a
// solver given up as dead or silent is killed at once. A stop signal after Shutdown reaches
// the solvers no more (SignalGuard::solvers_ending): their end state is written whole.

#include "launch/run_outcome.hpp"
#include "launch/run_solvers.hpp"

namespace demfem::coupling::launch {

/// @brief Ends the solvers of `solvers` and removes the segment. A solver that then exits
/// with an error fails a run that had not failed (`outcome`).
void end_solvers(RunSolvers& solvers, RunOutcome& outcome);

}  // namespace demfem::coupling::launch
