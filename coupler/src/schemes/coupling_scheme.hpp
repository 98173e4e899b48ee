#pragma once
// The coupling schemes (docs/coupling.md): how one coupling step t_i -> t_i+1 moves the two
// solvers and the interface data between them. One class per family, as preCICE has them:
//   SingleSolverScheme   dem_only, fem_only: one solver, nothing exchanged
//   OneWayStaticScheme   one_way_static: the DEM settles on a fixed mesh, then one static FEM solve
//   SerialScheme         just_in_time (DEM then FEM), predictive (FEM then DEM)
//   ConcurrentScheme     concurrent: both at once, each from the other's data at t_i
//   ImplicitScheme       implicit: each step iterated to convergence, with an Acceleration
// A scheme holds no output and no checkpoint machinery: it advances the solvers through its
// StepExchange and keeps its history in SchemeState (and, for the implicit one, in its
// accelerator, which it saves and loads with a checkpoint). Private to the coupling library.

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "demfem/coupling/coupling_run.hpp"
#include "schemes/scheme_state.hpp"
#include "schemes/step_exchange.hpp"

namespace demfem::io {
class H5File;
}

namespace demfem::coupling {

/// @brief What a scheme works with: the run's settings, the solvers, the interface history,
/// and the run's totals (the implicit scheme counts its iterations there).
struct SchemeContext {
  const CouplingSettings& settings;
  StepExchange& exchange;
  SchemeState& state;
  const std::vector<double>& reference_positions;  ///< the interface mesh's, m (3n)
  RunSummary& summary;
  std::function<void(const std::string&)> report;  ///< warnings of the run (stderr)
};

/// @brief One coupling scheme: advances both solvers over one coupling step.
class CouplingScheme {
 public:
  explicit CouplingScheme(const SchemeContext& context) : ctx_(context) {}
  virtual ~CouplingScheme() = default;
  CouplingScheme(const CouplingScheme&) = delete;
  CouplingScheme& operator=(const CouplingScheme&) = delete;

  /// Coupling step `d.step` from t = dem_cmd.time: the solvers advanced, their outcome in `d`
  /// and in the state, the interface work, drift and force sum of the step in `d`.
  void step(StepCommand dem_cmd, StepCommand fem_cmd, StepDiagnostics& d);

  /// The wall time of step `d` spent waiting for the solvers (one after the other: the sum).
  virtual double solver_wall(const StepDiagnostics& d) const { return d.wall_dem + d.wall_fem; }
  /// Why the run must stop after this step's checks ("" to go on); asked once per step.
  virtual std::string take_stop_reason() { return {}; }
  /// The scheme's history beyond SchemeState, into / from a checkpoint's coupler.h5.
  virtual void save_history(io::H5File& /*file*/) const {}
  virtual void load_history(const io::H5File& /*file*/) {}

 protected:
  /// Moves the solvers over the step (the scheme's order and data).
  virtual void advance(StepCommand dem_cmd, StepCommand fem_cmd, StepDiagnostics& d) = 0;
  /// The interface work both sides did in the step, the drift between their copies of the
  /// interface at its end; the accepted FEM positions become the step's start of the next.
  virtual void account_interface(StepDiagnostics& d);

  /// The DEM's step starts from the FEM's state at t_i: its positions, velocities and
  /// accelerations into the shared buffer (the DEM moves the mesh by x + v tau + a tau^2/2).
  void hand_fem_kinematics_to_dem(StepCommand& dem_cmd);

  const CouplingSettings& settings() const { return ctx_.settings; }
  StepExchange& exchange() { return ctx_.exchange; }
  InterfaceBuffers& buffers() { return ctx_.exchange.buffers(); }
  SchemeState& state() { return ctx_.state; }
  std::size_t interface_values() const { return ctx_.exchange.interface_values(); }
  bool coupled() const { return ctx_.settings.has_dem && ctx_.settings.has_fem; }

  const SchemeContext ctx_;
};

/// @brief The scheme of `context.settings.scheme`. Throws scene::SceneError when the
/// solvers cannot run it (an implicit scheme over solvers that cannot iterate).
std::unique_ptr<CouplingScheme> make_coupling_scheme(const SchemeContext& context);

/// @brief Trapezoidal work of node forces that change linearly from f0 to f1 over the node
/// displacement x1 - x0 (the same rule on both sides, so their difference is the scheme's), J.
double trapezoid_work(std::span<const double> f0, std::span<const double> f1,
                      std::span<const double> x0, std::span<const double> x1);

/// @brief The largest distance between the same node in `a` and `b`, m.
double max_node_distance(std::span<const double> a, std::span<const double> b);

}  // namespace demfem::coupling
