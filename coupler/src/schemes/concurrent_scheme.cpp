#include "schemes/concurrent_scheme.hpp"

#include <algorithm>
#include <chrono>

namespace demfem::coupling {

void ConcurrentScheme::advance(StepCommand dem_cmd, StepCommand fem_cmd, StepDiagnostics& d) {
  using Clock = std::chrono::steady_clock;
  SchemeState& st = state();
  InterfaceBuffers& buf = buffers();
  StepExchange& ex = exchange();
  constexpr std::uint32_t b = kSharedBuffer;
  hand_fem_kinematics_to_dem(dem_cmd);
  st.fem_force = st.dem_force_prev;
  fem_cmd.buffer = kConcurrentFemBuffer;
  std::ranges::copy(st.fem_force, buf.forces(fem_cmd.buffer).begin());
  const auto t0 = Clock::now();
  ex.send(Role::dem, dem_cmd);
  try {
    ex.send(Role::fem, fem_cmd);
  } catch (...) {
    ex.drain(Role::dem);  // the DEM's reply must not stay behind
    throw;
  }
  StepResult rd;
  try {
    rd = ex.wait(Role::dem, dem_cmd);
  } catch (...) {
    ex.drain(Role::fem);  // as above: its reply is drained
    throw;
  }
  d.wall_dem = std::chrono::duration<double>(Clock::now() - t0).count();
  const StepResult rf = ex.wait(Role::fem, fem_cmd);
  d.wall_fem = std::chrono::duration<double>(Clock::now() - t0).count();
  ex.dem_done(rd, b, d);
  ex.fem_done(rf, d);
  std::ranges::copy(buf.positions(fem_cmd.buffer), st.next_positions.begin());
  std::ranges::copy(buf.velocities(fem_cmd.buffer), st.velocities.begin());
  std::ranges::copy(buf.accelerations(fem_cmd.buffer), st.accelerations.begin());
}

}  // namespace demfem::coupling
