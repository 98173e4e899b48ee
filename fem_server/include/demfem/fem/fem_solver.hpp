#pragma once
// The in-process API of the FEM engine. fem_server is a thin protocol loop around it; tests
// and benchmarks drive it directly.

#include <cstdint>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "demfem/fem/element_results.hpp"
#include "demfem/fem/fem_problem.hpp"
#include "demfem/fem/sparse_solver.hpp"
#include "demfem/interface/interface_mesh.hpp"

namespace demfem::io {
class H5File;
}

namespace demfem::fem {

/// @brief A defect of the model that the solver found: a mechanism or an unconstrained
/// rigid-body motion (the message names the nodes that move freely), a singular mass matrix,
/// a displacement larger than the model, a non-finite solution. Bad input, like a scene error:
/// fem_server exits with status 2.
class FemModelError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// @brief Spectral radius of the amplification matrix of FemSolver's Bossak-Newmark step for
/// an undamped oscillator at omega dt = `omega_dt` (>= 0): above 1 the step amplifies that
/// frequency, i.e. the scheme is unstable there. Used to check user-set gamma and beta.
double bossak_spectral_radius(const BossakParameters& bossak, double omega_dt);

/// @brief An in-memory copy of a FemSolver's state (FemSolver::save_state): what save()
/// writes, for going back to the start of an iterated coupling step (implicit coupling).
/// Reuse one object: its vectors keep their capacity.
struct FemStateCopy {
  std::vector<double> u, v, a;  ///< free DOFs: displacement, velocity, acceleration
  std::vector<double> interface_forces;
  double time = 0.0;
  std::int64_t step = -1;  ///< -1: nothing saved yet
  bool acceleration_ready = false;
};

/// @brief Linear-elastic FEM solver: static and Bossak-Newmark dynamic analysis.
class FemSolver {
 public:
  explicit FemSolver(FemProblem problem);
  /// As above with a chosen sparse factorisation (benchmarks, comparisons).
  FemSolver(FemProblem problem, SolverBackend backend);
  ~FemSolver();
  FemSolver(FemSolver&&) noexcept;
  FemSolver& operator=(FemSolver&&) noexcept;

  const FemProblem& problem() const;
  /// All DOFs (3 per node, 6 per shell node), fixed ones included.
  std::size_t dof_count() const;
  /// DOFs left after eliminating the constrained ones (the size of the solved system).
  std::size_t free_dof_count() const;
  SolverBackend solver_backend() const;

  /// The coupled surface (see interface_mesh.hpp); fixed for the solver's life.
  const InterfaceMesh& interface_mesh() const;
  /// Mesh node of each interface node (shells: the mid-surface node of a top/bottom copy).
  const std::vector<std::int32_t>& interface_mesh_nodes() const;
  /// Forces on the interface nodes (3 * interface node count, N); held until replaced.
  void set_interface_forces(std::span<const double> forces);

  /// The model checks that need a factorisation, done at set-up instead of in the first step
  /// (fem_server calls it before it attaches, so a coupled run with a bad model stops before
  /// the DEM computes anything): static, K is factorised (a mechanism or a structure the
  /// clamps do not hold throws FemModelError naming the free nodes); dynamic, the masses are
  /// checked and M is factorised. The factorisations are kept for the solves: no extra cost.
  void prepare(bool static_analysis);
  /// Static solve K u = F(t) for the current time's external and interface loads. Throws
  /// FemModelError for a singular stiffness (naming the free nodes) and for a solution larger
  /// than the model (a mechanism that survived the factorisation's pivot check).
  void solve_static();
  /// One Bossak-Newmark step from time() to time() + dt. The effective matrix is factorised
  /// on the first step and again only when dt changes.
  void advance(double dt);
  double time() const;
  std::int64_t step_count() const;

  /// Interface kinematics at the current time (each 3 * interface node count).
  void interface_kinematics(std::span<double> positions, std::span<double> velocities,
                            std::span<double> accelerations) const;

  /// Nodal fields, 3 translations per mesh node (rotations of shell nodes are internal).
  std::vector<double> displacements() const;
  std::vector<double> velocities() const;
  std::vector<double> accelerations() const;
  /// Reaction forces at constrained DOFs, 3 per mesh node (zero where free), N.
  std::vector<double> reaction_forces() const;
  ElementResults element_results() const;
  /// Kinetic energy v^T M v / 2 and strain energy u^T K u / 2 of the current state, J.
  double kinetic_energy() const;
  double strain_energy() const;

  /// Complete state for a bitwise-identical continuation (u, v, a, time, step, forces).
  void save(io::H5File& file, const std::string& group) const;
  void restore(const io::H5File& file, const std::string& group);
  /// The state of save() in memory: u, v, a (the Bossak history), interface forces, time and
  /// step. 3 doubles per free DOF; the factorisation is kept (the step size does not change).
  void save_state(FemStateCopy& copy) const;
  /// Back to the state of save_state(): the continuation is bitwise the one that followed it.
  void restore_state(const FemStateCopy& copy);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace demfem::fem
