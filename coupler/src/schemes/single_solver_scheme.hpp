#pragma once
// dem_only and fem_only: a scene with one solver. Nothing is exchanged; the coupling step is
// the output and diagnostics interval of that solver alone. Private to the coupling library.

#include "schemes/coupling_scheme.hpp"

namespace demfem::coupling {

/// @brief One solver alone: the DEM in slices of dem_substeps (the last cut to end at
/// run.end_time), or the FEM (static when fem.static).
class SingleSolverScheme : public CouplingScheme {
 public:
  using CouplingScheme::CouplingScheme;

 protected:
  void advance(StepCommand dem_cmd, StepCommand fem_cmd, StepDiagnostics& d) override;
};

}  // namespace demfem::coupling
