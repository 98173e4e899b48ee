#include "schemes/one_way_static_scheme.hpp"

#include <algorithm>

namespace demfem::coupling {

void OneWayStaticScheme::advance(StepCommand dem_cmd, StepCommand fem_cmd, StepDiagnostics& d) {
  const CouplingSettings& s = settings();
  SchemeState& st = state();
  // The DEM mesh stays at the reference (no kinematics are sent).
  if (d.step == 0) st.dem_start = st.positions;
  exchange().dem_step(dem_cmd, d);
  const bool last = d.step + 1 == s.step_count;
  const bool ke_ok = s.settle_kinetic_energy > 0.0 && d.time >= s.settle_min_time * (1.0 - 1e-12) &&
                     d.kinetic_energy <= s.settle_kinetic_energy;
  if (!ke_ok && !(last && s.settle_kinetic_energy == 0.0)) return;
  st.settled = true;
  std::ranges::copy(st.dem_force, buffers().forces(kSharedBuffer).begin());
  st.fem_force = st.dem_force;
  fem_cmd.flags |= protocol::kStepStatic;
  exchange().fem_step(fem_cmd, d);
  std::ranges::copy(buffers().positions(kSharedBuffer), st.next_positions.begin());
  // A slowly applied load does W = F.u / 2 (the strain energy); the DEM's mesh did not move,
  // so its side is zero by construction (not a scheme error).
  st.work_fem = trapezoid_work(st.fem_force_prev, st.fem_force, st.positions, st.next_positions);
  st.positions = st.next_positions;
}

void OneWayStaticScheme::account_interface(StepDiagnostics& d) {
  const SchemeState& st = state();
  d.drift = st.settled ? 0.0 : max_node_distance(st.dem_end, st.positions);
}

}  // namespace demfem::coupling
