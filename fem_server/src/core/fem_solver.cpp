// Linear-elastic FEM solver: static solve and Bossak-Newmark time stepping (see
// fem_solver.hpp). Constraints are eliminated: all vectors of the state are over the free
// DOFs only; fixed DOFs are zero.
#include "demfem/fem/fem_solver.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

#include <Eigen/Eigenvalues>

#include "demfem/fem/assembly.hpp"
#include "demfem/io/h5_file.hpp"
#include "elements.hpp"

namespace demfem::fem {

using Eigen::VectorXd;

struct FemSolver::Impl {
  FemProblem problem;
  SolverBackend backend;
  DofMap dofs;
  SparseMatrix k_full, m_full;  // all DOFs (reactions)
  SparseMatrix k, m;            // free DOFs
  InterfaceMap iface;

  struct TimedLoad {
    VectorXd full, reduced;
    TimeFunction amplitude;
  };
  VectorXd f_const_full, f_const;  // loads without amplitude, gravity
  std::vector<TimedLoad> timed;
  std::vector<double> iface_forces;

  VectorXd u_fixed_full;  // prescribed values of the fixed DOFs (zero at free DOFs)
  VectorXd f_prescribed;  // K_fc u_c over the free DOFs: moved to the right-hand side
  bool has_prescribed = false;
  double model_size = 0.0;  // bounding-box diagonal of the nodes used by elements, m
  bool mass_checked = false;

  VectorXd u, v, a;  // free DOFs
  double time = 0.0;
  std::int64_t step = 0;
  bool accel_ready = false;  // a = M^-1 (F - C v - K u) computed for the current state

  SparseSpdSolver dynamic_solver, static_solver, mass_solver;
  double dt_factorised = 0.0;  // 0 = no effective matrix factorised
  VectorXd rhs, ut, vt, work, a_new;

  Impl(FemProblem p, SolverBackend b)
      : problem(std::move(p)), backend(b), dynamic_solver(b), static_solver(b), mass_solver(b) {}

  VectorXd reduce(const VectorXd& full) const {
    VectorXd r(static_cast<Eigen::Index>(dofs.free.size()));
    for (std::size_t i = 0; i < dofs.free.size(); ++i)
      r(static_cast<Eigen::Index>(i)) = full(dofs.free[i]);
    return r;
  }
  VectorXd expand(const VectorXd& red) const {
    VectorXd f = VectorXd::Zero(dofs.total);
    for (std::size_t i = 0; i < dofs.free.size(); ++i)
      f(dofs.free[i]) = red(static_cast<Eigen::Index>(i));
    return f;
  }

  /// Displacement of all DOFs: the free ones from u, the fixed ones their prescribed value.
  VectorXd full_u() const {
    VectorXd f = expand(u);
    if (has_prescribed) f += u_fixed_full;
    return f;
  }

  // ---- model checks -----------------------------------------------------------------

  /// Mesh node and component of a row of the reduced system: "node 17 (beam.inp:23), DOF y".
  std::string dof_name(Eigen::Index row) const {
    if (row < 0 || static_cast<std::size_t>(row) >= dofs.free.size()) return "an unknown DOF";
    const std::int32_t g = dofs.free[static_cast<std::size_t>(row)];
    const auto it = std::upper_bound(dofs.node_offset.begin(), dofs.node_offset.end(), g);
    const auto n = static_cast<std::size_t>(it - dofs.node_offset.begin() - 1);
    static const char* names[6] = {"x", "y", "z", "rx", "ry", "rz"};
    return node_name(problem.mesh, n) + ", DOF " + names[g - dofs.node_offset[n]];
  }

  /// Nodes whose amplitude in x (a reduced vector, DOFs weighted by sqrt of the stiffness
  /// diagonal so that translations and rotations compare) exceeds 1 % of the largest: the
  /// nodes that take part in a free motion. Returns them and writes a list for messages.
  std::vector<std::size_t> moving_nodes(const VectorXd& weighted, std::string& list) const {
    const std::size_t nn = problem.mesh.nodes.size();
    std::vector<double> amp(nn, 0.0);
    for (std::size_t r = 0; r < dofs.free.size(); ++r) {
      const std::int32_t g = dofs.free[r];
      const auto it = std::upper_bound(dofs.node_offset.begin(), dofs.node_offset.end(), g);
      const auto n = static_cast<std::size_t>(it - dofs.node_offset.begin() - 1);
      amp[n] = std::max(amp[n], std::abs(weighted(static_cast<Eigen::Index>(r))));
    }
    const double top = *std::max_element(amp.begin(), amp.end());
    std::vector<std::size_t> out;
    for (std::size_t n = 0; n < nn; ++n)
      if (amp[n] > 1e-2 * top) out.push_back(n);
    list.clear();
    constexpr std::size_t kShown = 8;
    for (std::size_t i = 0; i < out.size() && i < kShown; ++i)
      list += (i ? ", " : "") + node_name(problem.mesh, out[i]);
    if (out.size() > kShown) list += " and " + std::to_string(out.size() - kShown) + " more";
    return out;
  }

  /// Explains a free motion: the whole structure (clamps missing) or part of it (mechanism).
  std::string free_motion_text(const std::vector<std::size_t>& moving, const std::string& list) {
    const std::size_t used = problem.mesh.nodes.size() - orphan_nodes(problem.mesh).size();
    if (moving.size() >= used)
      return "the whole structure can move as a rigid body: the clamps do not hold it in every "
             "direction. Add clamps ([[fem.clamps]] in the scene, or *BOUNDARY in the .inp). "
             "Moving nodes: " +
             list;
    return std::to_string(moving.size()) + " of " + std::to_string(used) +
           " nodes can move without deforming any element: a mechanism (parts joined only by "
           "a node or an edge, a collapsed element), a part no clamp holds, or elements so thin "
           "that their stiffness is lost to round-off. Free nodes: " +
           list + ". Fix the connectivity of the mesh or clamp these nodes";
  }

  /// The stiffness matrix k is singular: find its null space by two steps of inverse
  /// iteration on K + sigma diag(K) (sigma = 1e-10 keeps the shifted matrix factorisable while
  /// a free motion, of Rayleigh quotient ~0, is amplified 1e10 times more than any deformation)
  /// and name the nodes that move in it.
  std::string diagnose_singular_stiffness() {
    try {
      const Eigen::VectorXd d = k.diagonal();
      const double mean = d.cwiseAbs().mean();
      SparseMatrix ks = k;
      VectorXd w(d.size());
      for (Eigen::Index i = 0; i < d.size(); ++i) {
        w(i) = d(i) > 0.0 ? d(i) : mean;
        ks.coeffRef(i, i) = (d(i) > 0.0 ? d(i) : 0.0) + 1e-10 * w(i);
      }
      SparseSpdSolver shifted(backend);
      shifted.factorize(ks, "shifted stiffness matrix");
      VectorXd x(d.size()), y(d.size());
      // A fixed pseudo-random start (deterministic messages), weighted like the diagonal.
      for (Eigen::Index i = 0; i < d.size(); ++i)
        x(i) = std::sqrt(w(i)) *
               (0.5 + std::fmod(std::sin(static_cast<double>(i) * 12.9898) * 43758.5453, 0.5));
      for (int it = 0; it < 2; ++it) {
        shifted.solve(x, y);
        y /= y.norm();
        x = w.cwiseProduct(y);
      }
      std::string list;
      const auto moving = moving_nodes(w.cwiseSqrt().cwiseProduct(y), list);
      return free_motion_text(moving, list);
    } catch (const std::exception& e) {
      return std::string("(the free nodes could not be found: ") + e.what() + ")";
    }
  }

  /// Factorises, turning a singular matrix into a FemModelError that names the DOF and, for
  /// the stiffness, the freely moving nodes.
  void factorize_checked(SparseSpdSolver& solver, const SparseMatrix& matrix,
                         const std::string& what, bool stiffness) {
    try {
      solver.factorize(matrix, what);
    } catch (const SingularMatrixError& e) {
      std::string msg = std::string(e.what()) + "; at " + dof_name(e.row) + ". ";
      msg += stiffness ? diagnose_singular_stiffness()
                       : std::string(
                             "Every node must carry mass: check the densities and that "
                             "no DOF is left without elements");
      throw FemModelError(msg);
    }
  }

  void check_finite(const VectorXd& x, const char* what) const {
    if (!x.allFinite())
      throw FemModelError("FEM: the " + std::string(what) +
                          " became non-finite at t = " + std::to_string(time) +
                          " s: a load, amplitude or material value overflowed");
  }

  /// A dynamic analysis needs every element to have mass.
  void check_mass() {
    if (mass_checked) return;
    const Mesh& mesh = problem.mesh;
    for (std::size_t e = 0; e < mesh.elements.size(); ++e) {
      const Material& mat = problem.materials[static_cast<std::size_t>(
          problem.sections[static_cast<std::size_t>(mesh.elements[e].section)].material)];
      if (!(mat.density > 0.0))
        throw FemModelError("FEM: a dynamic analysis needs mass, but material '" + mat.name +
                            "' (of " + element_name(mesh, e) +
                            ") has density 0: give its density (> 0 kg/m^3)");
    }
    if (has_prescribed)
      throw FemModelError(
          "FEM: non-zero prescribed displacements are supported by the static analysis only; "
          "a dynamic analysis would need their velocity and acceleration too");
    mass_checked = true;
  }

  double amplitude(const TimedLoad& l, double t) const {
    const double s = l.amplitude(t);
    if (!std::isfinite(s))
      throw std::runtime_error("FEM: a load amplitude returned a non-finite value at t = " +
                               std::to_string(t));
    return s;
  }

  /// Interface forces (and the moments of the shell offsets) added into a vector indexed by
  /// `map` (global -> target index, -1 = skip) or by global DOF when map is null.
  void add_interface_forces(VectorXd& out, const std::vector<std::int32_t>* map) const {
    for (std::size_t i = 0; i < iface.mesh_node.size(); ++i) {
      const auto n = static_cast<std::size_t>(iface.mesh_node[i]);
      const Eigen::Vector3d f(iface_forces[3 * i], iface_forces[3 * i + 1],
                              iface_forces[3 * i + 2]);
      const auto off = dofs.node_offset[n];
      auto add = [&](std::int32_t g, double val) {
        const std::int32_t r = map ? (*map)[static_cast<std::size_t>(g)] : g;
        if (r >= 0) out(r) += val;
      };
      for (int c = 0; c < 3; ++c) add(off + c, f(c));
      if (dofs.node_dofs[n] == 6) {
        // Force on an offset surface point = force + moment (offset x force) on the
        // mid-surface node (thesis eq. 3.9 sums the forces; the moment keeps the resultant
        // of the top/bottom contact forces statically equivalent).
        const Eigen::Vector3d mom = iface.offset[i].cross(f);
        for (int c = 0; c < 3; ++c) add(off + 3 + c, mom(c));
      }
    }
  }

  /// External load at time t over the free DOFs, written into `out` (no allocation).
  void load_reduced(double t, VectorXd& out) const {
    out = f_const;
    for (const auto& l : timed) out.noalias() += amplitude(l, t) * l.reduced;
    add_interface_forces(out, &dofs.reduced);
  }
  VectorXd load_full(double t) const {
    VectorXd out = f_const_full;
    for (const auto& l : timed) out += amplitude(l, t) * l.full;
    add_interface_forces(out, nullptr);
    return out;
  }

  double cm() const { return problem.damping.mass_factor; }
  double ck() const { return problem.damping.stiffness_factor; }

  void init_acceleration() {
    // M a0 = F(t0) - C v0 - K u0.
    check_mass();
    if (!mass_solver.factorized()) factorize_checked(mass_solver, m, "mass matrix", false);
    load_reduced(time, rhs);
    work = cm() * v;
    rhs.noalias() -= m * work;
    work = u + ck() * v;
    rhs.noalias() -= k * work;
    mass_solver.solve(rhs, a);
    accel_ready = true;
  }

  void factorize_dynamic(double dt) {
    const auto& b = problem.bossak;
    // (1 - alpha) M + gamma dt C + beta dt^2 K, with C = cm M + ck K.
    const double cmass = (1.0 - b.alpha) + b.gamma * dt * cm();
    const double cstiff = b.beta * dt * dt + b.gamma * dt * ck();
    SparseMatrix eff = cmass * m + cstiff * k;
    char what[96];
    std::snprintf(what, sizeof what, "effective dynamic matrix (dt = %g s)", dt);
    factorize_checked(dynamic_solver, eff, what, false);
    dt_factorised = dt;
  }

  void advance(double dt) {
    if (!(dt > 0.0) || !std::isfinite(dt))
      throw std::invalid_argument("FemSolver::advance: dt = " + std::to_string(dt) +
                                  " must be finite and > 0");
    if (!accel_ready) init_acceleration();
    if (dt != dt_factorised) factorize_dynamic(dt);
    const auto& b = problem.bossak;
    // Newmark predictors (thesis eq. 2.85, 2.86 without the a_{n+1} terms).
    ut = u + dt * v + (dt * dt * (0.5 - b.beta)) * a;
    vt = v + (dt * (1.0 - b.gamma)) * a;
    // Bossak equilibrium at t_{n+1} (eq. 2.87 with K u_{n+1}), solved for a_{n+1}:
    // A a_{n+1} = F_{n+1} - M (alpha a_n + cm vt) - K (ut + ck vt).
    const double t1 = time + dt;
    load_reduced(t1, rhs);
    work = b.alpha * a + cm() * vt;
    rhs.noalias() -= m * work;
    work = ut + ck() * vt;
    rhs.noalias() -= k * work;
    dynamic_solver.solve(rhs, a_new);
    u = ut + (b.beta * dt * dt) * a_new;
    v = vt + (b.gamma * dt) * a_new;
    a.swap(a_new);
    time = t1;
    ++step;
    check_finite(u, "displacement");
  }

  /// Translation (c < 3) or rotation (c >= 3) DOF c of mesh node n from a free-DOF vector;
  /// fixed DOFs give their prescribed value for the displacement, 0 otherwise.
  double node_value(const VectorXd& x, std::size_t n, int c, bool displacement = false) const {
    if (c >= dofs.node_dofs[n]) return 0.0;
    const auto g = dofs.node_offset[n] + c;
    const auto r = dofs.reduced[static_cast<std::size_t>(g)];
    if (r >= 0) return x(r);
    return displacement && has_prescribed ? u_fixed_full(g) : 0.0;
  }
  std::vector<double> nodal(const VectorXd& x, bool displacement = false) const {
    const std::size_t nn = problem.mesh.nodes.size();
    std::vector<double> out(3 * nn);
    for (std::size_t n = 0; n < nn; ++n)
      for (int c = 0; c < 3; ++c)
        out[3 * n + static_cast<std::size_t>(c)] = node_value(x, n, c, displacement);
    return out;
  }
};

double bossak_spectral_radius(const BossakParameters& b, double omega_dt) {
  // advance() for M = 1, K = w^2, C = 0, F = 0 in the scaled state (u, dt v, dt^2 a):
  // predictors, then (1 - alpha) a1 + alpha a0 + w^2 (ut + beta dt^2 a1) = 0.
  const double w2 = omega_dt * omega_dt;
  Eigen::Matrix3d amp;
  for (int c = 0; c < 3; ++c) {
    const double u = c == 0, v = c == 1, a = c == 2;
    const double ut = u + v + (0.5 - b.beta) * a;
    const double vt = v + (1.0 - b.gamma) * a;
    const double a1 = -(b.alpha * a + w2 * ut) / ((1.0 - b.alpha) + b.beta * w2);
    amp.col(c) << ut + b.beta * a1, vt + b.gamma * a1, a1;
  }
  return Eigen::EigenSolver<Eigen::Matrix3d>(amp, false).eigenvalues().cwiseAbs().maxCoeff();
}

FemSolver::FemSolver(FemProblem problem)
    : FemSolver(std::move(problem), SolverBackend::automatic) {}

FemSolver::FemSolver(FemProblem problem, SolverBackend backend) {
  validate_problem(problem);
  impl_ = std::make_unique<Impl>(std::move(problem), backend);
  Impl& s = *impl_;
  const FemProblem& p = s.problem;
  s.dofs = make_dof_map(p);
  if (s.dofs.free.empty()) throw std::invalid_argument("FEM problem: every DOF is constrained");
  s.k_full = assemble_stiffness(p, s.dofs);
  s.m_full = assemble_mass(p, s.dofs);
  s.k = reduce_matrix(s.k_full, s.dofs);
  s.m = reduce_matrix(s.m_full, s.dofs);
  LoadVectors loads = load_vectors(p, s.dofs, s.m_full);
  s.f_const_full = std::move(loads.constant);
  for (auto& [f, amp] : loads.timed) {
    Impl::TimedLoad l;
    l.reduced = s.reduce(f);
    l.full = std::move(f);
    l.amplitude = std::move(amp);
    s.timed.push_back(std::move(l));
  }
  s.f_const = s.reduce(s.f_const_full);
  // Prescribed values of fixed DOFs (*BOUNDARY with a value): K_fc u_c moves to the load side.
  s.u_fixed_full = VectorXd::Zero(s.dofs.total);
  for (const auto& c : p.constraints)
    for (auto n : c.nodes)
      for (int k = 0; k < s.dofs.node_dofs[static_cast<std::size_t>(n)]; ++k)
        if (c.fixed[static_cast<std::size_t>(k)] && c.value[static_cast<std::size_t>(k)] != 0.0) {
          s.u_fixed_full(s.dofs.node_offset[static_cast<std::size_t>(n)] + k) =
              c.value[static_cast<std::size_t>(k)];
          s.has_prescribed = true;
        }
  if (s.has_prescribed) {
    for (std::size_t i = 0; i < s.dofs.free.size(); ++i) s.u_fixed_full(s.dofs.free[i]) = 0.0;
    s.f_prescribed = s.reduce(s.k_full * s.u_fixed_full);
  }
  {
    std::array<double, 3> lo{INFINITY, INFINITY, INFINITY}, hi{-INFINITY, -INFINITY, -INFINITY};
    for (const auto& el : p.mesh.elements)
      for (int a = 0; a < nodes_per_element(el.type); ++a)
        for (int c = 0; c < 3; ++c) {
          const double x = p.mesh.nodes[static_cast<std::size_t>(el.nodes[a])][c];
          lo[c] = std::min(lo[c], x);
          hi[c] = std::max(hi[c], x);
        }
    s.model_size = std::hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]);
  }
  s.iface = build_interface(p);
  s.iface_forces.assign(3 * s.iface.mesh_node.size(), 0.0);
  const auto nf = static_cast<Eigen::Index>(s.dofs.free.size());
  for (VectorXd* x : {&s.u, &s.v, &s.a, &s.rhs, &s.ut, &s.vt, &s.work, &s.a_new}) x->setZero(nf);
}

FemSolver::~FemSolver() = default;
FemSolver::FemSolver(FemSolver&&) noexcept = default;
FemSolver& FemSolver::operator=(FemSolver&&) noexcept = default;

const FemProblem& FemSolver::problem() const {
  return impl_->problem;
}
std::size_t FemSolver::dof_count() const {
  return static_cast<std::size_t>(impl_->dofs.total);
}
std::size_t FemSolver::free_dof_count() const {
  return impl_->dofs.free.size();
}
SolverBackend FemSolver::solver_backend() const {
  return impl_->dynamic_solver.backend();
}
const InterfaceMesh& FemSolver::interface_mesh() const {
  return impl_->iface.mesh;
}
const std::vector<std::int32_t>& FemSolver::interface_mesh_nodes() const {
  return impl_->iface.mesh_node;
}
double FemSolver::time() const {
  return impl_->time;
}
std::int64_t FemSolver::step_count() const {
  return impl_->step;
}

void FemSolver::set_interface_forces(std::span<const double> forces) {
  Impl& s = *impl_;
  check_interface_forces(forces, s.iface_forces.size(), "FemSolver");
  std::copy(forces.begin(), forces.end(), s.iface_forces.begin());
  // The initial acceleration depends on the load; recompute it before the first step.
  if (s.step == 0) s.accel_ready = false;
}

void FemSolver::prepare(bool static_analysis) {
  Impl& s = *impl_;
  if (static_analysis) {
    if (!s.static_solver.factorized())
      s.factorize_checked(s.static_solver, s.k, "stiffness matrix", true);
    return;
  }
  s.check_mass();
  if (!s.mass_solver.factorized()) s.factorize_checked(s.mass_solver, s.m, "mass matrix", false);
}

void FemSolver::solve_static() {
  Impl& s = *impl_;
  if (!s.static_solver.factorized())
    s.factorize_checked(s.static_solver, s.k, "stiffness matrix", true);
  s.load_reduced(s.time, s.rhs);
  if (s.has_prescribed) s.rhs -= s.f_prescribed;
  s.static_solver.solve(s.rhs, s.u);
  s.check_finite(s.u, "static displacement");
  // A linear static displacement larger than the model: either loads off by orders of
  // magnitude, or a mechanism whose pivot survived the factorisation's check (round-off gave
  // it a small positive value); its nodes are those that move most.
  double umax = 0.0;
  const auto full = s.nodal(s.u, true);
  for (std::size_t i = 0; i + 2 < full.size(); i += 3)
    umax = std::max(umax, std::hypot(full[i], full[i + 1], full[i + 2]));
  if (umax > s.model_size) {
    const VectorXd d = s.k.diagonal().cwiseAbs().cwiseSqrt();
    std::string list;
    const auto moving = s.moving_nodes(d.cwiseProduct(s.u), list);
    char head[400];
    const double pivot = s.static_solver.smallest_pivot_ratio();
    // A well-conditioned stiffness (no pivot anywhere near round-off) has no mechanism: the
    // loads are too large for it (issue 19: E = 2.1e4 typed for 2.1e11 named 171 "free nodes").
    constexpr double kMechanismPivot = 1e-8;
    std::snprintf(head, sizeof head,
                  "FEM: the static displacement reaches %.3g m, more than the size of the model "
                  "(%.3g m; smallest pivot ratio %.3g). Linear elasticity does not hold there: "
                  "check the load magnitudes and units%s",
                  umax, s.model_size, pivot,
                  pivot >= kMechanismPivot
                      ? " (the stiffness is well conditioned, so the loads are too large for it: "
                        "a Young's modulus in MPa given as Pa is 1e6 times too soft)"
                      : ", or ");
    if (pivot >= kMechanismPivot) throw FemModelError(head);
    throw FemModelError(head + s.free_motion_text(moving, list));
  }
  s.v.setZero();
  s.a.setZero();
  s.accel_ready = false;
}

void FemSolver::advance(double dt) {
  impl_->advance(dt);
}

void FemSolver::interface_kinematics(std::span<double> positions, std::span<double> velocities,
                                     std::span<double> accelerations) const {
  const Impl& s = *impl_;
  const std::size_t n = s.iface.mesh_node.size();
  if (positions.size() != 3 * n || velocities.size() != 3 * n || accelerations.size() != 3 * n)
    throw std::invalid_argument("FemSolver::interface_kinematics: spans must hold " +
                                std::to_string(3 * n) + " values (3 per interface node)");
  for (std::size_t i = 0; i < n; ++i) {
    const auto node = static_cast<std::size_t>(s.iface.mesh_node[i]);
    Eigen::Vector3d x, vel, acc, th, om, al;
    for (int c = 0; c < 3; ++c) {
      x(c) = s.node_value(s.u, node, c, true);
      vel(c) = s.node_value(s.v, node, c);
      acc(c) = s.node_value(s.a, node, c);
      th(c) = s.node_value(s.u, node, c + 3, true);
      om(c) = s.node_value(s.v, node, c + 3);
      al(c) = s.node_value(s.a, node, c + 3);
    }
    // Offset surface point of a shell: x = x_mid + u + theta x offset (small rotations).
    const Eigen::Vector3d& r = s.iface.offset[i];
    x += th.cross(r);
    vel += om.cross(r);
    acc += al.cross(r);
    for (int c = 0; c < 3; ++c) {
      positions[3 * i + static_cast<std::size_t>(c)] =
          s.iface.mesh.reference_positions[3 * i + static_cast<std::size_t>(c)] + x(c);
      velocities[3 * i + static_cast<std::size_t>(c)] = vel(c);
      accelerations[3 * i + static_cast<std::size_t>(c)] = acc(c);
    }
  }
}

std::vector<double> FemSolver::displacements() const {
  return impl_->nodal(impl_->u, true);
}
std::vector<double> FemSolver::velocities() const {
  return impl_->nodal(impl_->v);
}
std::vector<double> FemSolver::accelerations() const {
  return impl_->nodal(impl_->a);
}

std::vector<double> FemSolver::reaction_forces() const {
  const Impl& s = *impl_;
  // R = K u + M a + C v - F at the fixed DOFs (what the supports exert on the structure).
  const VectorXd uf = s.full_u(), vf = s.expand(s.v), af = s.expand(s.a);
  VectorXd r = s.k_full * (uf + s.ck() * vf) + s.m_full * (af + s.cm() * vf) - s.load_full(s.time);
  const std::size_t nn = s.problem.mesh.nodes.size();
  std::vector<double> out(3 * nn, 0.0);
  for (std::size_t n = 0; n < nn; ++n)
    for (int c = 0; c < 3; ++c) {
      const auto g = s.dofs.node_offset[n] + c;
      if (s.dofs.reduced[static_cast<std::size_t>(g)] < 0)
        out[3 * n + static_cast<std::size_t>(c)] = r(g);
    }
  return out;
}

ElementResults FemSolver::element_results() const {
  return compute_element_results(impl_->problem, impl_->dofs, impl_->full_u());
}

double FemSolver::kinetic_energy() const {
  const Impl& s = *impl_;
  return 0.5 * s.v.dot(s.m * s.v);
}
double FemSolver::strain_energy() const {
  const Impl& s = *impl_;
  if (s.has_prescribed) {
    const VectorXd uf = s.full_u();
    return 0.5 * uf.dot(s.k_full * uf);
  }
  return 0.5 * s.u.dot(s.k * s.u);
}

void FemSolver::save(io::H5File& file, const std::string& group) const {
  const Impl& s = *impl_;
  file.create_group(group);
  auto span_of = [](const VectorXd& x) {
    return std::span<const double>(x.data(), static_cast<std::size_t>(x.size()));
  };
  file.write(group + "/u", span_of(s.u));
  file.write(group + "/v", span_of(s.v));
  file.write(group + "/a", span_of(s.a));
  file.write(group + "/interface_forces", std::span<const double>(s.iface_forces));
  file.set_attribute(group, "time", s.time);
  file.set_attribute(group, "step", s.step);
  file.set_attribute(group, "acceleration_ready", static_cast<std::int64_t>(s.accel_ready));
  file.set_attribute(group, "dt_factorised", s.dt_factorised);
  file.set_attribute(group, "dof_count", static_cast<std::int64_t>(s.dofs.total));
  file.set_attribute(group, "free_dof_count", static_cast<std::int64_t>(s.dofs.free.size()));
}

void FemSolver::save_state(FemStateCopy& c) const {
  const Impl& s = *impl_;
  c.u.assign(s.u.data(), s.u.data() + s.u.size());
  c.v.assign(s.v.data(), s.v.data() + s.v.size());
  c.a.assign(s.a.data(), s.a.data() + s.a.size());
  c.interface_forces = s.iface_forces;
  c.time = s.time;
  c.step = s.step;
  c.acceleration_ready = s.accel_ready;
}

void FemSolver::restore_state(const FemStateCopy& c) {
  Impl& s = *impl_;
  if (c.step < 0 || c.u.size() != static_cast<std::size_t>(s.u.size()))
    throw std::logic_error(
        "FemSolver::restore_state: " +
        std::string(c.step < 0 ? "nothing was saved" : "the copy belongs to another model"));
  s.u = Eigen::Map<const VectorXd>(c.u.data(), s.u.size());
  s.v = Eigen::Map<const VectorXd>(c.v.data(), s.v.size());
  s.a = Eigen::Map<const VectorXd>(c.a.data(), s.a.size());
  s.iface_forces = c.interface_forces;
  s.time = c.time;
  s.step = c.step;
  s.accel_ready = c.acceleration_ready;
}

void FemSolver::restore(const io::H5File& file, const std::string& group) {
  Impl& s = *impl_;
  const auto where = file.path().string() + ":" + group;
  check_saved_dof_count(file, group, s.dofs, "FemSolver::restore");
  auto read = [&](const std::string& name, VectorXd& x) {
    const auto d = file.read_doubles(group + "/" + name);
    if (d.size() != static_cast<std::size_t>(x.size()))
      throw std::runtime_error("FemSolver::restore: " + where + "/" + name + " has " +
                               std::to_string(d.size()) + " values, expected " +
                               std::to_string(x.size()));
    // As strict as a scene: a checkpoint that matches its manifest may still hold a state
    // saved just before a blow-up.
    for (std::size_t k = 0; k < d.size(); ++k)
      if (!std::isfinite(d[k]))
        throw std::runtime_error("FemSolver::restore: " + where + "/" + name + "[" +
                                 std::to_string(k) + "] is not finite (" + std::to_string(d[k]) +
                                 "); the state cannot be continued: resume from an earlier "
                                 "checkpoint");
    x = Eigen::Map<const VectorXd>(d.data(), x.size());
  };
  read("u", s.u);
  read("v", s.v);
  read("a", s.a);
  const auto f = file.read_doubles(group + "/interface_forces");
  if (f.size() != s.iface_forces.size())
    throw std::runtime_error("FemSolver::restore: " + where +
                             "/interface_forces does not match the interface size");
  s.iface_forces = f;
  s.time = file.attribute_double(group, "time");
  s.step = file.attribute_int64(group, "step");
  if (!std::isfinite(s.time) || s.time < 0.0 || s.step < 0)
    throw std::runtime_error("FemSolver::restore: " + where + ": time " + std::to_string(s.time) +
                             " or step " + std::to_string(s.step) + " is not a valid state");
  s.accel_ready = file.attribute_int64(group, "acceleration_ready") != 0;
  // The factorisation is rebuilt for the saved dt on the next step (deterministic, so the
  // continuation is bitwise identical).
  const double dt = file.attribute_double(group, "dt_factorised");
  if (dt > 0 && dt != s.dt_factorised) s.factorize_dynamic(dt);
}

}  // namespace demfem::fem
