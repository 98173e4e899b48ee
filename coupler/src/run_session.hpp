#pragma once
// Everything one CouplingRun::run() works with, shared by its parts: the run loop
// (coupling_run.cpp), its checkpoints (run_checkpoints.cpp), the recovery from a dead solver
// (recovery.cpp) and the per-step checks (step_checks.cpp). Private to the coupling library.

#include <atomic>
#include <chrono>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include "demfem/coupling/coupling_run.hpp"
#include "interface_output.hpp"
#include "run_output.hpp"
#include "schemes/coupling_scheme.hpp"
#include "schemes/scheme_state.hpp"
#include "schemes/step_exchange.hpp"

namespace demfem::coupling {

using RunClock = std::chrono::steady_clock;

inline double seconds_between(RunClock::time_point a, RunClock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

/// @brief One run: the solvers, the settings and controls, the totals, the scheme with its
/// history, and the output. Built after the solvers' handshake (the interface mesh is known).
struct RunSession {
  RunSession(SolverLink& link, const CouplingSettings& settings, const RunControl& control,
             const std::filesystem::path& output_dir, RecoveryStats& stats, RunOutput& output,
             InterfaceMesh mesh);

  /// A message about checkpoints, recovery or convergence (RunControl::report).
  void report(const std::string& message) const {
    if (control.report) control.report(message);
  }
  /// The interface as the output files show it: the FEM's positions and velocities as the
  /// scheme holds them, the DEM's forces and mesh positions.
  InterfaceState interface_state() const {
    return InterfaceState{&summary.mesh, state.positions, state.velocities, state.dem_force,
                          state.dem_end};
  }
  /// coupling.h5 with the interface as it is now.
  void write_end_state() const;

  SolverLink& link;
  const CouplingSettings& settings;
  const RunControl& control;
  const std::filesystem::path& output_dir;
  RecoveryStats& stats;
  RunOutput& output;
  RunSummary summary;
  std::size_t n3;  ///< 3 x the interface's node count
  SchemeState state;
  StepExchange exchange;
  std::unique_ptr<CouplingScheme> scheme;
  RunClock::time_point run_start = RunClock::now();  ///< of the first step (wall_total)
};

}  // namespace demfem::coupling
