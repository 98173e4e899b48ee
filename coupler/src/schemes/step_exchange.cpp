#include "schemes/step_exchange.hpp"

#include <algorithm>
#include <chrono>
#include <sstream>
#include <stdexcept>
#include <string>

#include "interface_checks.hpp"
#include "run_text.hpp"

namespace demfem::coupling {

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

}  // namespace

StepExchange::StepExchange(SolverLink& link, const RunControl& control, SchemeState& state,
                           std::size_t interface_values)
    : link_(link), control_(control), state_(state), n3_(interface_values) {}

SolverFailure StepExchange::failure(Role role, const StepCommand& cmd, const std::exception& e,
                                    std::optional<protocol::ErrorKind> kind) const {
  // Named with the backend's own name (its Hello): an outside program is blamed by name.
  const std::string what = e.what();
  std::ostringstream m;
  m << "the " << role_label(role) << " solver failed in coupling step " << cmd.step
    << " (t = " << format_number(cmd.time) << " s): "
    << (what.rfind("its backend \"", 0) == 0 ? "" : "its backend \"" + link_.name(role) + "\": ")
    << what;
  return SolverFailure(role, cmd.step, cmd.time, m.str(),
                       dynamic_cast<const protocol::PeerDied*>(&e) != nullptr,
                       kind.value_or(error_kind_of(e)));
}

void StepExchange::send(Role role, const StepCommand& cmd) {
  try {
    link_.send_step(role, cmd);
    if (control_.after_send) control_.after_send(role, cmd.step);
  } catch (const std::exception& e) {
    throw failure(role, cmd, e);
  }
}

StepResult StepExchange::wait(Role role, const StepCommand& cmd) {
  StepResult r;
  try {
    r = link_.wait_step_done(role);
  } catch (const std::exception& e) {
    throw failure(role, cmd, e);
  }
  if (n3_ > 0) {
    InterfaceBuffers& buf = link_.buffers();
    if (const std::string bad = role == Role::fem ? non_finite_fem_kinematics(buf, cmd.buffer)
                                                  : non_finite_dem_output(buf, cmd.buffer);
        !bad.empty()) {
      // The solver's own blow-up (exit status 3), as if it had refused the state itself.
      throw failure(role, cmd,
                    std::runtime_error("its backend \"" + link_.name(role) + "\": " + bad),
                    protocol::ErrorKind::blow_up);
    }
  }
  return r;
}

void StepExchange::dem_done(const StepResult& r, std::uint32_t buffer, StepDiagnostics& d) {
  d.max_overlap = r.values[0];
  d.kinetic_energy = r.values[1];
  d.dem_max_overlap = r.values[2];
  d.wall_dem_compute += r.compute_seconds;
  if (n3_ > 0) {
    InterfaceBuffers& buf = link_.buffers();
    std::ranges::copy(buf.forces(buffer), state_.dem_force.begin());
    std::ranges::copy(buf.dem_positions(buffer), state_.dem_end.begin());
  }
}

void StepExchange::fem_done(const StepResult& r, StepDiagnostics& d) {
  d.fem_max_displacement = r.values[0];
  d.wall_fem_compute += r.compute_seconds;
}

void StepExchange::dem_step(const StepCommand& cmd, StepDiagnostics& d) {
  const auto t0 = Clock::now();
  send(Role::dem, cmd);
  const StepResult r = wait(Role::dem, cmd);
  d.wall_dem += seconds_since(t0);
  dem_done(r, cmd.buffer, d);
}

void StepExchange::fem_step(const StepCommand& cmd, StepDiagnostics& d) {
  const auto t0 = Clock::now();
  send(Role::fem, cmd);
  const StepResult r = wait(Role::fem, cmd);
  d.wall_fem += seconds_since(t0);
  fem_done(r, d);
}

void StepExchange::drain(Role role) noexcept {
  try {
    (void)link_.wait_step_done(role);
  } catch (...) {
  }
}

}  // namespace demfem::coupling
