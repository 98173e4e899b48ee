#pragma once
// concurrent: both solvers step at the same time, each from the other's data at t_i
// (preCICE's ParallelCouplingScheme, explicit). Private to the coupling library.

#include <algorithm>

#include "schemes/coupling_scheme.hpp"

namespace demfem::coupling {

/// @brief The DEM moves the mesh from the FEM's state at t_i (as just_in_time) in buffer 0,
/// while the FEM advances with the DEM's last forces (F_i, as predictive) in buffer 1.
class ConcurrentScheme : public CouplingScheme {
 public:
  using CouplingScheme::CouplingScheme;

  /// The solvers' steps overlap: the FEM's wall time (from the common send to its reply)
  /// covers both.
  double solver_wall(const StepDiagnostics& d) const override {
    return std::max(d.wall_dem, d.wall_fem);
  }

 protected:
  void advance(StepCommand dem_cmd, StepCommand fem_cmd, StepDiagnostics& d) override;
};

}  // namespace demfem::coupling
