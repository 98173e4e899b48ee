#pragma once
// Natural frequencies and mode shapes: K phi = omega^2 M phi on the free DOFs (clamped DOFs
// eliminated, as in the time integration), solved by shift-invert Lanczos (Spectra's
// SymGEigsShiftSolver) on the sparse factorisation of K - sigma M (SparseSpdSolver: CHOLMOD
// or Eigen's SimplicialLDLT). Small problems, or asking for nearly all modes, use a dense
// generalized eigensolver instead (Lanczos needs fewer modes than DOFs).

#include <cstdint>
#include <string>

#include <Eigen/Dense>

#include "demfem/fem/sparse_solver.hpp"

namespace demfem::fem {

/// @brief What to compute.
struct ModalOptions {
  int count = 10;            ///< modes wanted (the lowest above the shift)
  double shift = 0.0;        ///< sigma, rad^2/s^2: modes nearest it; below the lowest omega^2 (a
                             ///< negative value for a structure free to move as a rigid body)
  double tolerance = 1e-12;  ///< Lanczos relative convergence tolerance of the Ritz values
  int max_iterations = 1000;
  SolverBackend backend = SolverBackend::automatic;
};

/// @brief Modes of the free-DOF system, ascending omega^2, mass-normalised
/// (shapes^T M shapes = I, so shapes^T K shapes = diag(omega2)).
struct ModeSet {
  Eigen::VectorXd omega2;  ///< rad^2/s^2
  Eigen::MatrixXd shapes;  ///< free DOFs x count
  /// ||K phi - omega^2 M phi|| / max(||K phi||, max omega^2 ||M phi||) of each mode
  Eigen::VectorXd residual;
  std::string method;  ///< "shift-invert Lanczos (Spectra)" or "dense"
  int iterations = 0;  ///< Lanczos restarts (0 for dense)
};

/// @brief Computes the lowest `options.count` modes (nearest the shift) of K phi = w^2 M phi.
/// K symmetric positive semi-definite, M symmetric positive definite, both over the same
/// DOFs. Throws std::invalid_argument for a count outside [1, DOFs], SingularMatrixError when
/// K - sigma M cannot be factorised (a shift at an eigenvalue, or sigma = 0 for a structure
/// that can move freely), std::runtime_error when Lanczos does not converge.
ModeSet compute_modes(const SparseMatrix& k, const SparseMatrix& m, const ModalOptions& options);

}  // namespace demfem::fem
