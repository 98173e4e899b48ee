#pragma once
// The Bossak-Newmark step of FemSolver (thesis eq. 2.85-2.87, solved for the new acceleration,
// Rayleigh damping C = cm M + ck K) on a small dense system M a + C v + K u = f: the modal
// coordinates of ModalSolver (M = I, K = diag(omega^2)) and the six rigid-body coordinates
// of RigidSolver. The same update in the same form, so that a reduced model integrates each
// of its coordinates exactly as the full FEM integrates the same motion.

#include <Eigen/Dense>

#include "demfem/fem/fem_problem.hpp"

namespace demfem::fem {

/// @brief State of a reduced system: displacements, velocities, accelerations.
struct ReducedState {
  Eigen::VectorXd u, v, a;
  void resize(Eigen::Index n) {
    u.setZero(n);
    v.setZero(n);
    a.setZero(n);
  }
};

class ReducedBossak {
 public:
  /// `extra_damping`: added to the Rayleigh damping (e.g. dashpots); empty = none.
  ReducedBossak(Eigen::MatrixXd mass, Eigen::MatrixXd stiffness, Eigen::MatrixXd extra_damping,
                RayleighDamping rayleigh, BossakParameters bossak);

  Eigen::Index size() const { return m_.rows(); }
  const Eigen::MatrixXd& mass() const { return m_; }
  const Eigen::MatrixXd& stiffness() const { return k_; }
  const Eigen::MatrixXd& damping() const { return c_; }

  /// a = M^-1 (f - C v - K u): the acceleration of a state under the load f.
  void init_acceleration(ReducedState& s, const Eigen::VectorXd& f) const;
  /// One step of dt under the load f at its end; the effective matrix
  /// (1 - alpha) M + gamma dt C + beta dt^2 K is factorised when dt changes.
  void advance(ReducedState& s, const Eigen::VectorXd& f_end, double dt);
  /// K u = f, v = a = 0. Throws std::runtime_error when K is singular.
  void solve_static(ReducedState& s, const Eigen::VectorXd& f) const;

 private:
  Eigen::MatrixXd m_, k_, c_;
  double cm_, ck_;
  BossakParameters b_;
  Eigen::LDLT<Eigen::MatrixXd> mass_llt_, eff_;
  double dt_factorised_ = 0.0;
};

}  // namespace demfem::fem
