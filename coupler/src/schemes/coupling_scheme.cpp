#include "schemes/coupling_scheme.hpp"

#include <algorithm>
#include <cmath>

#include "schemes/concurrent_scheme.hpp"
#include "schemes/implicit_scheme.hpp"
#include "schemes/one_way_static_scheme.hpp"
#include "schemes/serial_scheme.hpp"
#include "schemes/single_solver_scheme.hpp"

namespace demfem::coupling {

double trapezoid_work(std::span<const double> f0, std::span<const double> f1,
                      std::span<const double> x0, std::span<const double> x1) {
  double w = 0.0;
  for (std::size_t k = 0; k < x0.size(); ++k) w += 0.5 * (f0[k] + f1[k]) * (x1[k] - x0[k]);
  return w;
}

double max_node_distance(std::span<const double> a, std::span<const double> b) {
  double m = 0.0;
  for (std::size_t i = 0; i + 2 < a.size(); i += 3) {
    const double dx = a[i] - b[i], dy = a[i + 1] - b[i + 1], dz = a[i + 2] - b[i + 2];
    m = std::max(m, std::sqrt(dx * dx + dy * dy + dz * dz));
  }
  return m;
}

void CouplingScheme::step(StepCommand dem_cmd, StepCommand fem_cmd, StepDiagnostics& d) {
  advance(dem_cmd, fem_cmd, d);
  account_interface(d);
  SchemeState& st = state();
  if (coupled()) {
    st.dem_force_prev = st.dem_force;
    st.fem_force_prev = st.fem_force;
  }
  d.work_dem = st.work_dem;
  d.work_fem = st.work_fem;
  d.energy_error = st.work_dem - st.work_fem;
  for (std::size_t k = 2; k < interface_values(); k += 3) d.force_sum_z += st.dem_force[k];
}

void CouplingScheme::account_interface(StepDiagnostics& d) {
  if (!coupled()) return;
  SchemeState& st = state();
  st.work_dem += trapezoid_work(st.dem_force_prev, st.dem_force, st.dem_start, st.dem_end);
  st.work_fem += trapezoid_work(st.fem_force_prev, st.fem_force, st.positions, st.next_positions);
  d.drift = max_node_distance(st.dem_end, st.next_positions);
  st.positions = st.next_positions;
}

std::unique_ptr<CouplingScheme> make_coupling_scheme(const SchemeContext& context) {
  switch (context.settings.scheme) {
    case Scheme::dem_only:
    case Scheme::fem_only:
      return std::make_unique<SingleSolverScheme>(context);
    case Scheme::one_way_static:
      return std::make_unique<OneWayStaticScheme>(context);
    case Scheme::just_in_time:
    case Scheme::predictive:
      return std::make_unique<SerialScheme>(context);
    case Scheme::concurrent:
      return std::make_unique<ConcurrentScheme>(context);
    case Scheme::implicit:
      return std::make_unique<ImplicitScheme>(context);
  }
  throw std::logic_error("make_coupling_scheme: unknown coupling scheme");
}

void CouplingScheme::hand_fem_kinematics_to_dem(StepCommand& dem_cmd) {
  SchemeState& st = state();
  InterfaceBuffers& buf = buffers();
  constexpr std::uint32_t b = kSharedBuffer;
  std::ranges::copy(st.positions, buf.positions(b).begin());
  std::ranges::copy(st.velocities, buf.velocities(b).begin());
  std::ranges::copy(st.accelerations, buf.accelerations(b).begin());
  st.dem_start = st.positions;
  dem_cmd.flags |= protocol::kStepSetKinematics;
}

}  // namespace demfem::coupling
