#pragma once
// The solvers of one run, started by the launcher: either processes (dem_server, fem_server,
// or the program of an external backend) attached to a shared-memory segment that this
// object owns, each supervised as a SolverProcess and started again when it dies (the run
// then rolls back to its last checkpoint, CouplingRun); or, with --in-process, the solver
// libraries in this process (LocalLink). --debug-kill's hook is installed here: it needs the
// processes.

#include <memory>
#include <optional>
#include <string>

#include "demfem/coupling/coupling_run.hpp"
#include "demfem/coupling/solver_link.hpp"
#include "demfem/protocol/protocol.hpp"
#include "launch/debug_kill.hpp"
#include "launch/launch_options.hpp"
#include "launch/mpi_job_files.hpp"
#include "launch/preflight.hpp"
#include "launch/resume_point.hpp"
#include "launch/supervisor.hpp"

namespace demfem::coupling::launch {

/// @brief The solvers of a run and the link the coupling loop talks to them through.
class RunSolvers {
 public:
  RunSolvers(const LaunchOptions& opt, const CheckedRun& run);
  RunSolvers(const RunSolvers&) = delete;  // the hooks in RunControl call back through `this`
  RunSolvers& operator=(const RunSolvers&) = delete;

  /// Creates the segment and starts the solver processes; sets control.restart_solver (and
  /// control.after_send for --debug-kill). Throws what starting them throws.
  void start_processes(const std::optional<ResumePoint>& resume, RunControl& control);
  /// --in-process: the solver libraries in this process (control.after_send for
  /// --debug-kill of the coupler or the job).
  void start_in_process(RunControl& control);

  /// The link to the solvers; null before a start (or when the start threw).
  SolverLink* link() { return link_.get(); }
  /// The process of `role`; null in process, without that solver, or before its start.
  SolverProcess* process(protocol::Role role) {
    return role == protocol::Role::dem ? dem_proc_.get() : fem_proc_.get();
  }
  /// How messages name the process of `role`: "dem_server", "fem_server", or an external
  /// backend's label.
  const std::string& program(protocol::Role role) const {
    return role == protocol::Role::dem ? dem_program_ : fem_program_;
  }
  /// Ends the link and removes the segment (the processes stay until destroyed).
  void close_link();

 private:
  protocol::CouplerOptions coupler_options() const;
  std::unique_ptr<SolverProcess> start_one(protocol::Role role,
                                           const std::optional<ExternalCommand>& external,
                                           const std::vector<std::string>& args,
                                           const std::vector<std::string>& fem_args);
  void describe_processes(RemoteLink& link, const std::optional<ResumePoint>& resume);
  void restart(protocol::Role role);
  /// The external DEM's Hello came from `pid` (rank 0 under mpirun): kept for the restart's
  /// grace, and its MPI job noted for the clean-up of its files.
  void note_external_dem_hello(pid_t pid);
  void debug_kill_after_send(protocol::Role role, std::int64_t step);

  const LaunchOptions& opt_;
  const CheckedRun& run_;
  std::optional<DebugKill> debug_kill_;
  std::unique_ptr<protocol::CouplerSession> session_;
  // Before the processes: their hooks remove these files when they end, also in ~RunSolvers.
  MpiJobFiles dem_mpi_jobs_;  // the MPI jobs of an external DEM (one per start)
  pid_t dem_hello_pid_ = 0;   // the pid in the external DEM's Hello (mpirun's rank 0); 0: none
  std::unique_ptr<SolverProcess> dem_proc_, fem_proc_;
  std::unique_ptr<SolverLink> link_;
  std::string fem_program_ = "fem_server";  // how messages name the FEM process
  std::string dem_program_ = "dem_server";  // and the DEM process
};

}  // namespace demfem::coupling::launch
