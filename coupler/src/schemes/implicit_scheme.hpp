#pragma once
// implicit: every coupling step iterated to convergence as a Dirichlet-Neumann fixed point on
// the interface displacement at t_i+1, the next iterate from an Acceleration (constant or
// Aitken under-relaxation, IQN-ILS; acceleration.hpp), whose history is part of the scheme's
// and goes into a checkpoint with it. preCICE's implicit coupling with its acceleration/.
// Private to the coupling library.

#include <memory>
#include <string>
#include <vector>

#include "demfem/coupling/acceleration.hpp"
#include "schemes/coupling_scheme.hpp"

namespace demfem::coupling {

/// @brief The implicit scheme with its accelerator; iteration counts go into the run's
/// totals (RunSummary: iterations, max_iterations, unconverged_steps).
class ImplicitScheme : public CouplingScheme {
 public:
  /// Throws scene::SceneError when a solver cannot go back to a step's start (its Hello does
  /// not announce the capability 'iteration').
  explicit ImplicitScheme(const SchemeContext& context);

  /// A step that did not converge with coupling.on_nonconvergence = "stop".
  std::string take_stop_reason() override;
  /// The accelerator's history, group "acceleration".
  void save_history(io::H5File& file) const override;
  void load_history(const io::H5File& file) override;

 protected:
  void advance(StepCommand dem_cmd, StepCommand fem_cmd, StepDiagnostics& d) override;

 private:
  /// Both solvers over the step once, from the interface displacement u_in_ at its end.
  void iterate(StepCommand& dem_cmd, StepCommand& fem_cmd, StepDiagnostics& d);
  /// A step accepted without convergence: stop the run, or count and report it.
  void not_converged(std::int64_t iterations, const StepDiagnostics& d);

  std::unique_ptr<Acceleration> accel_;
  // Work arrays of a step (3n): the displacement given to the DEM, the one the FEM returned,
  // the accelerator's next, the forces of the iteration before, the FEM's kinematics.
  std::vector<double> u_in_, u_out_, u_next_, force_before_, fem_vel_, fem_acc_;
  std::string stop_reason_;
};

}  // namespace demfem::coupling
