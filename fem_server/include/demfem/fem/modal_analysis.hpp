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
  /// Bytes the dense eigensolver may take; 0 = MemAvailable of /proc/meminfo (tests set it).
  std::uint64_t memory_available = 0;
};

/// @brief Whether compute_modes uses the dense eigensolver for `count` modes of `dofs` free
/// DOFs: small models (at most 200 DOFs), and requests Lanczos cannot take (its Krylov space
/// of max(2 count + 1, 20) vectors must be smaller than the system).
bool uses_dense_modes(std::int64_t dofs, int count);

/// @brief The most modes shift-invert Lanczos computes for `dofs` free DOFs (more go to the
/// dense solver); 0 when the model is small enough to be always solved densely.
int max_lanczos_modes(std::int64_t dofs);

/// @brief What the dense eigensolver costs for `dofs` free DOFs: `bytes` for its dense
/// matrices (K, M, the eigenvectors and the solver's work copies: 6 n^2 doubles) and a rough
/// `seconds` (about 10 n^3 floating-point operations at kDenseFlopsPerSecond).
struct DenseModesCost {
  double bytes = 0.0;
  double seconds = 0.0;
};
DenseModesCost dense_modes_cost(std::int64_t dofs);

/// @brief The warning for a request that switches to the dense solver although the model is
/// large (more than 200 free DOFs): why, its memory and time estimates, and the mode count
/// that keeps Lanczos. Empty when Lanczos serves or the model is small.
std::string dense_modes_warning(std::int64_t dofs, int count);

/// @brief MemAvailable of /proc/meminfo in bytes; 0 when it cannot be read.
std::uint64_t available_memory_bytes();

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
/// DOFs. Throws std::invalid_argument for a count outside [1, DOFs] or when the dense solver
/// would need more memory than `options.memory_available`, SingularMatrixError when
/// K - sigma M cannot be factorised (a shift at an eigenvalue, or sigma = 0 for a structure
/// that can move freely), std::runtime_error when Lanczos does not converge.
ModeSet compute_modes(const SparseMatrix& k, const SparseMatrix& m, const ModalOptions& options);

}  // namespace demfem::fem
