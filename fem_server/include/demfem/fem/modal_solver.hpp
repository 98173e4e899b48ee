#pragma once
// The structure reduced to its first N modes plus a static correction for the loads: the
// engine of the modal-reduced FEM backend (fem.backend = "modal", docs/backends.md).
//
//   u(t) = Phi q(t) + R L g(t),   R = K^-1 - Phi Omega^-2 Phi^T  (residual flexibility)
//
// Phi (free DOFs x N, mass-normalised) and Omega^2 come from compute_modes. The loads are
// F(t) = L w(t) with the load basis L = [B, f_const, f_1 .. f_m]: B maps the 3 n interface
// forces to the DOFs (interface_load_matrix), f_const is the self weight and the constant
// loads, f_k the loads with an amplitude; w = [interface forces, 1, amplitude_k(t)].
// Each modal coordinate obeys q'' + (cm + ck w^2) q' + w^2 q = phi^T F and is integrated by
// FemSolver's Bossak-Newmark step (ReducedBossak), so that with N = all free DOFs the model
// is the full FEM to round-off. The truncated modes are taken as quasi-static: the limit of
// the same Bossak step for w -> infinity, which with stiffness-proportional damping is
// g + ck g' = w (a lag of ck), integrated with the same Newmark relations. This explicit
// static correction (residual flexibility) gives the exact static solution K^-1 F for any N.
// Everything a coupling step needs is precomputed over the interface: Phi_I = B^T Phi
// (3n x N), P = Phi^T L (N x n_L) and S = L^T R L (n_L x n_L, whose first 3n rows are the
// interface rows of R L); a step costs O(N n_L + n_L^2 / 3), independent of the mesh. Full
// fields (output, checkpoints) need one solve with the factorised K each.

#include <cstdint>
#include <memory>
#include <span>
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

/// @brief [fem.modal] of a scene: the modal analysis and the modal-reduced backend.
struct ModalSettings {
  int modes = 20;  ///< N
  /// sigma, rad^2/s^2: the analysis finds the modes nearest it (negative for a structure that
  /// can move freely); the backend always uses the lowest modes (sigma = 0)
  double shift = 0.0;
  bool static_correction = true;  ///< the residual-flexibility term R L g
  SolverBackend backend = SolverBackend::automatic;
};

class ModalSolver {
 public:
  /// Assembles, factorises K, computes the modes and the interface matrices. Throws
  /// FemModelError for a structure its clamps do not hold (K singular: the static correction
  /// needs K^-1), a massless material or prescribed displacements (as dynamics does), and
  /// std::invalid_argument for N outside [1, free DOFs].
  ModalSolver(FemProblem problem, ModalSettings settings);
  ~ModalSolver();
  ModalSolver(ModalSolver&&) noexcept;
  ModalSolver& operator=(ModalSolver&&) noexcept;

  const FemProblem& problem() const;
  const ModalSettings& settings() const;
  int mode_count() const;
  /// omega^2 of the modes, rad^2/s^2, ascending.
  const Eigen::VectorXd& omega2() const;
  std::size_t free_dof_count() const;
  /// Entries of the load basis: 3 n interface force components + 1 + loads with amplitudes.
  std::size_t load_count() const;
  const InterfaceMesh& interface_mesh() const;
  void set_interface_forces(std::span<const double> forces);

  /// Static response to the loads at time(): the exact K^-1 F with the static correction.
  void solve_static();
  /// One Bossak-Newmark step of every modal coordinate (and of the correction) to time() + dt.
  void advance(double dt);
  double time() const;
  std::int64_t step_count() const;

  /// Interface kinematics (3 per interface node), O(3 n (N + n_L)).
  void interface_kinematics(std::span<double> positions, std::span<double> velocities,
                            std::span<double> accelerations) const;
  /// Largest |u| over the interface nodes, m (the step diagnostic; no full field is formed).
  double max_interface_displacement() const;

  /// Full fields reconstructed from the modes (3 translations per mesh node): one solve with
  /// the factorised K each (output steps only).
  std::vector<double> displacements() const;
  std::vector<double> velocities() const;
  std::vector<double> accelerations() const;
  ElementResults element_results() const;
  /// q'^T q' / 2 (the correction carries no inertia) and (sum w^2 q^2 + g^T S g) / 2, J.
  double kinetic_energy() const;
  double strain_energy() const;

  /// Writes `group` in FemSolver's layout (the reconstructed full u, v, a over the free DOFs:
  /// what another FEM backend restores) and `group`_modal with the modal state.
  void save(io::H5File& file, const std::string& group) const;
  /// From this backend's own state when the file has it for the same modes (a bitwise
  /// continuation); otherwise from the full state in `group` (written by FemSolver, or by a
  /// ModalSolver with other modes): q = Phi^T M u (and v, a), the correction at the loads of
  /// that time. restore_report() then says how far the projection is from the full state.
  void restore(const io::H5File& file, const std::string& group);
  /// Empty after a restore of its own state; otherwise what the projection lost.
  const std::string& restore_report() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace demfem::fem
