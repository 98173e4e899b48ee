// Modal-reduced structure with a static correction (see modal_solver.hpp).
#include "demfem/fem/modal_solver.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "demfem/fem/assembly.hpp"
#include "demfem/fem/fem_solver.hpp"
#include "demfem/fem/modal_analysis.hpp"
#include "demfem/fem/reduced_bossak.hpp"
#include "demfem/io/h5_file.hpp"

namespace demfem::fem {

using Eigen::MatrixXd;
using Eigen::VectorXd;

namespace {

/// Largest S = L^T R L held in memory (n_L^2 doubles): beyond it the interface is too large
/// for a dense residual flexibility.
constexpr double kMaxCorrectionBytes = 4e9;

std::span<const double> span_of(const VectorXd& x) {
  return {x.data(), static_cast<std::size_t>(x.size())};
}

}  // namespace

struct ModalSolver::Impl {
  FemProblem problem;
  ModalSettings settings;
  DofMap dofs;
  SparseMatrix m;            // reduced mass (projections)
  SparseSpdSolver k_solver;  // factorised reduced K (full fields, the correction)
  InterfaceMap iface;
  SparseMatrix b;  // free DOFs x 3n
  VectorXd f_const;
  std::vector<VectorXd> f_timed;
  std::vector<TimeFunction> amplitudes;
  MatrixXd phi;     // free DOFs x N
  VectorXd omega2;  // N
  MatrixXd phi_i;   // 3n x N
  MatrixXd p;       // N x n_L
  MatrixXd s;       // n_L x n_L (zero without the correction)
  std::unique_ptr<ReducedBossak> bossak;

  SparseMatrix stiffness;    // reduced stiffness (the transient's energy)
  SparseSpdSolver m_solver;  // factorised reduced mass (truncated initial accelerations)
  ReducedState q, g;
  ReducedState ci;  // the correction at the interface, S_I g (kept by the same recursion)
  /// The truncated modes' own motion from an initial state Z = (zu, zv, za) (free DOFs, all
  /// M-orthogonal to the modes): the initial acceleration of a fresh start (the full FEM's
  /// a0 = M^-1 F0 has a share in them) and, after a swap from a full state, the part of u, v, a
  /// the modes and the quasi-static correction do not hold. They follow the same limit
  /// recursion without load, so the motion is sum_j c[j] Z_j with coefficient triples c[j]
  /// (u, v, a) of the response to a unit initial value of component j.
  struct Transient {
    std::array<VectorXd, 3> z;   // free DOFs (empty: none)
    std::array<VectorXd, 3> zi;  // B^T z: at the interface
    std::array<std::array<double, 3>, 3> c{};
    MatrixXd lz;  // L^T Z (n_L x 3): coupling to the correction's energy
    Eigen::Matrix3d kzz = Eigen::Matrix3d::Zero(),
                    mzz = Eigen::Matrix3d::Zero();  // Z^T K Z, Z^T M Z
    bool active() const { return z[0].size() > 0; }
  } tr;
  std::vector<double> forces;
  double time = 0.0;
  std::int64_t step = 0;
  bool accel_ready = false;
  double last_dt = 0.0;
  std::string report;

  std::size_t n3() const { return 3 * iface.mesh_node.size(); }
  Eigen::Index nl() const { return static_cast<Eigen::Index>(n3() + 1 + f_timed.size()); }

  /// w(t) = [interface forces, 1, amplitude_k(t)].
  VectorXd weights(double t) const {
    VectorXd w(nl());
    for (std::size_t i = 0; i < forces.size(); ++i) w(static_cast<Eigen::Index>(i)) = forces[i];
    w(static_cast<Eigen::Index>(n3())) = 1.0;
    for (std::size_t k = 0; k < amplitudes.size(); ++k) {
      const double a = amplitudes[k](t);
      if (!std::isfinite(a))
        throw std::runtime_error(
            "FEM (modal): a load amplitude returned a non-finite value at t = " +
            std::to_string(t));
      w(static_cast<Eigen::Index>(n3() + 1 + k)) = a;
    }
    return w;
  }

  /// L x over the free DOFs.
  VectorXd load_basis_times(const VectorXd& x) const {
    VectorXd f = b * x.head(static_cast<Eigen::Index>(n3()));
    f += x(static_cast<Eigen::Index>(n3())) * f_const;
    for (std::size_t k = 0; k < f_timed.size(); ++k)
      f += x(static_cast<Eigen::Index>(n3() + 1 + k)) * f_timed[k];
    return f;
  }
  /// L^T y (y over the free DOFs).
  VectorXd load_basis_transpose_times(const VectorXd& y) const {
    VectorXd out(nl());
    out.head(static_cast<Eigen::Index>(n3())) = b.transpose() * y;
    out(static_cast<Eigen::Index>(n3())) = f_const.dot(y);
    for (std::size_t k = 0; k < f_timed.size(); ++k)
      out(static_cast<Eigen::Index>(n3() + 1 + k)) = f_timed[k].dot(y);
    return out;
  }

  /// Component k (0 u, 1 v, 2 a) of the transient at the interface or over the free DOFs.
  VectorXd transient(int k, bool interface) const {
    VectorXd x = VectorXd::Zero(interface ? static_cast<Eigen::Index>(n3())
                                          : static_cast<Eigen::Index>(dofs.free.size()));
    if (!tr.active()) return x;
    for (int j = 0; j < 3; ++j) x += tr.c[j][k] * (interface ? tr.zi[j] : tr.z[j]);
    return x;
  }

  /// Component k of the full field over the free DOFs: Phi q + R L g + transient (one K
  /// solve when the correction is on).
  VectorXd full_field(int k) const {
    const VectorXd& qx = k == 0 ? q.u : k == 1 ? q.v : q.a;
    const VectorXd& gx = k == 0 ? g.u : k == 1 ? g.v : g.a;
    VectorXd u = phi * qx + transient(k, false);
    if (settings.static_correction && gx.size() > 0 && gx.cwiseAbs().maxCoeff() > 0.0) {
      const VectorXd f = load_basis_times(gx);
      VectorXd x(f.size());
      const_cast<SparseSpdSolver&>(k_solver).solve(f, x);
      u += x - phi * (p * gx).cwiseQuotient(omega2);
    }
    return u;
  }
  std::vector<double> nodal(const VectorXd& free) const {
    const std::size_t nn = problem.mesh.nodes.size();
    std::vector<double> out(3 * nn, 0.0);
    for (std::size_t n = 0; n < nn; ++n)
      for (int c = 0; c < 3; ++c) {
        const auto r = dofs.reduced[static_cast<std::size_t>(dofs.node_offset[n] + c)];
        if (r >= 0) out[3 * n + static_cast<std::size_t>(c)] = free(r);
      }
    return out;
  }
  VectorXd expand(const VectorXd& free) const {
    VectorXd f = VectorXd::Zero(dofs.total);
    for (std::size_t i = 0; i < dofs.free.size(); ++i)
      f(dofs.free[i]) = free(static_cast<Eigen::Index>(i));
    return f;
  }
  /// Component k of the interface displacement (3n): modes + correction + transient.
  VectorXd interface_values(int k) const {
    const VectorXd& qx = k == 0 ? q.u : k == 1 ? q.v : q.a;
    const VectorXd& cx = k == 0 ? ci.u : k == 1 ? ci.v : ci.a;
    VectorXd x = phi_i * qx;
    if (settings.static_correction) x += cx;
    if (tr.active()) x += transient(k, true);
    return x;
  }

  /// One step of the Bossak recursion in its limit for w -> infinity (the truncated modes'
  /// inertia neglected): x + ck x' = rhs, with Newmark's relations for x, x', x''.
  void limit_step(ReducedState& x, const VectorXd& rhs, double dt) const {
    const auto& bp = problem.bossak;
    const double ck = problem.damping.stiffness_factor;
    const VectorXd xt = x.u + dt * x.v + (dt * dt * (0.5 - bp.beta)) * x.a;
    const VectorXd vt = x.v + (dt * (1.0 - bp.gamma)) * x.a;
    x.a = (rhs - xt - ck * vt) / (bp.beta * dt * dt + bp.gamma * dt * ck);
    x.u = xt + (bp.beta * dt * dt) * x.a;
    x.v = vt + (bp.gamma * dt) * x.a;
  }
  void limit_step(std::array<double, 3>& c, double dt) const {
    const auto& bp = problem.bossak;
    const double ck = problem.damping.stiffness_factor;
    const double xt = c[0] + dt * c[1] + dt * dt * (0.5 - bp.beta) * c[2];
    const double vt = c[1] + dt * (1.0 - bp.gamma) * c[2];
    c[2] = (0.0 - xt - ck * vt) / (bp.beta * dt * dt + bp.gamma * dt * ck);
    c[0] = xt + bp.beta * dt * dt * c[2];
    c[1] = vt + bp.gamma * dt * c[2];
  }
  /// The correction (load space and interface) and the transient over one step, to the loads
  /// w at its end.
  void correction_step(const VectorXd& w, double dt) {
    limit_step(g, w, dt);
    limit_step(ci, s.topRows(static_cast<Eigen::Index>(n3())) * w, dt);
    if (tr.active())
      for (auto& c : tr.c) limit_step(c, dt);
  }

  /// Sets the transient to start from `z` (u, v, a over the free DOFs) now.
  void start_transient(std::array<VectorXd, 3> z) {
    tr.z = std::move(z);
    for (int j = 0; j < 3; ++j) {
      tr.zi[j] = b.transpose() * tr.z[j];
      for (int k = 0; k < 3; ++k) tr.c[j][k] = j == k ? 1.0 : 0.0;
    }
    tr.lz.resize(nl(), 3);
    for (int j = 0; j < 3; ++j) tr.lz.col(j) = load_basis_transpose_times(tr.z[j]);
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        tr.kzz(i, j) = tr.z[i].dot(stiffness * tr.z[j]);
        tr.mzz(i, j) = tr.z[i].dot(m * tr.z[j]);
      }
  }
  /// Removes the share of the modes from x (x - Phi Phi^T M x): what the truncated modes hold.
  VectorXd truncated(const VectorXd& x) const { return x - phi * (phi.transpose() * (m * x)); }

  /// The initial acceleration, as FemSolver computes it (M a = F - C v - K u): the modes get
  /// theirs, the truncated modes theirs through the transient.
  void init_acceleration() {
    bossak->init_acceleration(q, p * weights(time));
    if (!settings.static_correction) return;
    const double cm = problem.damping.mass_factor, ck = problem.damping.stiffness_factor;
    const VectorXd u = full_field(0), v = full_field(1);
    const VectorXd r = load_basis_times(weights(time)) - cm * (m * v) - stiffness * (u + ck * v);
    if (!m_solver.factorized()) m_solver.factorize(m, "mass matrix (modal-reduced backend)");
    VectorXd a(r.size());
    m_solver.solve(r, a);
    const VectorXd zero = VectorXd::Zero(r.size());
    // Keep what a transient already holds (displacement and velocity of a swap).
    std::array<VectorXd, 3> z = {tr.active() ? transient(0, false) : zero,
                                 tr.active() ? transient(1, false) : zero, truncated(a)};
    start_transient(std::move(z));
  }

  void check_finite(const VectorXd& x, const char* what) const {
    if (!x.allFinite())
      throw FemModelError("FEM (modal): the " + std::string(what) +
                          " became non-finite at t = " + std::to_string(time) +
                          " s: a load, amplitude or material value overflowed");
  }
};

ModalSolver::ModalSolver(FemProblem problem, ModalSettings settings) {
  validate_problem(problem);
  impl_ = std::make_unique<Impl>();
  Impl& s = *impl_;
  s.problem = std::move(problem);
  s.settings = settings;
  s.k_solver = SparseSpdSolver(settings.backend);
  s.m_solver = SparseSpdSolver(settings.backend);
  const FemProblem& p = s.problem;
  for (const auto& c : p.constraints)
    for (std::size_t k = 0; k < 6; ++k)
      if (c.fixed[k] && c.value[k] != 0.0)
        throw FemModelError(
            "FEM (modal): non-zero prescribed displacements are supported by the static "
            "analysis of the full FEM only; the modal-reduced backend integrates in time");
  for (std::size_t e = 0; e < p.mesh.elements.size(); ++e) {
    const Material& mat = p.materials[static_cast<std::size_t>(
        p.sections[static_cast<std::size_t>(p.mesh.elements[e].section)].material)];
    if (!(mat.density > 0.0))
      throw FemModelError("FEM (modal): the modes need mass, but material '" + mat.name + "' (of " +
                          element_name(p.mesh, e) +
                          ") has density 0: give its density (> 0 kg/m^3)");
  }
  s.dofs = make_dof_map(p);
  if (s.dofs.free.empty()) throw std::invalid_argument("FEM problem: every DOF is constrained");
  const SparseMatrix m_full = assemble_mass(p, s.dofs);
  const SparseMatrix kr = reduce_matrix(assemble_stiffness(p, s.dofs), s.dofs);
  s.m = reduce_matrix(m_full, s.dofs);
  try {
    s.k_solver.factorize(kr, "stiffness matrix (modal-reduced backend)");
  } catch (const SingularMatrixError& e) {
    throw FemModelError(std::string(e.what()) +
                        ". The modal-reduced backend needs a structure that its clamps hold "
                        "against every rigid-body motion (its static correction and static "
                        "solve use K^-1); clamp it, or use fem.backend = \"fem\"");
  }
  ModalOptions mo;
  mo.count = settings.modes;
  mo.backend = settings.backend;
  const ModeSet modes = compute_modes(kr, s.m, mo);
  s.phi = modes.shapes;
  s.omega2 = modes.omega2;
  if (!(s.omega2.minCoeff() > 0.0))
    throw FemModelError(
        "FEM (modal): the lowest mode has omega^2 = " + std::to_string(s.omega2.minCoeff()) +
        ": the structure is not held against a rigid-body motion");

  s.iface = build_interface(p);
  s.b = interface_load_matrix(s.dofs, s.iface);
  LoadVectors loads = load_vectors(p, s.dofs, m_full);
  auto reduce = [&](const VectorXd& full) {
    VectorXd r(static_cast<Eigen::Index>(s.dofs.free.size()));
    for (std::size_t i = 0; i < s.dofs.free.size(); ++i)
      r(static_cast<Eigen::Index>(i)) = full(s.dofs.free[i]);
    return r;
  };
  s.f_const = reduce(loads.constant);
  for (auto& [f, amp] : loads.timed) {
    s.f_timed.push_back(reduce(f));
    s.amplitudes.push_back(amp);
  }
  const auto n3 = static_cast<Eigen::Index>(s.n3());
  const Eigen::Index nl = s.nl();
  const auto nm = static_cast<Eigen::Index>(s.omega2.size());
  // Projections on the modes: P = Phi^T L, Phi_I = B^T Phi.
  s.phi_i = s.b.transpose() * s.phi;
  s.p.resize(nm, nl);
  s.p.leftCols(n3) = s.phi_i.transpose();
  s.p.col(n3) = s.phi.transpose() * s.f_const;
  for (std::size_t k = 0; k < s.f_timed.size(); ++k)
    s.p.col(n3 + 1 + static_cast<Eigen::Index>(k)) = s.phi.transpose() * s.f_timed[k];
  // The residual flexibility in the load basis, S = L^T K^-1 L - P^T Omega^-2 P, a column at
  // a time (one K solve each: the set-up cost grows with the interface, a step's does not).
  if (settings.static_correction) {
    const double bytes = 8.0 * static_cast<double>(nl) * static_cast<double>(nl);
    if (bytes > kMaxCorrectionBytes) {
      char msg[400];
      std::snprintf(msg, sizeof msg,
                    "FEM (modal): the static correction over %lld interface force components "
                    "and loads needs a dense %lld x %lld matrix (%.1f GB, more than the %.0f GB "
                    "accepted); choose a smaller fem.interface_surface, or turn the correction "
                    "off (fem.modal.static_correction = false) and take more modes",
                    static_cast<long long>(nl), static_cast<long long>(nl),
                    static_cast<long long>(nl), bytes / 1e9, kMaxCorrectionBytes / 1e9);
      throw FemModelError(msg);
    }
    s.s.resize(nl, nl);
    const MatrixXd wp = s.p.array().colwise() / s.omega2.array();  // Omega^-2 P
    VectorXd e = VectorXd::Zero(nl), f, x(static_cast<Eigen::Index>(s.dofs.free.size()));
    for (Eigen::Index j = 0; j < nl; ++j) {
      e.setZero();
      e(j) = 1.0;
      f = s.load_basis_times(e);
      s.k_solver.solve(f, x);
      s.s.col(j) = s.load_basis_transpose_times(x) - s.p.transpose() * wp.col(j);
    }
    s.s = 0.5 * (s.s + s.s.transpose()).eval();
  } else {
    s.s.setZero(nl, nl);
  }
  s.bossak = std::make_unique<ReducedBossak>(
      MatrixXd::Identity(nm, nm), MatrixXd(s.omega2.asDiagonal()), MatrixXd(), p.damping, p.bossak);
  s.stiffness = kr;
  s.q.resize(nm);
  s.g.resize(nl);
  s.ci.resize(n3);
  s.forces.assign(s.n3(), 0.0);
}

ModalSolver::~ModalSolver() = default;
ModalSolver::ModalSolver(ModalSolver&&) noexcept = default;
ModalSolver& ModalSolver::operator=(ModalSolver&&) noexcept = default;

const FemProblem& ModalSolver::problem() const {
  return impl_->problem;
}
const ModalSettings& ModalSolver::settings() const {
  return impl_->settings;
}
int ModalSolver::mode_count() const {
  return static_cast<int>(impl_->omega2.size());
}
const Eigen::VectorXd& ModalSolver::omega2() const {
  return impl_->omega2;
}
std::size_t ModalSolver::free_dof_count() const {
  return impl_->dofs.free.size();
}
std::size_t ModalSolver::load_count() const {
  return static_cast<std::size_t>(impl_->nl());
}
const InterfaceMesh& ModalSolver::interface_mesh() const {
  return impl_->iface.mesh;
}
double ModalSolver::time() const {
  return impl_->time;
}
std::int64_t ModalSolver::step_count() const {
  return impl_->step;
}
const std::string& ModalSolver::restore_report() const {
  return impl_->report;
}

void ModalSolver::set_interface_forces(std::span<const double> forces) {
  Impl& s = *impl_;
  check_interface_forces(forces, s.forces.size(), "ModalSolver");
  std::copy(forces.begin(), forces.end(), s.forces.begin());
  // As FemSolver: the initial acceleration depends on the first load.
  if (s.step == 0) s.accel_ready = false;
}

void ModalSolver::solve_static() {
  Impl& s = *impl_;
  const VectorXd w = s.weights(s.time);
  s.q.u = (s.p * w).cwiseQuotient(s.omega2);
  s.q.v.setZero();
  s.q.a.setZero();
  s.g.u = s.settings.static_correction ? w : VectorXd::Zero(s.nl());
  s.g.v.setZero();
  s.g.a.setZero();
  s.ci.u = s.settings.static_correction
               ? VectorXd(s.s.topRows(static_cast<Eigen::Index>(s.n3())) * w)
               : VectorXd::Zero(static_cast<Eigen::Index>(s.n3()));
  s.ci.v.setZero();
  s.ci.a.setZero();
  s.tr = Impl::Transient{};
  s.accel_ready = false;
  s.check_finite(s.q.u, "static displacement");
}

void ModalSolver::advance(double dt) {
  Impl& s = *impl_;
  if (!(dt > 0.0) || !std::isfinite(dt))
    throw std::invalid_argument("ModalSolver::advance: dt = " + std::to_string(dt) +
                                " must be finite and > 0");
  if (!s.accel_ready) {
    s.init_acceleration();
    s.accel_ready = true;
  }
  const double t1 = s.time + dt;
  const VectorXd w = s.weights(t1);
  s.bossak->advance(s.q, s.p * w, dt);
  if (s.settings.static_correction) s.correction_step(w, dt);
  s.time = t1;
  ++s.step;
  s.last_dt = dt;
  s.check_finite(s.q.u, "displacement");
  s.check_finite(s.g.u, "static correction");
}

void ModalSolver::interface_kinematics(std::span<double> positions, std::span<double> velocities,
                                       std::span<double> accelerations) const {
  const Impl& s = *impl_;
  const std::size_t n = s.n3();
  if (positions.size() != n || velocities.size() != n || accelerations.size() != n)
    throw std::invalid_argument("ModalSolver::interface_kinematics: spans must hold " +
                                std::to_string(n) + " values (3 per interface node)");
  const VectorXd x = s.interface_values(0), v = s.interface_values(1), a = s.interface_values(2);
  for (std::size_t i = 0; i < n; ++i) {
    const auto k = static_cast<Eigen::Index>(i);
    positions[i] = s.iface.mesh.reference_positions[i] + x(k);
    velocities[i] = v(k);
    accelerations[i] = a(k);
  }
}

double ModalSolver::max_interface_displacement() const {
  const Impl& s = *impl_;
  const VectorXd x = s.interface_values(0);
  double m = 0.0;
  for (Eigen::Index i = 0; i + 2 < x.size(); i += 3) m = std::max(m, x.segment<3>(i).norm());
  return m;
}

std::vector<double> ModalSolver::displacements() const {
  return impl_->nodal(impl_->full_field(0));
}
std::vector<double> ModalSolver::velocities() const {
  return impl_->nodal(impl_->full_field(1));
}
std::vector<double> ModalSolver::accelerations() const {
  return impl_->nodal(impl_->full_field(2));
}
ElementResults ModalSolver::element_results() const {
  const Impl& s = *impl_;
  return compute_element_results(s.problem, s.dofs, s.expand(s.full_field(0)));
}

double ModalSolver::kinetic_energy() const {
  const Impl& s = *impl_;
  double e = 0.5 * s.q.v.squaredNorm();
  if (s.tr.active()) {
    const Eigen::Vector3d c(s.tr.c[0][1], s.tr.c[1][1], s.tr.c[2][1]);
    e += 0.5 * c.dot(s.tr.mzz * c);
  }
  return e;
}
double ModalSolver::strain_energy() const {
  const Impl& s = *impl_;
  double e = 0.5 * s.q.u.dot(s.omega2.cwiseProduct(s.q.u)) + 0.5 * s.g.u.dot(s.s * s.g.u);
  if (s.tr.active()) {
    // u = Phi q + R L g + Z c, Z in the truncated modes: (R L g)^T K Z c = g^T L^T Z c.
    const Eigen::Vector3d c(s.tr.c[0][0], s.tr.c[1][0], s.tr.c[2][0]);
    e += s.g.u.dot(s.tr.lz * c) + 0.5 * c.dot(s.tr.kzz * c);
  }
  return e;
}

void ModalSolver::save(io::H5File& file, const std::string& group) const {
  const Impl& s = *impl_;
  // FemSolver's layout: the full state, what any FEM-engine backend can restore.
  file.create_group(group);
  const VectorXd u = s.full_field(0), v = s.full_field(1), a = s.full_field(2);
  file.write(group + "/u", span_of(u));
  file.write(group + "/v", span_of(v));
  file.write(group + "/a", span_of(a));
  file.write(group + "/interface_forces", std::span<const double>(s.forces));
  file.set_attribute(group, "time", s.time);
  file.set_attribute(group, "step", s.step);
  file.set_attribute(group, "acceleration_ready", static_cast<std::int64_t>(s.accel_ready));
  file.set_attribute(group, "dt_factorised", s.last_dt);
  file.set_attribute(group, "dof_count", static_cast<std::int64_t>(s.dofs.total));
  file.set_attribute(group, "free_dof_count", static_cast<std::int64_t>(s.dofs.free.size()));
  // The modal state itself, for a bitwise continuation by the same backend.
  const std::string mg = group + "_modal";
  file.create_group(mg);
  const std::pair<const char*, const VectorXd*> arrays[] = {
      {"q", &s.q.u},   {"q_v", &s.q.v}, {"q_a", &s.q.a},      {"g", &s.g.u},
      {"g_v", &s.g.v}, {"g_a", &s.g.a}, {"omega2", &s.omega2}};
  for (const auto& [name, x] : arrays) file.write(mg + "/" + name, span_of(*x));
  const std::pair<const char*, const VectorXd*> interface[] = {
      {"c", &s.ci.u}, {"c_v", &s.ci.v}, {"c_a", &s.ci.a}};
  for (const auto& [name, x] : interface) file.write(mg + "/" + name, span_of(*x));
  if (s.tr.active()) {
    for (int j = 0; j < 3; ++j) file.write(mg + "/z" + std::to_string(j), span_of(s.tr.z[j]));
    double c[9];
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k) c[3 * j + k] = s.tr.c[j][k];
    file.write(mg + "/transient", std::span<const double>(c, 9));
  }
  file.set_attribute(mg, "modes", static_cast<std::int64_t>(s.omega2.size()));
  file.set_attribute(mg, "load_count", static_cast<std::int64_t>(s.nl()));
  file.set_attribute(mg, "static_correction",
                     static_cast<std::int64_t>(s.settings.static_correction));
}

void ModalSolver::restore(const io::H5File& file, const std::string& group) {
  Impl& s = *impl_;
  const auto where = file.path().string() + ":" + group;
  check_saved_dof_count(file, group, s.dofs, "ModalSolver::restore");
  auto read = [&](const std::string& name, Eigen::Index size) {
    const auto d = file.read_doubles(name);
    if (d.size() != static_cast<std::size_t>(size))
      throw std::runtime_error("ModalSolver::restore: " + file.path().string() + ":" + name +
                               " has " + std::to_string(d.size()) + " values, expected " +
                               std::to_string(size));
    for (std::size_t k = 0; k < d.size(); ++k)
      if (!std::isfinite(d[k]))
        throw std::runtime_error("ModalSolver::restore: " + file.path().string() + ":" + name +
                                 "[" + std::to_string(k) +
                                 "] is not finite; the state cannot "
                                 "be continued: resume from an earlier checkpoint");
    return VectorXd(Eigen::Map<const VectorXd>(d.data(), size));
  };
  const auto f = file.read_doubles(group + "/interface_forces");
  if (f.size() != s.forces.size())
    throw std::runtime_error("ModalSolver::restore: " + where +
                             "/interface_forces does not match the interface size");
  const double time = file.attribute_double(group, "time");
  const std::int64_t step = file.attribute_int64(group, "step");
  if (!std::isfinite(time) || time < 0.0 || step < 0)
    throw std::runtime_error("ModalSolver::restore: " + where + ": time " + std::to_string(time) +
                             " or step " + std::to_string(step) + " is not a valid state");
  const auto nm = static_cast<Eigen::Index>(s.omega2.size());
  const std::string mg = group + "_modal";
  bool own = false;
  if (file.exists(mg) && file.attribute_int64(mg, "modes") == nm &&
      file.attribute_int64(mg, "load_count") == s.nl() &&
      file.attribute_int64(mg, "static_correction") ==
          static_cast<std::int64_t>(s.settings.static_correction)) {
    const VectorXd w2 = read(mg + "/omega2", nm);
    own = ((w2 - s.omega2).cwiseAbs().array() <= 1e-9 * s.omega2.array()).all();
  }
  s.forces = f;
  s.time = time;
  s.step = step;
  s.accel_ready = file.attribute_int64(group, "acceleration_ready") != 0;
  s.last_dt = file.attribute_double(group, "dt_factorised");
  s.report.clear();
  if (own) {
    s.q.u = read(mg + "/q", nm);
    s.q.v = read(mg + "/q_v", nm);
    s.q.a = read(mg + "/q_a", nm);
    s.g.u = read(mg + "/g", s.nl());
    s.g.v = read(mg + "/g_v", s.nl());
    s.g.a = read(mg + "/g_a", s.nl());
    const auto ni = static_cast<Eigen::Index>(s.n3());
    s.ci.u = read(mg + "/c", ni);
    s.ci.v = read(mg + "/c_v", ni);
    s.ci.a = read(mg + "/c_a", ni);
    s.tr = Impl::Transient{};
    if (file.exists(mg + "/transient")) {
      const auto nf = static_cast<Eigen::Index>(s.dofs.free.size());
      s.start_transient({read(mg + "/z0", nf), read(mg + "/z1", nf), read(mg + "/z2", nf)});
      const VectorXd c = read(mg + "/transient", 9);
      for (int j = 0; j < 3; ++j)
        for (int k = 0; k < 3; ++k) s.tr.c[j][k] = c(3 * j + k);
    }
    return;
  }
  // A full state (the full FEM's, or another modal basis's reconstruction): mass-orthogonal
  // projection on the modes, the truncated modes quasi-static under the loads of that time,
  // and what that leaves of u, v, a as the initial state of the truncated modes' own motion
  // (the transient), so that the interface kinematics continue exactly where they were.
  const auto nf = static_cast<Eigen::Index>(s.dofs.free.size());
  const VectorXd u = read(group + "/u", nf), v = read(group + "/v", nf), a = read(group + "/a", nf);
  const VectorXd mu = s.m * u, mv = s.m * v;
  s.q.u = s.phi.transpose() * mu;
  s.q.v = s.phi.transpose() * mv;
  s.q.a = s.phi.transpose() * (s.m * a);
  const auto ni = static_cast<Eigen::Index>(s.n3());
  s.g.resize(s.nl());
  s.ci.resize(ni);
  s.tr = Impl::Transient{};
  auto worst = [&](const VectorXd& full, const VectorXd& reduced, double& largest) {
    double d = 0.0;
    largest = 0.0;
    for (Eigen::Index i = 0; i + 2 < full.size(); i += 3) {
      d = std::max(d, (full.segment<3>(i) - reduced.segment<3>(i)).norm());
      largest = std::max(largest, full.segment<3>(i).norm());
    }
    return d;
  };
  double ux = 0.0, vx = 0.0;
  const VectorXd ui = s.b.transpose() * u, vi = s.b.transpose() * v;
  if (s.settings.static_correction) {
    s.g.u = s.weights(time);
    s.ci.u = s.s.topRows(ni) * s.g.u;
  }
  // The modes and the quasi-static correction alone: how much the transient has to carry.
  const double du_static = worst(ui, s.interface_values(0), ux);
  const double dv_static = worst(vi, s.interface_values(1), vx);
  if (s.settings.static_correction) {
    const VectorXd zu = s.truncated(u) - (s.full_field(0) - s.phi * s.q.u);
    s.start_transient({zu, s.truncated(v), s.truncated(a)});
  }
  const double du = worst(ui, s.interface_values(0), ux);
  const double dv = worst(vi, s.interface_values(1), vx);
  const double unorm = std::sqrt(std::max(u.dot(mu), 0.0));
  const VectorXd rest = u - s.phi * s.q.u;
  const double held =
      unorm > 0.0 ? 1.0 - std::sqrt(std::max(rest.dot(s.m * rest), 0.0)) / unorm : 1.0;
  char text[900];
  if (s.settings.static_correction) {
    std::snprintf(text, sizeof text,
                  "the full state of %s (t = %.9g s): %lld modal coordinates by mass-orthogonal "
                  "projection (q = Phi^T M u, and v, a; the modes hold %.6f of the displacement "
                  "in the mass norm), the static correction of the loads then, and the rest as "
                  "the initial state of the truncated modes (at the interface %.3g m and %.3g "
                  "m/s of the largest %.3g m and %.3g m/s, decaying as they relax): interface "
                  "positions continue within %.3g m, velocities within %.3g m/s",
                  file.path().c_str(), time, static_cast<long long>(nm), held, du_static, dv_static,
                  ux, vx, du, dv);
  } else {
    std::snprintf(text, sizeof text,
                  "the full state of %s (t = %.9g s) projected on %lld modes (q = Phi^T M u, and "
                  "v, a; no static correction): interface positions differ from the full state by "
                  "at most %.3g m (largest interface displacement %.3g m), velocities by %.3g m/s "
                  "(largest %.3g m/s); the modes hold %.6f of the displacement in the mass norm",
                  file.path().c_str(), time, static_cast<long long>(nm), du, ux, dv, vx, held);
  }
  s.report = text;
}

}  // namespace demfem::fem
