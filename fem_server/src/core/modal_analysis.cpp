// Shift-invert Lanczos for the lowest modes (see modal_analysis.hpp).
#include "demfem/fem/modal_analysis.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>
#include <vector>

#include <Spectra/MatOp/SparseSymMatProd.h>
#include <Spectra/SymGEigsShiftSolver.h>

namespace demfem::fem {

namespace {

/// Spectra's operator y = (K - sigma M)^{-1} x, on our sparse factorisation (so CHOLMOD
/// serves when the build has it, and a singular shifted matrix is refused as everywhere).
class ShiftInvertOp {
 public:
  using Scalar = double;
  ShiftInvertOp(const SparseMatrix& k, const SparseMatrix& m, SolverBackend backend)
      : k_(k), m_(m), solver_(backend), x_(k.rows()), y_(k.rows()) {}
  Eigen::Index rows() const { return k_.rows(); }
  Eigen::Index cols() const { return k_.cols(); }
  void set_shift(double sigma) {
    const SparseMatrix a = k_ - sigma * m_;
    solver_.factorize(a, "shifted stiffness matrix K - sigma M (modal analysis)");
  }
  void perform_op(const double* in, double* out) const {
    x_ = Eigen::Map<const Eigen::VectorXd>(in, x_.size());
    solver_.solve(x_, y_);
    Eigen::Map<Eigen::VectorXd>(out, y_.size()) = y_;
  }

 private:
  const SparseMatrix& k_;
  const SparseMatrix& m_;
  mutable SparseSpdSolver solver_;
  mutable Eigen::VectorXd x_, y_;
};

ModeSet dense_modes(const SparseMatrix& k, const SparseMatrix& m, const ModalOptions& o) {
  const Eigen::MatrixXd kd(k), md(m);
  Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> es(kd, md);
  if (es.info() != Eigen::Success)
    throw std::runtime_error(
        "modal analysis: the dense eigensolver failed (is M positive "
        "definite? every DOF needs mass)");
  // The `count` eigenvalues nearest the shift, ascending.
  std::vector<Eigen::Index> order(static_cast<std::size_t>(kd.rows()));
  std::iota(order.begin(), order.end(), Eigen::Index{0});
  std::stable_sort(order.begin(), order.end(), [&](Eigen::Index a, Eigen::Index b) {
    return std::abs(es.eigenvalues()(a) - o.shift) < std::abs(es.eigenvalues()(b) - o.shift);
  });
  order.resize(static_cast<std::size_t>(o.count));
  std::sort(order.begin(), order.end(), [&](Eigen::Index a, Eigen::Index b) {
    return es.eigenvalues()(a) < es.eigenvalues()(b);
  });
  ModeSet r;
  r.method = "dense";
  r.omega2.resize(o.count);
  r.shapes.resize(kd.rows(), o.count);
  for (int j = 0; j < o.count; ++j) {
    r.omega2(j) = es.eigenvalues()(order[static_cast<std::size_t>(j)]);
    r.shapes.col(j) = es.eigenvectors().col(order[static_cast<std::size_t>(j)]);
  }
  return r;
}

}  // namespace

ModeSet compute_modes(const SparseMatrix& k, const SparseMatrix& m, const ModalOptions& o) {
  const Eigen::Index n = k.rows();
  if (k.cols() != n || m.rows() != n || m.cols() != n)
    throw std::invalid_argument("compute_modes: K and M must be square and of the same size");
  if (o.count < 1 || o.count > n)
    throw std::invalid_argument("modal analysis: " + std::to_string(o.count) +
                                " modes asked for, the model has " + std::to_string(n) +
                                " free DOFs; accepted: 1 to " + std::to_string(n));
  ModeSet r;
  // Lanczos needs a Krylov space larger than the modes wanted and smaller than the system;
  // for small systems or nearly all modes the dense solver is both exact and cheap.
  const Eigen::Index ncv = std::min<Eigen::Index>(n, std::max<Eigen::Index>(2 * o.count + 1, 20));
  if (n <= 200 || ncv >= n) {
    r = dense_modes(k, m, o);
  } else {
    ShiftInvertOp op(k, m, o.backend);
    Spectra::SparseSymMatProd<double> bop(m);
    Spectra::SymGEigsShiftSolver<ShiftInvertOp, Spectra::SparseSymMatProd<double>,
                                 Spectra::GEigsMode::ShiftInvert>
        eigs(op, bop, o.count, ncv, o.shift);
    eigs.init();
    const Eigen::Index nconv = eigs.compute(Spectra::SortRule::LargestMagn, o.max_iterations,
                                            o.tolerance, Spectra::SortRule::SmallestAlge);
    if (eigs.info() != Spectra::CompInfo::Successful || nconv < o.count)
      throw std::runtime_error("modal analysis: shift-invert Lanczos converged " +
                               std::to_string(nconv) + " of " + std::to_string(o.count) +
                               " modes in " + std::to_string(eigs.num_iterations()) +
                               " restarts; ask for fewer modes, or move fem.modal.shift");
    r.method = "shift-invert Lanczos (Spectra)";
    r.iterations = static_cast<int>(eigs.num_iterations());
    r.omega2 = eigs.eigenvalues();
    r.shapes = eigs.eigenvectors();
  }
  // Mass normalisation (Spectra returns M-orthonormal vectors already; this also fixes the
  // dense ones and makes the sign deterministic: the largest component positive).
  r.residual.resize(o.count);
  // Residuals relative to the largest omega^2 found, so that rigid-body modes (K phi ~ 0)
  // have a meaningful one too.
  const double top = std::max(r.omega2.cwiseAbs().maxCoeff(), 1e-300);
  for (int j = 0; j < o.count; ++j) {
    auto phi = r.shapes.col(j);
    const double mm = phi.dot(m * phi);
    if (!(mm > 0.0))
      throw std::runtime_error("modal analysis: mode " + std::to_string(j + 1) +
                               " has no mass (phi^T M phi = " + std::to_string(mm) + ")");
    phi /= std::sqrt(mm);
    Eigen::Index big = 0;
    phi.cwiseAbs().maxCoeff(&big);
    if (phi(big) < 0.0) phi = -phi;
    const Eigen::VectorXd kphi = k * phi;
    const Eigen::VectorXd mphi = m * phi;
    r.residual(j) = (kphi - r.omega2(j) * mphi).norm() / std::max(kphi.norm(), top * mphi.norm());
  }
  return r;
}

}  // namespace demfem::fem
