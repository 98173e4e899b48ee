#pragma once
// One solver step as every coupling scheme takes it: the Step command sent, the reply awaited,
// what the solver wrote into the interface buffers checked for non-finite values, and its
// outcome (forces, mesh positions, overlaps, wall times) taken into the scheme's state and the
// step's diagnostics. A solver that fails or dies here becomes a SolverFailure that names it
// (by its backend's own name), the coupling step and the time. Private to the coupling library.

#include <cstddef>
#include <cstdint>
#include <exception>
#include <optional>

#include "demfem/coupling/coupling_run.hpp"
#include "schemes/scheme_state.hpp"

namespace demfem::coupling {

/// @brief The solver side of a coupling step, over a SolverLink.
class StepExchange {
 public:
  /// `control.after_send` is called after every Step sent (fault injection);
  /// `interface_values`: 3 x the interface's node count.
  StepExchange(SolverLink& link, const RunControl& control, SchemeState& state,
               std::size_t interface_values);

  /// Sends `cmd` to `role`'s solver.
  void send(Role role, const StepCommand& cmd);
  /// Waits for `role`'s reply to `cmd` and checks what it wrote into the buffer.
  StepResult wait(Role role, const StepCommand& cmd);
  /// Takes a DEM step's outcome: its overlaps and kinetic energy into `d`, its forces and mesh
  /// positions (in buffer `buffer`) into the state's dem_force and dem_end.
  void dem_done(const StepResult& r, std::uint32_t buffer, StepDiagnostics& d);
  /// Takes a FEM step's outcome (its largest displacement) into `d`.
  void fem_done(const StepResult& r, StepDiagnostics& d);
  /// send + wait + dem_done, its wall time added to d.wall_dem.
  void dem_step(const StepCommand& cmd, StepDiagnostics& d);
  /// send + wait + fem_done, its wall time added to d.wall_fem.
  void fem_step(const StepCommand& cmd, StepDiagnostics& d);
  /// Waits for a reply that must not stay behind after the other solver failed; its own
  /// failure is ignored (the first one is reported).
  void drain(Role role) noexcept;

  SolverLink& link() { return link_; }
  InterfaceBuffers& buffers() { return link_.buffers(); }
  std::size_t interface_values() const { return n3_; }

 private:
  SolverFailure failure(Role role, const StepCommand& cmd, const std::exception& e,
                        std::optional<protocol::ErrorKind> kind = std::nullopt) const;

  SolverLink& link_;
  const RunControl& control_;
  SchemeState& state_;
  std::size_t n3_;
};

}  // namespace demfem::coupling
