#pragma once
// The coupler's view of its solvers. The schemes (coupling_run.hpp) are written once against
// SolverLink; RemoteLink drives real solver processes through a protocol::CouplerSession,
// LocalLink holds the solvers' SolverBackend adapters in this process and calls them directly
// over process-local interface buffers. Both run the same adapter code on the same inputs in
// the same order, so a run through three processes equals the in-process run bit for bit.

#include <cstdint>
#include <exception>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <sys/types.h>

#include "demfem/interface/interface_mesh.hpp"
#include "demfem/protocol/protocol.hpp"

namespace demfem::coupling {

using protocol::InterfaceBuffers;
using protocol::Role;
using protocol::StepCommand;
using protocol::StepResult;

/// @brief A solver reported an error, or broke the protocol, in its handshake (Hello, mesh
/// exchange); what() names the process (its program and pid) and the cause.
class HandshakeFailed : public protocol::ProtocolError {
 public:
  HandshakeFailed(Role role, const std::string& text, bool bad_input = false)
      : ProtocolError(text), role_(role), bad_input_(bad_input) {}
  Role role() const { return role_; }
  /// The solver refused its input (a SolverError of kind bad_input): exit 2, not 1.
  bool bad_input() const { return bad_input_; }

 private:
  Role role_;
  bool bad_input_;
};

/// @brief The FEM reported another interface size than the run expects (the scene's
/// interface for demfem's own backends, the checkpoint's for a resume, the first process's for
/// a restart); what() names the process and both sizes. Bad input: the backend does not fit.
class InterfaceMismatch : public protocol::ProtocolError {
 public:
  using ProtocolError::ProtocolError;
};

/// @brief The solvers of one run, as the coupling schemes see them.
class SolverLink {
 public:
  virtual ~SolverLink() = default;
  /// This run has this solver.
  virtual bool has(Role role) const = 0;
  /// Handshakes and the mesh exchange (FEM publishes, DEM receives). Returns the interface
  /// mesh (empty when there is no FEM). Call once, before any step.
  virtual InterfaceMesh start() = 0;
  /// The solver's name as it reported it ("demfem-fem 0.1 (cpu)").
  virtual std::string name(Role role) const = 0;
  /// The solver can iterate a coupling step (protocol::kCapabilityIteration in its Hello).
  virtual bool supports_iteration(Role role) const = 0;
  /// Starts one step; the solver reads and writes buffers() (cmd.buffer) in place. The DEM and
  /// the FEM may each have a step in progress at once (the concurrent scheme, with different
  /// buffers).
  virtual void send_step(Role role, const StepCommand& cmd) = 0;
  /// Waits for the step started by send_step(). Throws protocol::ProtocolError subclasses.
  virtual StepResult wait_step_done(Role role) = 0;
  /// The interface arrays shared with the solvers (valid after start()).
  virtual InterfaceBuffers& buffers() = 0;
  /// Ends the solvers cleanly (never throws).
  virtual void shutdown() = 0;
  /// The solver writes its complete state to `file` (HDF5) and returns when it is written.
  virtual void checkpoint(Role role, const std::filesystem::path& file, std::int64_t step) = 0;
  /// The solver restores the state of `file`, written at coupling step `step`.
  virtual void restore(Role role, const std::filesystem::path& file, std::int64_t step) = 0;
};

/// @brief Solvers in this process, driven through their SolverBackend adapters. A step runs
/// when it is waited for; when both solvers have a step sent and not yet run (the concurrent
/// scheme), the FEM's runs on a worker thread while the DEM's runs on the calling thread
/// (whose OpenMP team the DEM keeps), so the two overlap here too. The solvers share nothing
/// but the interface buffers, in which they use different buffers, so the results are the
/// same bits as one after the other.
class LocalLink final : public SolverLink {
 public:
  /// Either pointer may be null (a run without that solver).
  LocalLink(std::unique_ptr<protocol::SolverBackend> dem,
            std::unique_ptr<protocol::SolverBackend> fem);
  ~LocalLink() override;

  bool has(Role role) const override;
  InterfaceMesh start() override;
  std::string name(Role role) const override;
  bool supports_iteration(Role role) const override;
  void send_step(Role role, const StepCommand& cmd) override;
  StepResult wait_step_done(Role role) override;
  InterfaceBuffers& buffers() override { return buffers_; }
  /// Accepts a held-back (iterated) step, as serve() does on Shutdown.
  void shutdown() override;
  void checkpoint(Role role, const std::filesystem::path& file, std::int64_t step) override;
  void restore(Role role, const std::filesystem::path& file, std::int64_t step) override;

  protocol::SolverBackend* backend(Role role) const;

 private:
  class Worker;
  void run_step(Role role);

  std::unique_ptr<protocol::SolverBackend> backends_[protocol::kRoleCount];
  protocol::IterationGate gates_[protocol::kRoleCount];
  std::optional<StepCommand> sent_[protocol::kRoleCount];    // sent, not yet run
  std::optional<StepResult> results_[protocol::kRoleCount];  // run, not yet waited for
  std::exception_ptr errors_[protocol::kRoleCount];
  std::unique_ptr<Worker> worker_;
  InterfaceBuffers buffers_;
  // Process-local storage behind buffers_, laid out as the bulk segment is.
  std::vector<double> reference_;
  std::vector<std::int32_t> triangles_;
  std::vector<double> arrays_;
};

/// @brief Solvers in their own processes, through the shared-memory protocol.
class RemoteLink final : public SolverLink {
 public:
  /// `pids`: the launched solver processes (watched while waiting for their Hello); a role
  /// without a pid is not part of the run.
  RemoteLink(protocol::CouplerSession& session, std::optional<pid_t> dem_pid,
             std::optional<pid_t> fem_pid);
  /// How messages name a solver process ("fem_server (pid 123)"); default: the role.
  void describe(Role role, std::string text) {
    descriptions_[static_cast<std::size_t>(role)] = std::move(text);
  }
  /// The FEM must report `nodes` interface nodes in its Hello (`what`: where that size comes
  /// from, for the message); start() throws InterfaceMismatch otherwise.
  void expect_fem_interface(std::size_t nodes, std::string what) {
    expected_fem_nodes_ = nodes;
    expected_fem_what_ = std::move(what);
  }
  /// Called in start() after each solver's Hello with the pid the Hello gave (the solver
  /// process itself, or rank 0 of an MPI job that mpirun started): the launcher notes an
  /// MPI job there to clean up after it (launch/mpi_job_files.hpp).
  void on_hello(std::function<void(Role, pid_t)> hook) { on_hello_ = std::move(hook); }

  bool has(Role role) const override;
  InterfaceMesh start() override;
  std::string name(Role role) const override;
  bool supports_iteration(Role role) const override;
  void send_step(Role role, const StepCommand& cmd) override;
  StepResult wait_step_done(Role role) override;
  InterfaceBuffers& buffers() override;
  void shutdown() override;
  void checkpoint(Role role, const std::filesystem::path& file, std::int64_t step) override;
  void restore(Role role, const std::filesystem::path& file, std::int64_t step) override;

 private:
  std::string description(Role role) const;
  protocol::CouplerSession& session_;
  std::optional<pid_t> pids_[protocol::kRoleCount];
  std::string descriptions_[protocol::kRoleCount];
  std::optional<std::size_t> expected_fem_nodes_;
  std::string expected_fem_what_;
  std::function<void(Role, pid_t)> on_hello_;
};

}  // namespace demfem::coupling
