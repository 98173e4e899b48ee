// Sparse SPD factorisations (see sparse_solver.hpp).
#include "demfem/fem/sparse_solver.hpp"

#include <cmath>
#include <cstdio>
#include <stdexcept>

#include <Eigen/SparseCholesky>
#ifdef DEMFEM_HAVE_CHOLMOD
// CHOLMOD (SuiteSparse): the supernodal factorisation is GPL-2.0+ licensed.
#include <Eigen/CholmodSupport>
#endif

namespace demfem::fem {

#ifdef DEMFEM_HAVE_CHOLMOD
namespace {
/// Eigen's CHOLMOD wrapper allocates a fresh dense result on every solve; this subclass
/// reaches the factor to call cholmod_solve2 with workspaces kept between solves, so a
/// time step does not allocate.
class CholmodLlt : public Eigen::CholmodSupernodalLLT<SparseMatrix> {
 public:
  // Failures are reported by our own exception (naming the matrix), not on stderr.
  CholmodLlt() { cholmod().print = 0; }
  ~CholmodLlt() { release(); }
  /// Pivot l_jj^2 of every column of the factor, in the original row order; `failed` is the
  /// original row where the factorisation stopped (-1 if it completed).
  void pivots(Eigen::VectorXd& out, Eigen::Index& failed) const {
    const cholmod_factor* f = this->m_cholmodFactor;
    const auto n = static_cast<Eigen::Index>(f->n);
    const int* perm = static_cast<const int*>(f->Perm);
    auto original = [&](Eigen::Index k) { return perm ? static_cast<Eigen::Index>(perm[k]) : k; };
    out.setZero(n);
    failed = f->minor < f->n ? original(static_cast<Eigen::Index>(f->minor)) : -1;
    if (failed >= 0 || !f->x) return;
    const auto* x = static_cast<const double*>(f->x);
    if (f->is_super) {
      // Supernode k: columns super[k]..super[k+1]-1, a dense column-major block of
      // pi[k+1]-pi[k] rows at x + px[k]; its diagonal has stride rows + 1.
      const int* super = static_cast<const int*>(f->super);
      const int* pi = static_cast<const int*>(f->pi);
      const int* px = static_cast<const int*>(f->px);
      for (std::size_t k = 0; k < f->nsuper; ++k) {
        const int rows = pi[k + 1] - pi[k];
        for (int c = 0; c < super[k + 1] - super[k]; ++c) {
          const double l = x[px[k] + c * (rows + 1)];
          out(original(super[k] + c)) = f->is_ll ? l * l : l;
        }
      }
    } else {
      const int* p = static_cast<const int*>(f->p);
      for (Eigen::Index k = 0; k < n; ++k) {
        const double l = x[p[k]];
        out(original(k)) = f->is_ll ? l * l : l;
      }
    }
  }
  void release() {
    if (x_) cholmod_free_dense(&x_, &cholmod());
    if (y_) cholmod_free_dense(&y_, &cholmod());
    if (e_) cholmod_free_dense(&e_, &cholmod());
  }
  bool solve_into(const Eigen::VectorXd& b, Eigen::VectorXd& x) {
    cholmod_dense bd;
    bd.nrow = static_cast<std::size_t>(b.size());
    bd.ncol = 1;
    bd.nzmax = bd.nrow;
    bd.d = bd.nrow;
    bd.x = const_cast<double*>(b.data());
    bd.z = nullptr;
    bd.xtype = CHOLMOD_REAL;
    bd.dtype = CHOLMOD_DOUBLE;
    if (!cholmod_solve2(CHOLMOD_A, this->m_cholmodFactor, &bd, nullptr, &x_, nullptr, &y_, &e_,
                        &cholmod()))
      return false;
    x = Eigen::Map<const Eigen::VectorXd>(static_cast<const double*>(x_->x), b.size());
    return true;
  }

 private:
  cholmod_dense* x_ = nullptr;
  cholmod_dense* y_ = nullptr;
  cholmod_dense* e_ = nullptr;
};
}  // namespace
#endif

struct SparseSpdSolver::Impl {
  SolverBackend backend = SolverBackend::simplicial_ldlt;
  Eigen::SimplicialLDLT<SparseMatrix> ldlt;
#ifdef DEMFEM_HAVE_CHOLMOD
  CholmodLlt llt;
#endif
  bool analysed = false;
  bool done = false;
  Eigen::Index rows = -1;
  Eigen::Index nnz = -1;
  Eigen::VectorXd tmp;  // LDLT solve buffer (kept: no allocation per solve)
  double smallest_ratio = 1.0;
};

bool cholmod_available() {
#ifdef DEMFEM_HAVE_CHOLMOD
  return true;
#else
  return false;
#endif
}

std::string backend_name(SolverBackend b) {
  if (b == SolverBackend::automatic)
    b = cholmod_available() ? SolverBackend::cholmod : SolverBackend::simplicial_ldlt;
  return b == SolverBackend::cholmod ? "cholmod" : "simplicial_ldlt";
}

SparseSpdSolver::SparseSpdSolver(SolverBackend backend) : impl_(std::make_unique<Impl>()) {
  if (backend == SolverBackend::automatic)
    backend = cholmod_available() ? SolverBackend::cholmod : SolverBackend::simplicial_ldlt;
  if (backend == SolverBackend::cholmod && !cholmod_available())
    throw std::invalid_argument("sparse solver: CHOLMOD requested but this build has no CHOLMOD");
  impl_->backend = backend;
}
SparseSpdSolver::~SparseSpdSolver() = default;
SparseSpdSolver::SparseSpdSolver(SparseSpdSolver&&) noexcept = default;
SparseSpdSolver& SparseSpdSolver::operator=(SparseSpdSolver&&) noexcept = default;

namespace {

std::string row_text(Eigen::Index r) {
  return "row " + std::to_string(r);
}

/// Checks that `a` can be handed to a Cholesky factorisation at all: square, finite, with a
/// positive diagonal. Returns the diagonal.
Eigen::VectorXd checked_diagonal(const SparseMatrix& a, const std::string& what) {
  if (a.rows() != a.cols() || a.rows() == 0)
    throw std::invalid_argument("FEM: the " + what + " is " + std::to_string(a.rows()) + " x " +
                                std::to_string(a.cols()) + ", not a non-empty square matrix");
  Eigen::VectorXd d = Eigen::VectorXd::Zero(a.rows());
  for (Eigen::Index c = 0; c < a.outerSize(); ++c)
    for (SparseMatrix::InnerIterator it(a, c); it; ++it) {
      if (!std::isfinite(it.value()))
        throw SingularMatrixError("FEM: the " + what + " has a non-finite entry (" +
                                      std::to_string(it.value()) + ") in " + row_text(it.row()) +
                                      ": a material, thickness, time step or damping value "
                                      "overflowed",
                                  it.row(), 0.0);
      if (it.row() == it.col()) d(c) = it.value();
    }
  for (Eigen::Index r = 0; r < d.size(); ++r)
    if (!(d(r) > 0.0))
      throw SingularMatrixError("FEM: the " + what + " has a " +
                                    (d(r) == 0.0 ? std::string("zero") : std::string("negative")) +
                                    " diagonal entry in " + row_text(r) +
                                    ": this DOF has no stiffness (or no mass) at all",
                                r, 0.0);
  return d;
}

}  // namespace

void SparseSpdSolver::factorize(const SparseMatrix& a, const std::string& what) {
  Impl& s = *impl_;
  s.done = false;
  const Eigen::VectorXd diag = checked_diagonal(a, what);
  // Same size and non-zero count: the pattern comes from the same mesh, reuse the ordering.
  const bool same = s.analysed && s.rows == a.rows() && s.nnz == a.nonZeros();
  Eigen::VectorXd pivot;
  Eigen::Index failed = -1;
#ifdef DEMFEM_HAVE_CHOLMOD
  if (s.backend == SolverBackend::cholmod) {
    if (!same) s.llt.analyzePattern(a);
    s.llt.factorize(a);
    s.llt.pivots(pivot, failed);
  }
#endif
  if (s.backend == SolverBackend::simplicial_ldlt) {
    if (!same) s.ldlt.analyzePattern(a);
    s.ldlt.factorize(a);
    // D is in the permuted order: row i of P A P^T is row Pinv(i) of A.
    const Eigen::VectorXd& d = s.ldlt.vectorD();
    const auto& pinv = s.ldlt.permutationPinv().indices();
    pivot.setZero(a.rows());
    for (Eigen::Index i = 0; i < d.size(); ++i) pivot(pinv(i)) = d(i);
    if (s.ldlt.info() != Eigen::Success) {
      for (Eigen::Index i = 0; i < d.size() && failed < 0; ++i)
        if (!(d(i) > 0.0)) failed = pinv(i);
      if (failed < 0) failed = 0;
    }
  }
  s.analysed = true;
  s.rows = a.rows();
  s.nnz = a.nonZeros();
  Eigen::Index worst = failed;
  double ratio = 0.0;
  if (failed < 0) {
    ratio = 1.0;
    for (Eigen::Index r = 0; r < pivot.size(); ++r) {
      const double q = pivot(r) / diag(r);
      if (!(q >= ratio)) {  // also catches NaN
        ratio = std::isnan(q) ? 0.0 : q;
        worst = r;
      }
    }
  }
  if (failed >= 0 || !(ratio > 0.0))
    throw SingularMatrixError("FEM: factorisation of the " + what +
                                  " failed: the matrix is not positive definite (first failing "
                                  "pivot in " +
                                  row_text(worst) + ")",
                              worst, 0.0);
  if (ratio < kSingularPivotRatio) {
    char buf[96];
    std::snprintf(buf, sizeof buf, "%.3g of its diagonal entry (limit %g)", ratio,
                  kSingularPivotRatio);
    throw SingularMatrixError("FEM: the " + what +
                                  " is singular to working precision: the pivot of " +
                                  row_text(worst) + " is " + buf,
                              worst, ratio);
  }
  s.smallest_ratio = ratio;
  s.done = true;
}

double SparseSpdSolver::smallest_pivot_ratio() const {
  return impl_->smallest_ratio;
}

void SparseSpdSolver::solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) {
  Impl& s = *impl_;
  if (!s.done) throw std::logic_error("sparse solver: solve() before factorize()");
#ifdef DEMFEM_HAVE_CHOLMOD
  if (s.backend == SolverBackend::cholmod) {
    if (!s.llt.solve_into(b, x)) throw std::runtime_error("FEM: CHOLMOD solve failed");
    return;
  }
#endif
  // x = P^T L^-T D^-1 L^-1 P b, spelled out so that no step allocates (Eigen's solve()
  // permutes in place through a temporary mask).
  s.tmp.resize(b.size());
  x.resize(b.size());
  s.tmp.noalias() = s.ldlt.permutationP() * b;
  s.ldlt.matrixL().solveInPlace(s.tmp);
  s.tmp.array() /= s.ldlt.vectorD().array();
  s.ldlt.matrixU().solveInPlace(s.tmp);
  x.noalias() = s.ldlt.permutationPinv() * s.tmp;
}

bool SparseSpdSolver::factorized() const {
  return impl_->done;
}
SolverBackend SparseSpdSolver::backend() const {
  return impl_->backend;
}

}  // namespace demfem::fem
