#include "schemes/single_solver_scheme.hpp"

#include <algorithm>
#include <cmath>

namespace demfem::coupling {

void SingleSolverScheme::advance(StepCommand dem_cmd, StepCommand fem_cmd, StepDiagnostics& d) {
  const CouplingSettings& s = settings();
  if (s.scheme == Scheme::dem_only) {
    // The DEM alone advances in slices; the last one is cut to end at run.end_time.
    const double t = dem_cmd.time;
    const double left = (s.run.end_time - t) / s.dem_dt;
    const std::int64_t n = std::llround(left);
    if (std::abs(left - static_cast<double>(n)) <= 1e-6 && n < dem_cmd.substeps) {
      dem_cmd.substeps = std::max<std::int64_t>(1, n);
      dem_cmd.dt = static_cast<double>(dem_cmd.substeps) * s.dem_dt;
      d.time = t + dem_cmd.dt;
    }
    exchange().dem_step(dem_cmd, d);
    return;
  }
  if (s.fem_static) fem_cmd.flags |= protocol::kStepStatic;
  exchange().fem_step(fem_cmd, d);
  if (interface_values() > 0)
    std::ranges::copy(buffers().positions(kSharedBuffer), state().positions.begin());
}

}  // namespace demfem::coupling
