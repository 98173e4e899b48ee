#pragma once
// The checks after every coupling step (docs/coupling.md, "Blow-up"): the interface forces
// and both copies of the interface positions finite, every diagnostic finite, the
// particle-interface overlap and the interface energy error within coupling.blowup's bounds.
// Private to the coupling library.

#include <optional>

#include "demfem/coupling/coupling_run.hpp"
#include "schemes/scheme_state.hpp"

namespace demfem::coupling {

/// @brief The first check step `d` fails, as the BlowUp that stops the run; none when all
/// pass. The energy error is not bounded for one_way_static, whose DEM mesh never moves.
std::optional<BlowUp> blow_up_of(const StepDiagnostics& d, const SchemeState& state,
                                 const CouplingSettings& settings);

}  // namespace demfem::coupling
