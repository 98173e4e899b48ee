#include "schemes/serial_scheme.hpp"

#include <algorithm>

namespace demfem::coupling {

void SerialScheme::advance(StepCommand dem_cmd, StepCommand fem_cmd, StepDiagnostics& d) {
  if (settings().scheme == Scheme::predictive) {
    predictive(dem_cmd, fem_cmd, d);
  } else {
    just_in_time(dem_cmd, fem_cmd, d);
  }
}

void SerialScheme::just_in_time(StepCommand dem_cmd, StepCommand fem_cmd, StepDiagnostics& d) {
  // Algorithm 3: the DEM moves the mesh from the FEM's state at t_i (x + v tau + a tau^2/2)
  // for n_D substeps; its forces then drive one FEM step.
  SchemeState& st = state();
  InterfaceBuffers& buf = buffers();
  constexpr std::uint32_t b = kSharedBuffer;
  hand_fem_kinematics_to_dem(dem_cmd);
  exchange().dem_step(dem_cmd, d);
  // The DEM adapter left its forces in the buffer; the FEM reads them there.
  st.fem_force = st.dem_force;
  exchange().fem_step(fem_cmd, d);
  std::ranges::copy(buf.positions(b), st.next_positions.begin());
  std::ranges::copy(buf.velocities(b), st.velocities.begin());
  std::ranges::copy(buf.accelerations(b), st.accelerations.begin());
}

void SerialScheme::predictive(StepCommand dem_cmd, StepCommand fem_cmd, StepDiagnostics& d) {
  // eq. 3.4-3.7: the FEM steps first with the last DEM forces; the DEM then moves the mesh
  // from P_i with V = (P_{i+1} - P_i) / dt_F and A = 0, ending where the FEM is.
  SchemeState& st = state();
  InterfaceBuffers& buf = buffers();
  constexpr std::uint32_t b = kSharedBuffer;
  st.fem_force = st.dem_force_prev;
  std::ranges::copy(st.fem_force, buf.forces(b).begin());
  exchange().fem_step(fem_cmd, d);
  std::ranges::copy(buf.positions(b), st.next_positions.begin());
  const double inv_dt = 1.0 / settings().coupling_dt;
  auto v = buf.velocities(b);
  for (std::size_t k = 0; k < interface_values(); ++k)
    v[k] = (st.next_positions[k] - st.positions[k]) * inv_dt;
  std::ranges::copy(st.positions, buf.positions(b).begin());
  std::ranges::fill(buf.accelerations(b), 0.0);
  st.dem_start = st.positions;
  dem_cmd.flags |= protocol::kStepSetKinematics;
  exchange().dem_step(dem_cmd, d);
}

}  // namespace demfem::coupling
