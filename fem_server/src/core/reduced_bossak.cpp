#include "demfem/fem/reduced_bossak.hpp"

#include <stdexcept>
#include <string>

namespace demfem::fem {

ReducedBossak::ReducedBossak(Eigen::MatrixXd mass, Eigen::MatrixXd stiffness,
                             Eigen::MatrixXd extra_damping, RayleighDamping rayleigh,
                             BossakParameters bossak)
    : m_(std::move(mass)),
      k_(std::move(stiffness)),
      cm_(rayleigh.mass_factor),
      ck_(rayleigh.stiffness_factor),
      b_(bossak) {
  if (m_.rows() != m_.cols() || k_.rows() != m_.rows() || k_.cols() != m_.rows())
    throw std::invalid_argument("ReducedBossak: M and K must be square and of one size");
  c_ = cm_ * m_ + ck_ * k_;
  if (extra_damping.size() > 0) {
    if (extra_damping.rows() != m_.rows() || extra_damping.cols() != m_.rows())
      throw std::invalid_argument("ReducedBossak: the extra damping has the wrong size");
    c_ += extra_damping;
  }
  mass_llt_.compute(m_);
  if (mass_llt_.info() != Eigen::Success || !(mass_llt_.vectorD().minCoeff() > 0.0))
    throw std::runtime_error("ReducedBossak: the reduced mass matrix is not positive definite");
}

void ReducedBossak::init_acceleration(ReducedState& s, const Eigen::VectorXd& f) const {
  s.a = mass_llt_.solve(f - c_ * s.v - k_ * s.u);
}

void ReducedBossak::advance(ReducedState& s, const Eigen::VectorXd& f, double dt) {
  if (!(dt > 0.0)) throw std::invalid_argument("ReducedBossak::advance: dt must be > 0");
  if (dt != dt_factorised_) {
    // (1 - alpha) M + gamma dt C + beta dt^2 K, with C = cm M + ck K (+ extra), as FemSolver.
    eff_.compute((1.0 - b_.alpha) * m_ + b_.gamma * dt * c_ + b_.beta * dt * dt * k_);
    dt_factorised_ = dt;
  }
  const Eigen::VectorXd ut = s.u + dt * s.v + (dt * dt * (0.5 - b_.beta)) * s.a;
  const Eigen::VectorXd vt = s.v + (dt * (1.0 - b_.gamma)) * s.a;
  // A a1 = f1 - M alpha a0 - C vt - K ut
  const Eigen::VectorXd a1 = eff_.solve(f - m_ * (b_.alpha * s.a) - c_ * vt - k_ * ut);
  s.u = ut + (b_.beta * dt * dt) * a1;
  s.v = vt + (b_.gamma * dt) * a1;
  s.a = a1;
}

void ReducedBossak::solve_static(ReducedState& s, const Eigen::VectorXd& f) const {
  Eigen::LDLT<Eigen::MatrixXd> k(k_);
  if (k.info() != Eigen::Success ||
      !(k.vectorD().cwiseAbs().minCoeff() > 1e-14 * k.vectorD().cwiseAbs().maxCoeff()))
    throw std::runtime_error(
        "the reduced stiffness matrix is singular: the model is not held "
        "against every rigid-body motion");
  s.u = k.solve(f);
  s.v.setZero(s.u.size());
  s.a.setZero(s.u.size());
}

}  // namespace demfem::fem
