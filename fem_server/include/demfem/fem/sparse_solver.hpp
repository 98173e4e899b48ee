#pragma once
// One small interface over the sparse symmetric positive definite factorisations the FEM
// uses: CHOLMOD's supernodal LLT (when the build found SuiteSparse, DEMFEM_HAVE_CHOLMOD) and
// Eigen's SimplicialLDLT as the always-available fallback. Licence note: CHOLMOD's supernodal
// module is GPL-2.0+; a binary linked with it is distributed under the GPL.

#include <memory>
#include <stdexcept>
#include <string>

#include <Eigen/SparseCore>

namespace demfem::fem {

using SparseMatrix = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;

enum class SolverBackend : std::uint8_t {
  automatic,        ///< CHOLMOD when available, else SimplicialLDLT
  cholmod,          ///< CHOLMOD supernodal LLT (throws if not built in)
  simplicial_ldlt,  ///< Eigen::SimplicialLDLT
};

/// @brief Name of a backend ("cholmod", "simplicial_ldlt"); automatic is resolved first.
std::string backend_name(SolverBackend backend);
/// @brief True when the build links CHOLMOD.
bool cholmod_available();

/// @brief factorize() found the matrix singular or not positive definite. `row` is the row
/// (of the factorised matrix) where it showed: a zero, negative or non-finite diagonal entry,
/// a pivot that failed, or the pivot with the smallest ratio pivot / diagonal entry; -1 when
/// not known. The caller maps the row to a node and a DOF for its message.
class SingularMatrixError : public std::runtime_error {
 public:
  SingularMatrixError(const std::string& message, Eigen::Index row_, double pivot_ratio_)
      : std::runtime_error(message), row(row_), pivot_ratio(pivot_ratio_) {}
  Eigen::Index row;
  double pivot_ratio;  ///< pivot / diagonal entry at `row` (0 for a zero or failed pivot)
};

/// Pivots (LDL^T: d_i; LL^T: l_ii^2) smaller than this fraction of their diagonal entry a_ii
/// mean that a_ii was cancelled to round-off by the rows eliminated before: the matrix is
/// singular to working precision (a mechanism, an unconstrained rigid-body motion). Legitimate
/// models stay far above it: the smallest ratio over the FEM test suite is 2.5e-6 (see
/// docs/reliability.md); a hinge gives 1e-16..1e-13.
inline constexpr double kSingularPivotRatio = 1e-14;

/// @brief Factorisation of a sparse SPD matrix; the symbolic analysis is reused while the
/// sparsity pattern stays the same. solve() does not allocate. factorize() refuses (with
/// SingularMatrixError) a matrix with a non-finite entry, a non-positive diagonal entry, a
/// failed pivot or a pivot ratio below kSingularPivotRatio, instead of handing such a matrix
/// to the factorisation (a zero matrix crashed CHOLMOD) or returning garbage solutions.
class SparseSpdSolver {
 public:
  explicit SparseSpdSolver(SolverBackend backend = SolverBackend::automatic);
  ~SparseSpdSolver();
  SparseSpdSolver(SparseSpdSolver&&) noexcept;
  SparseSpdSolver& operator=(SparseSpdSolver&&) noexcept;

  /// Symbolic analysis (ordering) and numeric factorisation. Throws SingularMatrixError
  /// (with `what` in the message) when the matrix is not positive definite.
  void factorize(const SparseMatrix& a, const std::string& what);
  /// Smallest pivot / diagonal ratio of the last successful factorisation (1 = diagonal).
  double smallest_pivot_ratio() const;
  /// x = A^{-1} b. x and b must have the factorised size and must not alias.
  void solve(const Eigen::VectorXd& b, Eigen::VectorXd& x);
  bool factorized() const;
  SolverBackend backend() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace demfem::fem
