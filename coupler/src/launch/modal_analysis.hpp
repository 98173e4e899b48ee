#pragma once
// fem.analysis = "modal": natural frequencies, no solver process and no time steps; the
// launcher computes them itself (fem::run_modal_analysis) into the output folder.

#include "launch/launch_options.hpp"
#include "launch/preflight.hpp"
#include "launch/run_folder.hpp"

namespace demfem::coupling::launch {

/// @brief Runs the modal analysis of the scene's [fem] and writes the run's end into run.json.
/// Returns the exit status: 0, kExitBadInput for a model that cannot be analysed,
/// kExitFailed otherwise.
int run_modal_analysis(const LaunchOptions& opt, const CheckedRun& run, RunFolder& folder);

}  // namespace demfem::coupling::launch
