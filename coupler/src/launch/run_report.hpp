#pragma once
// What the launcher prints and writes around the coupling loop: the plan of the run before
// it (scheme, coupling step, steps to the end time) and, for a run that reached its end, the
// summary (steps, scheme's totals, wall times), timing.csv and the [coupling] beam_check.

#include "launch/launch_options.hpp"
#include "launch/preflight.hpp"
#include "launch/run_outcome.hpp"

namespace demfem::coupling::launch {

/// @brief "demfem run: SCENE: scheme ..., dt_C = ..., N coupling steps to t = ..." on stdout.
void print_run_plan(const LaunchOptions& opt, const CheckedRun& run);

/// @brief The summary of a run that reached its end (nothing without outcome.summary);
/// timing.csv and beam_check.csv into the output folder. A failure to write them fails a
/// run that had not failed.
void report_results(const CheckedRun& run, RunOutcome& outcome);

}  // namespace demfem::coupling::launch
