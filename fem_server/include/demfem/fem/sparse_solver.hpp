#pragma once
// One small interface over the sparse symmetric positive definite factorisations the FEM
// uses: CHOLMOD's supernodal LLT (when the build found SuiteSparse, DEMFEM_HAVE_CHOLMOD) and
// Eigen's SimplicialLDLT as the always-available fallback. Licence note: CHOLMOD's supernodal
// module is GPL-2.0+; a binary linked with it is distributed under the GPL.

#include <memory>
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

/// @brief Factorisation of a sparse SPD matrix; the symbolic analysis is reused while the
/// sparsity pattern stays the same. solve() does not allocate.
class SparseSpdSolver {
 public:
  explicit SparseSpdSolver(SolverBackend backend = SolverBackend::automatic);
  ~SparseSpdSolver();
  SparseSpdSolver(SparseSpdSolver&&) noexcept;
  SparseSpdSolver& operator=(SparseSpdSolver&&) noexcept;

  /// Symbolic analysis (ordering) and numeric factorisation. Throws std::runtime_error
  /// (with `what` in the message) when the matrix is not positive definite.
  void factorize(const SparseMatrix& a, const std::string& what);
  /// x = A^{-1} b. x and b must have the factorised size and must not alias.
  void solve(const Eigen::VectorXd& b, Eigen::VectorXd& x);
  bool factorized() const;
  SolverBackend backend() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace demfem::fem
