#pragma once
// The [coupling] section of a scene and the coupling step that follows from [dem].dt and
// [fem].dt (thesis eq. 3.1-3.2: dt_C = dt_F = n_D dt_D). The coupler reads only [run] and
// [coupling]; it peeks read-only at [dem].dt and [fem].dt (and [fem].analysis when present)
// and leaves every other key of [dem] and [fem] to the solvers that own them.

#include <array>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "demfem/coupling/acceleration.hpp"
#include "demfem/interface/interface_mesh.hpp"
#include "demfem/scene/scene_reader.hpp"

namespace demfem::coupling {

/// The keys of [coupling] that belong to the implicit scheme (refused with any other scheme).
inline constexpr std::array<const char*, 11> kImplicitCouplingKeys = {
    "acceleration",     "max_iterations",     "displacement_tolerance", "force_tolerance",
    "displacement_abs_tolerance", "force_abs_tolerance", "on_nonconvergence",
    "initial_relaxation", "reuse_steps",      "max_columns",            "qr_filter"};

/// @brief The coupling algorithm (docs/coupling.md).
enum class Scheme : std::uint8_t {
  dem_only,        ///< no [fem]: the DEM runs alone
  fem_only,        ///< no [dem]: the FEM runs alone
  one_way_static,  ///< DEM to rest on a fixed mesh, then its forces once into a static FEM solve
  just_in_time,    ///< thesis Algorithm 3: DEM then FEM each coupling step
  predictive,      ///< thesis eq. 3.4-3.7: FEM then DEM with the predicted velocity
  concurrent,      ///< DEM and FEM at the same time, each from the other's last data
  implicit,        ///< each step iterated to convergence (Dirichlet-Neumann, accelerated)
};

/// @brief What an implicit step does when it has not converged in max_iterations.
enum class NonConvergence : std::uint8_t {
  stop,    ///< the run stops (exit status 3), as for a blow-up
  accept,  ///< the last iterate is accepted with a warning; counted in the summary
};

/// @brief The implicit scheme's keys of [coupling] (docs/coupling.md, "Implicit coupling").
struct ImplicitSettings {
  AccelerationSettings acceleration;
  std::int64_t max_iterations = 50;       ///< iterations of one step (>= 1)
  double displacement_tolerance = 1e-4;   ///< relative: |u~ - u| <= tol |u~| (2-norms)
  double force_tolerance = 1e-3;          ///< relative: |F^k - F^{k-1}| <= tol |F^k|
  double displacement_abs_tolerance = 0;  ///< m: |u~ - u| at most this also converges
  double force_abs_tolerance = 0;         ///< N: |F^k - F^{k-1}| at most this also converges
  NonConvergence on_nonconvergence = NonConvergence::stop;
};

/// @brief "one_way_static", "just_in_time", ...
const char* scheme_name(Scheme scheme);

/// @brief Optional verification of a beam under a uniform load (thesis ch. 4): after the run
/// the coupler solves the same FEM structure with the load as a pressure and prints the
/// deflections side by side with the analytical clamped-clamped value.
struct BeamCheck {
  std::array<double, 3> probe{};  ///< point whose nearest interface node is measured, m
  double load_mass = 0.0;         ///< kg
  double gravity = 9.81;          ///< m/s^2 (magnitude; the load acts along -z)
  std::string surface;            ///< FEM surface name the pressure acts on
  double length = 0.0;            ///< beam length, m (analytical formula)
  double width = 0.0;             ///< m
  double height = 0.0;            ///< m
  double youngs_modulus = 0.0;    ///< Pa
};

/// @brief The scene's [checkpoint] section (docs/reliability.md). A checkpoint is taken at
/// the first coupling-step boundary where any enabled criterion is due; without [checkpoint]
/// (or with every criterion 0) none is taken, and a crashed solver cannot be recovered.
struct CheckpointSettings {
  bool enabled = false;             ///< the section is present
  std::int64_t every_steps = 0;     ///< coupling steps between checkpoints (0 = off)
  double every_sim_time = 0.0;      ///< simulated s between checkpoints (0 = off)
  double every_wall_time = 0.0;     ///< wall-clock s between checkpoints (0 = off)
  std::int64_t keep = 3;            ///< committed checkpoints kept (K >= 1)
  std::filesystem::path directory;  ///< empty = <output_dir>/checkpoints
  std::int64_t max_retries = 3;     ///< restarts of a dying solver per checkpoint step
  /// Longest wait for a live solver's reply (a coupling step, a checkpoint, a restore), s;
  /// 0 = no limit. The heartbeat proves a solver alive, not that its step progresses: a
  /// solver that hangs inside a step is treated as dead after this long. Applies with or
  /// without the section (without it there is nothing to recover to: the run stops).
  /// The default, an hour, is far beyond any step that makes progress (a coupling step of
  /// 10^6 DEM substeps, a factorisation of a large mesh take minutes) and bounds what a hung
  /// solver costs; at most kMaxReplyTimeout (the wait counts it in milliseconds).
  double reply_timeout = 3600.0;
};
/// Largest checkpoint.reply_timeout, s (11.6 days).
inline constexpr double kMaxReplyTimeout = 1e6;

/// @brief Everything the coupler takes from a scene.
struct CouplingSettings {
  scene::RunSettings run;
  std::filesystem::path scene_file;
  bool has_dem = false;
  bool has_fem = false;
  Scheme scheme = Scheme::dem_only;
  bool force_averaging = false;
  ImplicitSettings implicit;  ///< scheme == implicit
  /// FEM-only runs: a single static solve (from [fem].analysis = "static").
  bool fem_static = false;
  /// [fem].analysis = "modal": the natural frequencies, computed by the launcher itself (no
  /// solver process, no coupling steps).
  bool fem_modal = false;
  /// [fem].backend: "fem", "modal", "rigid" (fem_server serves them) or "external" (the
  /// program of fem.command); `demfem run --fem-backend` overrides it (docs/backends.md).
  std::string fem_backend = "fem";
  /// [fem].command of an external backend: program and arguments as the scene gives them, and
  /// where (for messages).
  std::vector<std::string> fem_command;
  std::string fem_command_where;
  /// [dem].backend: "cpu", "cuda" (dem_server) or "external" (the program of dem.command, on
  /// the SDK's DEM side); `demfem run --dem-backend` overrides it (docs/backends.md).
  std::string dem_backend = "cpu";
  /// [dem].command of an external DEM: program and arguments, and where (for messages).
  std::vector<std::string> dem_command;
  std::string dem_command_where;
  bool dem_external() const { return has_dem && dem_backend == "external"; }
  bool fem_external() const { return has_fem && fem_backend == "external"; }

  double dem_dt = 0.0;            ///< [dem].dt, s
  double dem_settle_time = 0.0;   ///< [dem].settle_time, s: run before the DEM attaches
  double fem_dt = 0.0;            ///< [fem].dt, s
  double coupling_dt = 0.0;       ///< dt_C, s
  std::int64_t dem_substeps = 1;  ///< n_D per coupling step
  std::int64_t step_count = 0;    ///< coupling steps from start_time to run.end_time
  /// The run's clock at coupling step 0, s: 0, or the time of the DEM state a DEM-only scene
  /// continues ([dem.load] keep_time; start_clock_at). run.end_time is absolute.
  double start_time = 0.0;
  /// Why the clock starts at start_time, for messages: "file:line: key 'dem.load.keep_time'".
  std::string start_time_where;

  // one_way_static: the DEM runs on the fixed mesh until t >= settle_min_time and its
  // kinetic energy <= settle_kinetic_energy (0 = no criterion: until run.end_time).
  double settle_min_time = 0.0;        ///< s
  double settle_kinetic_energy = 0.0;  ///< J

  // Blow-up bounds (infinity = off).
  double max_overlap = std::numeric_limits<double>::infinity();       ///< m
  double max_energy_error = std::numeric_limits<double>::infinity();  ///< J

  std::int64_t diagnostics_interval = 1;  ///< coupling steps between CSV rows

  std::optional<BeamCheck> beam_check;
  CheckpointSettings checkpoint;

  /// The time at the start of coupling step `step` (the end of step - 1), s.
  double time_at(std::int64_t step) const {
    return start_time + static_cast<double>(step) * coupling_dt;
  }

  ForceMode force_mode() const {
    return force_averaging ? ForceMode::average : ForceMode::last_substep;
  }
};

/// @brief Relative tolerance of the n_D = dt_F / dt_D integrality check.
inline constexpr double kSubstepTolerance = 1e-9;

/// @brief Largest accepted step counts (docs/coupling.md, "Time steps"). Steps are counted in
/// 64-bit integers, but a run beyond these would not end in any useful time (a DEM step
/// costs at least a microsecond), and an end_time or dt typed wrong by orders of magnitude
/// (1e300, 1e-20) is refused before any process starts instead of overflowing or hanging.
inline constexpr std::int64_t kMaxCouplingSteps = 1'000'000'000;  ///< coupling steps of a run
inline constexpr std::int64_t kMaxDemSubsteps = 1'000'000'000;    ///< n_D of one coupling step
inline constexpr double kMaxDemSteps = scene::kMaxDemSteps;       ///< DEM steps of a run
static_assert(kMaxCouplingSteps == scene::kMaxFemSteps, "a solver alone has the same limit");

/// @brief n_D = fem_dt / dem_dt when it is an integer within kSubstepTolerance (relative)
/// and at most kMaxDemSubsteps; otherwise throws scene::SceneError naming both keys, their
/// values and the ratio.
std::int64_t dem_substeps(double fem_dt, double dem_dt, const std::string& fem_where,
                          const std::string& dem_where);

/// @brief Number of steps of `dt` that reach `end_time` (the last step may end past it when
/// end_time is not a multiple of dt within 1e-9). Saturates at INT64_MAX (the caller refuses
/// counts above kMaxCouplingSteps).
std::int64_t steps_to_reach(double end_time, double dt);

/// @brief Starts the run's clock at `time` (s) instead of 0: the DEM of a DEM-only scene
/// continues a loaded state at its time ([dem.load] keep_time, docs/scene_dem.md). run.end_time
/// stays the absolute end, so step_count becomes the steps from `time` to it. `where` says why
/// (the key), for messages. Throws scene::SceneError naming run.end_time and `where` when
/// run.end_time is not at least one DEM step after `time`.
void start_clock_at(CouplingSettings& s, double time, const std::string& where);

/// @brief Why a checkpoint of a run whose clock started at `checkpoint_start` (s; coupler.h5
/// attribute start_time, 0 where a checkpoint lacks it) cannot be continued by a run of `s`:
/// empty when the two start alike (the steps' times follow from the start).
std::string start_time_mismatch(const CouplingSettings& s, double checkpoint_start);

/// True when a solver's table ([dem] or [fem]) names backend = "external": the table then
/// belongs to the outside program (docs/backends.md), and demfem's own readers keep out of it.
bool names_external_backend(const std::optional<scene::Table>& solver);

/// @brief Reads [run] and [coupling] (strictly) and the step sizes. Throws scene::SceneError
/// naming file, line and key.
CouplingSettings read_coupling_settings(const scene::Document& scene);

}  // namespace demfem::coupling
