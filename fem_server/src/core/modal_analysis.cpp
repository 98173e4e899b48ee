// Shift-invert Lanczos for the lowest modes (see modal_analysis.hpp).
#include "demfem/fem/modal_analysis.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
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

/// Speed of the dense generalized eigensolver (Eigen, one core), measured on the development
/// machine (3000 DOFs: 28 s of CPU; docs/scene_fem.md, "Modal analysis"): only for the
/// estimate in the warning.
constexpr double kDenseFlopsPerSecond = 1.0e10;

std::string gigabytes(double bytes) {
  char text[32];
  std::snprintf(text, sizeof text, "%.3g GB", bytes / 1e9);
  return text;
}

}  // namespace

bool uses_dense_modes(std::int64_t dofs, int count) {
  const std::int64_t ncv = std::min<std::int64_t>(dofs, std::max<std::int64_t>(2 * count + 1, 20));
  return dofs <= 200 || ncv >= dofs;
}

int max_lanczos_modes(std::int64_t dofs) {
  if (dofs <= 200) return 0;
  // ncv = max(2 count + 1, 20) < dofs
  return static_cast<int>(std::min<std::int64_t>((dofs - 2) / 2, 1 << 30));
}

DenseModesCost dense_modes_cost(std::int64_t dofs) {
  const double n = static_cast<double>(dofs);
  return {6.0 * n * n * sizeof(double), 10.0 * n * n * n / kDenseFlopsPerSecond};
}

std::string dense_modes_warning(std::int64_t dofs, int count) {
  if (dofs <= 200 || !uses_dense_modes(dofs, count)) return {};
  const DenseModesCost c = dense_modes_cost(dofs);
  char text[600];
  std::snprintf(text, sizeof text,
                "%d modes of %lld free DOFs: more than shift-invert Lanczos can compute (at most "
                "%d: its Krylov space of 2 x modes + 1 vectors must be smaller than the model), "
                "so the dense eigensolver runs instead: about %s of memory and of the order of "
                "%.0f s (it grows as DOFs^3); ask for at most %d modes to keep Lanczos",
                count, static_cast<long long>(dofs), max_lanczos_modes(dofs),
                gigabytes(c.bytes).c_str(), c.seconds, max_lanczos_modes(dofs));
  return text;
}

std::uint64_t available_memory_bytes() {
  std::ifstream in("/proc/meminfo");
  std::string key;
  std::uint64_t value = 0;
  std::string unit;
  while (in >> key >> value) {
    std::getline(in, unit);
    if (key == "MemAvailable:") return value * 1024;  // kB
  }
  return 0;
}

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
  if (uses_dense_modes(n, o.count)) {
    const DenseModesCost cost = dense_modes_cost(n);
    const std::uint64_t avail = o.memory_available ? o.memory_available : available_memory_bytes();
    if (avail > 0 && cost.bytes > static_cast<double>(avail)) {
      const int most = max_lanczos_modes(n);
      throw std::invalid_argument(
          "modal analysis: " + std::to_string(o.count) + " modes of " + std::to_string(n) +
          " free DOFs need the dense eigensolver (" +
          (most > 0 ? "shift-invert Lanczos computes at most " + std::to_string(most) + " of them"
                    : std::string("the model is small")) +
          "), whose matrices take " + gigabytes(cost.bytes) + ", more than the " +
          gigabytes(static_cast<double>(avail)) + " of memory available (MemAvailable)" +
          (most > 0 ? "; ask for at most " + std::to_string(most) + " modes" : std::string()));
    }
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
