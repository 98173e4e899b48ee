#pragma once
// The explicit sequential schemes: one solver after the other, once per coupling step, each
// given what the other has just computed (preCICE's SerialCouplingScheme). Private to the
// coupling library.

#include "schemes/coupling_scheme.hpp"

namespace demfem::coupling {

/// @brief just_in_time (thesis Algorithm 3: DEM, then FEM with its forces) and predictive
/// (eq. 3.4-3.7: FEM with the last DEM forces, then DEM towards where the FEM ended).
class SerialScheme : public CouplingScheme {
 public:
  using CouplingScheme::CouplingScheme;

 protected:
  void advance(StepCommand dem_cmd, StepCommand fem_cmd, StepDiagnostics& d) override;

 private:
  void just_in_time(StepCommand dem_cmd, StepCommand fem_cmd, StepDiagnostics& d);
  void predictive(StepCommand dem_cmd, StepCommand fem_cmd, StepDiagnostics& d);
};

}  // namespace demfem::coupling
