#pragma once
// The coupling run: the loop over coupling steps, written once over SolverLink (solver_link.hpp);
// the schemes themselves are classes in coupler/src/schemes/ (docs/architecture.md).
// Each coupling step sends Step commands in the scheme's order, moves forces and kinematics
// through the interface buffers, and records the diagnostics of docs/coupling.md: drift
// between the DEM and FEM copies of the interface, the interface work seen by each side, the
// largest particle-interface overlap, and the wall time of DEM, FEM and coupling. A NaN, an
// overlap or an energy error beyond its bound stops the run with a BlowUp that names the step
// and the quantity; the series written so far stay on disk.

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "demfem/coupling/coupling_settings.hpp"
#include "demfem/coupling/solver_link.hpp"

namespace demfem::coupling {

/// @brief A step that went wrong numerically; what() names the step, time and quantity.
class BlowUp : public std::runtime_error {
 public:
  BlowUp(std::int64_t step, double time, std::string quantity, double value, double bound,
         const std::string& text);
  std::int64_t step() const { return step_; }
  double time() const { return time_; }
  const std::string& quantity() const { return quantity_; }
  double value() const { return value_; }
  double bound() const { return bound_; }

 private:
  std::int64_t step_;
  double time_;
  std::string quantity_;
  double value_;
  double bound_;
};

/// @brief A solver failed or died during a coupling step; what() names the solver, the step
/// and the time, and the cause (the protocol's PeerDied / SolverError text).
class SolverFailure : public std::runtime_error {
 public:
  SolverFailure(protocol::Role role, std::int64_t step, double time, const std::string& text,
                bool died = false, protocol::ErrorKind kind = protocol::ErrorKind::failure)
      : std::runtime_error(text), role_(role), step_(step), time_(time), died_(died), kind_(kind) {}
  /// The solver process died or stopped answering (protocol::PeerDied), as opposed to
  /// reporting an error: only a death is recovered from a checkpoint (an error would repeat).
  bool died() const { return died_; }
  /// What the solver reported (protocol::SolverError, or a BackendError in process): a bad
  /// model (exit 2), a blow-up (exit 3) or a failure (exit 1).
  protocol::ErrorKind kind() const { return kind_; }
  protocol::Role role() const { return role_; }
  std::int64_t step() const { return step_; }
  double time() const { return time_; }

 private:
  protocol::Role role_;
  std::int64_t step_;
  double time_;
  bool died_;
  protocol::ErrorKind kind_;
};

/// @brief The kind of a solver's error as the coupler received it: a protocol::SolverError's
/// (three processes), a protocol::BackendError's (in process); failure for anything else.
protocol::ErrorKind error_kind_of(const std::exception& e);

/// @brief A solver kept dying: it was restarted `max_retries` times from the same
/// checkpoint and died again. what() names the solver, the checkpoint and every failure.
class RecoveryExhausted : public SolverFailure {
 public:
  using SolverFailure::SolverFailure;
};

/// @brief The run was asked to stop (signal) between two steps.
class Interrupted : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// @brief The run's output folder is no longer its own (its lock file was removed or replaced:
/// the folder was deleted, perhaps for another run): the run stops and writes nothing more
/// there, so that it cannot mix its files with another run's.
class OutputFolderLost : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// @brief The checkpoint given to --resume cannot be continued with this scene: a solver or
/// the coupler refused its state (a changed mesh or particle count, non-finite values, a
/// changed scheme). Bad input (exit status 2), not a failure of the run.
class ResumeRefused : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// @brief A solver's error text reports a blow-up (a non-finite state, an unstable
/// integration: "not finite", "blew up") rather than a failure; the launcher exits with
/// status 3 for these, as for the coupler's own blow-up checks. Only for errors of kind
/// failure: a solver that does not classify its errors (an outside backend throwing plain
/// exceptions); demfem's own solvers send ErrorKind::blow_up.
bool is_blow_up_report(const std::string& text);

/// @brief Diagnostics of one coupling step (one CSV row).
struct StepDiagnostics {
  std::int64_t step = 0;
  double time = 0.0;                  ///< s, at the step's end
  double drift = 0.0;                 ///< max node distance DEM copy vs FEM copy at step end, m
  double work_dem = 0.0;              ///< cumulative interface work as the DEM sees it, J
  double work_fem = 0.0;              ///< cumulative interface work as the FEM sees it, J
  double energy_error = 0.0;          ///< work_dem - work_fem, J
  double max_overlap = 0.0;           ///< largest particle-interface overlap of the step, m
  double dem_max_overlap = 0.0;       ///< largest overlap of any DEM contact, m
  double kinetic_energy = 0.0;        ///< DEM kinetic energy, J
  double fem_max_displacement = 0.0;  ///< max |u| reported by the FEM, m
  double force_sum_z = 0.0;           ///< sum of interface forces (z), N
  double wall_dem = 0.0;              ///< s in the DEM step (send to done)
  double wall_fem = 0.0;              ///< s in the FEM step
  double wall_coupling = 0.0;         ///< s in the coupler for this step (mapping, bookkeeping,
                                      ///< diagnostics, output)
  std::int64_t iterations = 1;        ///< iterations of the step (implicit; 1 otherwise)
  double residual_displacement = 0.0;  ///< implicit: |u~ - u| / |u~| of the last iteration
  double residual_force = 0.0;         ///< implicit: |F^k - F^{k-1}| / |F^k| of the last one
  bool converged = true;               ///< implicit: both tolerances met
  double wall_dem_compute = 0.0;       ///< s the DEM computed (its own step() time, summed)
  double wall_fem_compute = 0.0;       ///< s the FEM computed
};

/// @brief Wall-clock totals, s.
struct WallTimes {
  double total = 0.0;
  double dem = 0.0;
  double fem = 0.0;
  double coupling = 0.0;
};

/// @brief Totals of a finished (or stopped) run.
struct RunSummary {
  std::int64_t steps = 0;
  double time = 0.0;  ///< simulated time reached, s
  // Wall times of this process (this session): every step it computed, recomputed ones
  // after a recovery included, so that the shares below add up to at most the total.
  double wall_total = 0.0;  ///< s, from the first step to the last
  double wall_dem = 0.0;
  double wall_fem = 0.0;
  double wall_coupling = 0.0;
  /// A resumed run: the wall times of the earlier sessions up to the checkpoint resumed
  /// from (coupler.h5); zero for a fresh run. The whole run so far is earlier + this session.
  WallTimes earlier;
  bool settled = false;  ///< one_way_static: the settle criterion was met
  // The implicit scheme, over the whole run (a resumed run counts the earlier sessions' steps
  // up to its checkpoint too).
  std::int64_t iterations = 0;         ///< iterations of all steps
  std::int64_t max_iterations = 0;     ///< most iterations of one step
  std::int64_t unconverged_steps = 0;  ///< accepted without convergence (on_nonconvergence)
  StepDiagnostics last;
  InterfaceMesh mesh;
  std::vector<double> positions;  ///< FEM interface positions at the end (3n)
  std::vector<double> forces;     ///< last interface forces (3n)
};

/// @brief How a run starts and what it does when a solver dies (docs/reliability.md).
struct RunControl {
  /// Start from this committed checkpoint folder instead of step 0 (`--resume`).
  std::optional<std::filesystem::path> resume_from;
  /// Starts a fresh process for a solver that died and attaches it to the run (the launcher's
  /// supervisor). Empty: a dead solver ends the run. With checkpoints, the run then rolls
  /// back to the last committed checkpoint and goes on.
  std::function<void(protocol::Role role)> restart_solver;
  /// Debug/testing hook, called after a Step was sent to `role` in coupling step `step`
  /// (before its StepDone is awaited): fault injection (`demfem_run --debug-kill`).
  std::function<void(protocol::Role role, std::int64_t step)> after_send;
  /// Messages about checkpoints and recovery (stderr in demfem_run).
  std::function<void(const std::string&)> report;
  /// Called before every coupling step and checkpoint; throws OutputFolderLost when the output
  /// folder is no longer this run's (demfem_run checks its folder lock, at most once a second).
  std::function<void()> check_output_folder;
  /// Polled before every coupling step: a checkpoint asked for from outside the run
  /// (demfem_run: SIGUSR1 / SIGUSR2). With [checkpoint], one is taken at this step boundary
  /// (unless the last one is of this step); with `stop`, `stop` is called then, which makes
  /// the run end as after a stop signal (Interrupted).
  enum class CheckpointRequest { none, go_on, stop };
  std::function<CheckpointRequest()> checkpoint_request;
  std::function<void()> stop;
  /// Recorded in every checkpoint (coupler.h5): scene_hash() of the scene, so that a resume
  /// can tell a changed scene; and the absolute output folder, so that a run resumed into
  /// another folder finds the series it continues.
  std::string scene_hash;
  /// The FEM backend of the run ("fem", "modal", "rigid", "external"), recorded in every
  /// checkpoint (coupler.h5 attribute fem_backend, with the name the FEM announced in
  /// fem_backend_name), so that a resume with another backend knows what wrote fem.h5.
  std::string fem_backend;
  /// The DEM backend ("cpu", "cuda", "external"), recorded likewise (coupler.h5 attributes
  /// dem_backend and dem_backend_name): an external DEM's dem.h5 is its own format.
  std::string dem_backend;
};

/// @brief Counts of the reliability machinery in one run.
struct RecoveryStats {
  std::int64_t checkpoints = 0;    ///< committed
  double checkpoint_wall = 0.0;    ///< s spent writing them
  std::int64_t recoveries = 0;     ///< solver restarts + rollbacks
  double recovery_wall = 0.0;      ///< s from the failure to the restored state
  std::int64_t resumed_from = -1;  ///< step of the checkpoint resumed from (-1 = none)
};

/// @brief Called after every coupling step (progress display).
using StepObserver = std::function<void(const StepDiagnostics&, const CouplingSettings&)>;

/// @brief Runs a scene's coupling loop over `link`.
class CouplingRun {
 public:
  /// `output_dir`: where coupling.csv and coupling.h5 go (created). `stop`: polled between
  /// steps; when set, the run ends with Interrupted.
  CouplingRun(SolverLink& link, const CouplingSettings& settings, std::filesystem::path output_dir,
              const std::atomic<bool>* stop = nullptr);

  void set_observer(StepObserver observer) { observer_ = std::move(observer); }
  void set_control(RunControl control) { control_ = std::move(control); }
  const RecoveryStats& recovery_stats() const { return stats_; }

  /// Runs to the end; with [checkpoint], takes a last checkpoint at the end (so that a finished
  /// run can be continued with a later run.end_time). Throws BlowUp, Interrupted,
  /// ResumeRefused, or protocol errors; the CSV written so far is flushed and coupling.h5
  /// holds the state of the last step in every case.
  RunSummary run();

 private:
  SolverLink& link_;
  const CouplingSettings& settings_;
  std::filesystem::path output_dir_;
  const std::atomic<bool>* stop_;
  StepObserver observer_;
  RunControl control_;
  RecoveryStats stats_;
};

/// @brief The checkpoint folder of a run: [checkpoint].directory (relative to the output
/// folder) or <output_dir>/checkpoints.
std::filesystem::path checkpoint_directory(const CouplingSettings& settings,
                                           const std::filesystem::path& output_dir);

/// @brief The parts a checkpoint of this run must hold (dem.h5 / fem.h5 / coupler.h5).
std::vector<std::string> checkpoint_parts(const CouplingSettings& settings);

/// @brief Index of the interface node nearest to `point` (ties: the lowest index).
std::size_t nearest_node(const InterfaceMesh& mesh, const std::array<double, 3>& point);

}  // namespace demfem::coupling
