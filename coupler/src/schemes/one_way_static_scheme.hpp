#pragma once
// one_way_static: the DEM settles on the interface held at its reference positions; once its
// kinetic energy is below coupling.settle.kinetic_energy (after settle.min_time), or at the
// last step when no threshold is set, its forces go once into a static FEM solve. Private to
// the coupling library.

#include "schemes/coupling_scheme.hpp"

namespace demfem::coupling {

/// @brief DEM to rest on a fixed mesh, then one static FEM solve with its forces.
class OneWayStaticScheme : public CouplingScheme {
 public:
  using CouplingScheme::CouplingScheme;

 protected:
  void advance(StepCommand dem_cmd, StepCommand fem_cmd, StepDiagnostics& d) override;
  /// The DEM's mesh never moves: no work on its side, and the drift is the FEM's
  /// displacement until the solve (zero after it).
  void account_interface(StepDiagnostics& d) override;
};

}  // namespace demfem::coupling
