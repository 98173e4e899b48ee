// Sparse SPD factorisations (see sparse_solver.hpp).
#include "demfem/fem/sparse_solver.hpp"

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

void SparseSpdSolver::factorize(const SparseMatrix& a, const std::string& what) {
  Impl& s = *impl_;
  s.done = false;
  // Same size and non-zero count: the pattern comes from the same mesh, reuse the ordering.
  const bool same = s.analysed && s.rows == a.rows() && s.nnz == a.nonZeros();
  bool ok = false;
#ifdef DEMFEM_HAVE_CHOLMOD
  if (s.backend == SolverBackend::cholmod) {
    if (!same) s.llt.analyzePattern(a);
    s.llt.factorize(a);
    ok = s.llt.info() == Eigen::Success;
  }
#endif
  if (s.backend == SolverBackend::simplicial_ldlt) {
    if (!same) s.ldlt.analyzePattern(a);
    s.ldlt.factorize(a);
    ok = s.ldlt.info() == Eigen::Success && (s.ldlt.vectorD().array() > 0).all();
  }
  s.analysed = true;
  s.rows = a.rows();
  s.nnz = a.nonZeros();
  if (!ok)
    throw std::runtime_error("FEM: factorisation of the " + what +
                             " failed: the matrix is not positive definite (a rigid-body "
                             "motion not constrained, or zero density/stiffness?)");
  s.done = true;
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
