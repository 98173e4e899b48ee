// The structure as one rigid body on springs (see rigid_solver.hpp).
#include "demfem/fem/rigid_solver.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "demfem/fem/assembly.hpp"
#include "demfem/fem/fem_solver.hpp"
#include "demfem/fem/reduced_bossak.hpp"
#include "demfem/io/h5_file.hpp"

namespace demfem::fem {

using Eigen::Matrix3d;
using Eigen::MatrixXd;
using Eigen::Vector3d;
using Eigen::VectorXd;

namespace {

Matrix3d skew(const Vector3d& r) {
  Matrix3d s;
  s << 0, -r(2), r(1), r(2), 0, -r(0), -r(1), r(0), 0;
  return s;
}

/// 3 x 6 map from (d, theta) to the displacement of a point at r from the reference point:
/// u = d + theta x r = d - r x theta.
Eigen::Matrix<double, 3, 6> point_map(const Vector3d& r) {
  Eigen::Matrix<double, 3, 6> g;
  g.leftCols<3>() = Matrix3d::Identity();
  g.rightCols<3>() = -skew(r);
  return g;
}

}  // namespace

struct RigidSolver::Impl {
  FemProblem problem;
  RigidSettings settings;
  InterfaceMap iface;
  Vector3d r0, com;
  double total_mass = 0.0;
  Matrix3d inertia_com;
  std::vector<int> free;  // indices of the free coordinates among the six
  MatrixXd map_full;      // all DOFs x 6 (G over the mesh, shell rotations included)
  MatrixXd map_iface;     // 3n x 6
  MatrixXd m6, k6, c6;    // 6 x 6
  VectorXd f_const6;
  std::vector<VectorXd> f_timed6;
  std::vector<TimeFunction> amplitudes;
  std::unique_ptr<ReducedBossak> bossak;
  ReducedState x;  // free coordinates
  std::vector<double> forces;
  double time = 0.0;
  std::int64_t step = 0;
  bool accel_ready = false;

  Eigen::Index nfree() const { return static_cast<Eigen::Index>(free.size()); }
  MatrixXd restrict_matrix(const MatrixXd& a) const {
    MatrixXd r(nfree(), nfree());
    for (Eigen::Index i = 0; i < nfree(); ++i)
      for (Eigen::Index j = 0; j < nfree(); ++j)
        r(i, j) = a(free[static_cast<std::size_t>(i)], free[static_cast<std::size_t>(j)]);
    return r;
  }
  VectorXd restrict_vector(const VectorXd& a) const {
    VectorXd r(nfree());
    for (Eigen::Index i = 0; i < nfree(); ++i) r(i) = a(free[static_cast<std::size_t>(i)]);
    return r;
  }
  VectorXd six(const VectorXd& reduced) const {
    VectorXd out = VectorXd::Zero(6);
    for (Eigen::Index i = 0; i < nfree(); ++i) out(free[static_cast<std::size_t>(i)]) = reduced(i);
    return out;
  }
  /// Generalized load on the free coordinates at time t.
  VectorXd load(double t) const {
    VectorXd f = f_const6;
    for (std::size_t k = 0; k < f_timed6.size(); ++k) {
      const double a = amplitudes[k](t);
      if (!std::isfinite(a))
        throw std::runtime_error(
            "FEM (rigid): a load amplitude returned a non-finite value at t = " +
            std::to_string(t));
      f += a * f_timed6[k];
    }
    f += map_iface.transpose() *
         Eigen::Map<const VectorXd>(forces.data(), static_cast<Eigen::Index>(forces.size()));
    return restrict_vector(f);
  }
  std::vector<double> nodal(const VectorXd& reduced) const {
    const VectorXd s6 = six(reduced);
    const std::size_t nn = problem.mesh.nodes.size();
    std::vector<double> out(3 * nn);
    for (std::size_t n = 0; n < nn; ++n) {
      const Vector3d r =
          Vector3d(problem.mesh.nodes[n][0], problem.mesh.nodes[n][1], problem.mesh.nodes[n][2]) -
          r0;
      const Vector3d u = point_map(r) * s6;
      for (int c = 0; c < 3; ++c) out[3 * n + static_cast<std::size_t>(c)] = u(c);
    }
    return out;
  }
};

namespace {

/// A reference point d away from the centre of mass adds m d^2 to the rotational inertia and
/// m d to the coupling of rotation and translation: the six-coordinate mass matrix's condition
/// number grows as (d / rho)^2, rho the smallest radius of gyration. Beyond
/// kMaxReferenceDistance radii of gyration (a condition number of about 1e10, leaving six of
/// sixteen digits) its factorisation loses the body's motion in round-off and, further out,
/// fails. Translations alone (every rotation fixed) do not couple: any point serves.
constexpr double kMaxReferenceDistance = 1e5;

void check_reference_point(const RigidSettings& settings, const Vector3d& r0, const Vector3d& com,
                           const Matrix3d& inertia_com, double mass) {
  if (!settings.has_reference_point) return;
  const auto& f = settings.fixed;
  if (f[3] && f[4] && f[5]) return;
  const double d = (r0 - com).norm();
  const Eigen::SelfAdjointEigenSolver<Matrix3d> eig(inertia_com);
  const double rho = std::sqrt(std::max(eig.eigenvalues().minCoeff(), 0.0) / mass);
  if (std::isfinite(d) && d <= kMaxReferenceDistance * rho) return;
  char text[700];
  std::snprintf(text, sizeof text,
                "FEM (rigid): fem.rigid.reference_point (%.6g, %.6g, %.6g) m lies %.3g m from "
                "the body's centre of mass (%.6g, %.6g, %.6g) m, %.3g times its smallest radius "
                "of gyration (%.3g m): the six-coordinate mass matrix would have a condition "
                "number of about %.1e and its factorisation would lose the motion in round-off. "
                "Accepted: within %.0e radii of gyration of the centre of mass (%.3g m); leave "
                "the key out to use the centre of mass",
                r0(0), r0(1), r0(2), d, com(0), com(1), com(2), d / rho, rho,
                1.0 + (d / rho) * (d / rho), kMaxReferenceDistance, kMaxReferenceDistance * rho);
  throw FemModelError(text);
}

}  // namespace

RigidSolver::RigidSolver(FemProblem problem, RigidSettings settings) {
  validate_problem(problem);
  impl_ = std::make_unique<Impl>();
  Impl& s = *impl_;
  s.problem = std::move(problem);
  s.settings = std::move(settings);
  const FemProblem& p = s.problem;
  // The mass of the free mesh (the clamps are the FEM's supports, not the body's).
  FemProblem unclamped = p;
  unclamped.constraints.clear();
  const DofMap dofs = make_dof_map(unclamped);
  const SparseMatrix m_full = assemble_mass(unclamped, dofs);
  // Translations of the whole body give the mass and the centre of mass.
  const std::size_t nn = p.mesh.nodes.size();
  auto rigid_map = [&](const Vector3d& ref) {
    MatrixXd g = MatrixXd::Zero(dofs.total, 6);
    for (std::size_t n = 0; n < nn; ++n) {
      const Vector3d r = Vector3d(p.mesh.nodes[n][0], p.mesh.nodes[n][1], p.mesh.nodes[n][2]) - ref;
      const auto off = dofs.node_offset[n];
      g.block(off, 0, 3, 6) = point_map(r);
      if (dofs.node_dofs[n] == 6) g.block(off + 3, 3, 3, 3) = Matrix3d::Identity();
    }
    return g;
  };
  const MatrixXd g0 = rigid_map(Vector3d::Zero());
  const MatrixXd m0 = g0.transpose() * (m_full * g0);
  s.total_mass = m0(0, 0);
  if (!(s.total_mass > 0.0))
    throw FemModelError(
        "FEM (rigid): the body has no mass: give its materials a density (> 0 "
        "kg/m^3)");
  // Static moment: m0(0:3, 3:6) = -m skew(com).
  const Matrix3d sm = -m0.block<3, 3>(0, 3) / s.total_mass;
  s.com = Vector3d(sm(2, 1), sm(0, 2), sm(1, 0));
  s.r0 = s.settings.has_reference_point
             ? Vector3d(s.settings.reference_point[0], s.settings.reference_point[1],
                        s.settings.reference_point[2])
             : s.com;
  {
    const MatrixXd gc = rigid_map(s.com);
    s.inertia_com = (gc.transpose() * (m_full * gc)).block<3, 3>(3, 3);
  }
  check_reference_point(s.settings, s.r0, s.com, s.inertia_com, s.total_mass);
  s.map_full = rigid_map(s.r0);
  s.m6 = s.map_full.transpose() * (m_full * s.map_full);
  s.m6 = 0.5 * (s.m6 + s.m6.transpose()).eval();
  // Loads projected on the six motions (with their moments about r0).
  LoadVectors loads = load_vectors(unclamped, dofs, m_full);
  s.f_const6 = s.map_full.transpose() * loads.constant;
  for (auto& [f, amp] : loads.timed) {
    s.f_timed6.push_back(s.map_full.transpose() * f);
    s.amplitudes.push_back(amp);
  }
  s.iface = build_interface(p);
  const std::size_t ni = s.iface.mesh_node.size();
  s.map_iface.resize(static_cast<Eigen::Index>(3 * ni), 6);
  for (std::size_t i = 0; i < ni; ++i) {
    const Vector3d r(s.iface.mesh.reference_positions[3 * i] - s.r0(0),
                     s.iface.mesh.reference_positions[3 * i + 1] - s.r0(1),
                     s.iface.mesh.reference_positions[3 * i + 2] - s.r0(2));
    s.map_iface.block(static_cast<Eigen::Index>(3 * i), 0, 3, 6) = point_map(r);
  }
  s.k6.setZero(6, 6);
  s.c6.setZero(6, 6);
  for (const RigidSpring& sp : s.settings.springs) {
    const Eigen::Matrix<double, 3, 6> g =
        point_map(Vector3d(sp.point[0], sp.point[1], sp.point[2]) - s.r0);
    const Vector3d k(sp.stiffness[0], sp.stiffness[1], sp.stiffness[2]);
    const Vector3d c(sp.damping[0], sp.damping[1], sp.damping[2]);
    s.k6 += g.transpose() * k.asDiagonal() * g;
    s.c6 += g.transpose() * c.asDiagonal() * g;
  }
  for (int i = 0; i < 6; ++i)
    if (!s.settings.fixed[static_cast<std::size_t>(i)]) s.free.push_back(i);
  if (s.free.empty())
    throw FemModelError(
        "FEM (rigid): every DOF of the body is fixed (fem.rigid.fixed): nothing "
        "can move");
  s.bossak = std::make_unique<ReducedBossak>(s.restrict_matrix(s.m6), s.restrict_matrix(s.k6),
                                             s.restrict_matrix(s.c6), p.damping, p.bossak);
  s.x.resize(s.nfree());
  s.forces.assign(3 * ni, 0.0);
}

RigidSolver::~RigidSolver() = default;
RigidSolver::RigidSolver(RigidSolver&&) noexcept = default;
RigidSolver& RigidSolver::operator=(RigidSolver&&) noexcept = default;

const FemProblem& RigidSolver::problem() const {
  return impl_->problem;
}
const InterfaceMesh& RigidSolver::interface_mesh() const {
  return impl_->iface.mesh;
}
double RigidSolver::mass() const {
  return impl_->total_mass;
}
std::array<double, 3> RigidSolver::centre_of_mass() const {
  return {impl_->com(0), impl_->com(1), impl_->com(2)};
}
std::array<double, 9> RigidSolver::inertia() const {
  std::array<double, 9> out{};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) out[static_cast<std::size_t>(3 * i + j)] = impl_->inertia_com(i, j);
  return out;
}
std::array<double, 3> RigidSolver::reference_point() const {
  return {impl_->r0(0), impl_->r0(1), impl_->r0(2)};
}
double RigidSolver::time() const {
  return impl_->time;
}
std::int64_t RigidSolver::step_count() const {
  return impl_->step;
}

void RigidSolver::set_interface_forces(std::span<const double> forces) {
  Impl& s = *impl_;
  check_interface_forces(forces, s.forces.size(), "RigidSolver");
  std::copy(forces.begin(), forces.end(), s.forces.begin());
  if (s.step == 0) s.accel_ready = false;
}

void RigidSolver::solve_static() {
  Impl& s = *impl_;
  try {
    s.bossak->solve_static(s.x, s.load(s.time));
  } catch (const std::runtime_error& e) {
    throw FemModelError(std::string("FEM (rigid): ") + e.what() +
                        ": give springs (fem.rigid.springs) or fixed DOFs (fem.rigid.fixed) "
                        "that hold every direction, or run it dynamically");
  }
  s.accel_ready = false;
}

void RigidSolver::advance(double dt) {
  Impl& s = *impl_;
  if (!(dt > 0.0) || !std::isfinite(dt))
    throw std::invalid_argument("RigidSolver::advance: dt = " + std::to_string(dt) +
                                " must be finite and > 0");
  if (!s.accel_ready) {
    s.bossak->init_acceleration(s.x, s.load(s.time));
    s.accel_ready = true;
  }
  s.bossak->advance(s.x, s.load(s.time + dt), dt);
  s.time += dt;
  ++s.step;
  if (!s.x.u.allFinite())
    throw FemModelError(
        "FEM (rigid): the motion became non-finite at t = " + std::to_string(s.time) + " s");
}

std::array<double, 6> RigidSolver::coordinates() const {
  const VectorXd v = impl_->six(impl_->x.u);
  return {v(0), v(1), v(2), v(3), v(4), v(5)};
}
std::array<double, 6> RigidSolver::rates() const {
  const VectorXd v = impl_->six(impl_->x.v);
  return {v(0), v(1), v(2), v(3), v(4), v(5)};
}

void RigidSolver::interface_kinematics(std::span<double> positions, std::span<double> velocities,
                                       std::span<double> accelerations) const {
  const Impl& s = *impl_;
  const std::size_t n = s.forces.size();
  if (positions.size() != n || velocities.size() != n || accelerations.size() != n)
    throw std::invalid_argument("RigidSolver::interface_kinematics: spans must hold " +
                                std::to_string(n) + " values (3 per interface node)");
  const VectorXd x = s.map_iface * s.six(s.x.u), v = s.map_iface * s.six(s.x.v),
                 a = s.map_iface * s.six(s.x.a);
  for (std::size_t i = 0; i < n; ++i) {
    const auto k = static_cast<Eigen::Index>(i);
    positions[i] = s.iface.mesh.reference_positions[i] + x(k);
    velocities[i] = v(k);
    accelerations[i] = a(k);
  }
}

double RigidSolver::max_interface_displacement() const {
  const Impl& s = *impl_;
  const VectorXd x = s.map_iface * s.six(s.x.u);
  double m = 0.0;
  for (Eigen::Index i = 0; i + 2 < x.size(); i += 3) m = std::max(m, x.segment<3>(i).norm());
  return m;
}

std::vector<double> RigidSolver::displacements() const {
  return impl_->nodal(impl_->x.u);
}
std::vector<double> RigidSolver::velocities() const {
  return impl_->nodal(impl_->x.v);
}
std::vector<double> RigidSolver::accelerations() const {
  return impl_->nodal(impl_->x.a);
}
double RigidSolver::kinetic_energy() const {
  const Impl& s = *impl_;
  return 0.5 * s.x.v.dot(s.bossak->mass() * s.x.v);
}
double RigidSolver::strain_energy() const {
  const Impl& s = *impl_;
  return 0.5 * s.x.u.dot(s.bossak->stiffness() * s.x.u);
}

void RigidSolver::save(io::H5File& file, const std::string& group) const {
  const Impl& s = *impl_;
  const std::string g = group + "_rigid";
  file.create_group(g);
  const VectorXd x6 = s.six(s.x.u), v6 = s.six(s.x.v), a6 = s.six(s.x.a);
  file.write(g + "/x", std::span<const double>(x6.data(), 6));
  file.write(g + "/v", std::span<const double>(v6.data(), 6));
  file.write(g + "/a", std::span<const double>(a6.data(), 6));
  file.write(g + "/interface_forces", std::span<const double>(s.forces));
  file.write(g + "/reference_point", std::span<const double>(s.r0.data(), 3));
  file.set_attribute(g, "mass", s.total_mass);
  file.set_attribute(g, "time", s.time);
  file.set_attribute(g, "step", s.step);
  file.set_attribute(g, "acceleration_ready", static_cast<std::int64_t>(s.accel_ready));
}

void RigidSolver::restore(const io::H5File& file, const std::string& group) {
  Impl& s = *impl_;
  const std::string g = group + "_rigid";
  const std::string where = file.path().string() + ":" + g;
  if (!file.exists(g))
    throw std::runtime_error("RigidSolver::restore: " + file.path().string() +
                             " holds no rigid-body state (group " + g + ")");
  const double mass = file.attribute_double(g, "mass");
  const auto r = file.read_doubles(g + "/reference_point");
  if (std::abs(mass - s.total_mass) > 1e-9 * s.total_mass || r.size() != 3 ||
      (Vector3d(r[0], r[1], r[2]) - s.r0).norm() > 1e-9 * (1.0 + s.r0.norm()))
    throw std::runtime_error("RigidSolver::restore: " + where +
                             " is the state of another body (mass " + std::to_string(mass) +
                             " kg, this one " + std::to_string(s.total_mass) +
                             " kg, or another reference point): the mesh, density or "
                             "fem.rigid.reference_point changed");
  auto read6 = [&](const std::string& name) {
    const auto d = file.read_doubles(g + "/" + name);
    if (d.size() != 6)
      throw std::runtime_error("RigidSolver::restore: " + where + "/" + name + " is malformed");
    for (double v : d)
      if (!std::isfinite(v))
        throw std::runtime_error("RigidSolver::restore: " + where + "/" + name +
                                 " is not finite; resume from an earlier checkpoint");
    return s.restrict_vector(Eigen::Map<const VectorXd>(d.data(), 6));
  };
  s.x.u = read6("x");
  s.x.v = read6("v");
  s.x.a = read6("a");
  const auto f = file.read_doubles(g + "/interface_forces");
  if (f.size() != s.forces.size())
    throw std::runtime_error("RigidSolver::restore: " + where +
                             "/interface_forces does not match the interface size");
  s.forces = f;
  s.time = file.attribute_double(g, "time");
  s.step = file.attribute_int64(g, "step");
  s.accel_ready = file.attribute_int64(g, "acceleration_ready") != 0;
}

}  // namespace demfem::fem
