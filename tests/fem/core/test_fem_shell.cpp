// MITC4 shell: cantilever strip 340 x 100 x 0.75 mm (E = 185 GPa, nu = 0.3) under uniform
// pressure, 10 mm elements, against plate-strip (cylindrical bending) theory.
#include <catch2/catch.hpp>

#include <cstdio>

#include "demfem/fem/fem_solver.hpp"
#include "fem_test_util.hpp"

using namespace demfem::fem;

namespace {
constexpr double kL = 0.34, kB = 0.1, kT = 0.75e-3, kE = 185e9, kNu = 0.3, kP = 10.0;

FemProblem strip(bool symmetric_edges) {
  auto p = test::make_problem(plate_mesh_quad({0, 0, 0}, kL, kB, {34, 10}), kE, kNu, 7850, kT);
  test::clamp(p, "xmin");
  if (symmetric_edges) {
    // Symmetry planes y = 0 and y = b (uy = 0, theta_x = theta_z = 0): a strip cut out of
    // an infinitely wide plate, i.e. exactly the plate-strip (cylindrical bending) case.
    for (const char* e : {"ymin", "ymax"})
      test::clamp(p, e, {false, true, false, true, false, true});
  }
  PressureLoad q;
  q.faces = p.mesh.surfaces.at("top");
  q.magnitude = kP;  // pushes the top surface down (-z)
  p.pressures.push_back(q);
  return p;
}

double tip_deflection(const FemProblem& p) {
  FemSolver s(p);
  s.solve_static();
  const auto u = s.displacements();
  return -u[3 * test::node_at(p.mesh, kL, kB / 2, 0) + 2];
}
}  // namespace

TEST_CASE("shell cantilever strip matches plate-strip theory", "[fem][shell]") {
  const double d = kE * kT * kT * kT / (12 * (1 - kNu * kNu));
  // Plate strip (Kirchhoff): w = p L^4 / (8 D), D = E t^3 / (12 (1 - nu^2)); the Mindlin
  // shear part p L^2 / (2 k G t) is 2e-5 of it here.
  const double w_plate = kP * kL * kL * kL * kL / (8 * d);
  const double w_sym = tip_deflection(strip(true));
  const double w_free = tip_deflection(strip(false));
  const double w_beam = w_plate / (1 - kNu * kNu);  // E I = (1 - nu^2) D b
  std::printf(
      "shell strip: plate-strip %.6e, symmetric edges %.6e (%.3f %%), free edges %.6e, "
      "beam %.6e m\n",
      w_plate, w_sym, 100 * (w_sym / w_plate - 1), w_free, w_beam);
  // Task tolerance: within 2 % of plate-strip theory at 10 mm elements.
  CHECK(std::abs(w_sym / w_plate - 1) < 0.02);
  // With free long edges the strip may curl anticlastically (beam-like, E I) except near the
  // clamp, where the plate stiffness D b holds: the result lies between the two theories.
  CHECK(w_free < w_beam);
  CHECK(w_free > w_sym);
}

TEST_CASE("shell interface: offset surfaces, force and moment onto the mid-surface",
          "[fem][shell]") {
  auto p = test::make_problem(plate_mesh_quad({0, 0, 0}, kL, kB, {34, 10}), kE, kNu, 7850, kT);
  test::clamp(p, "xmin");
  FemSolver s(p);
  const auto& im = s.interface_mesh();
  const std::size_t mid_nodes = p.mesh.nodes.size();
  REQUIRE(im.node_count() == 2 * mid_nodes);                       // top and bottom copy per node
  REQUIRE(im.triangle_count() == 2 * 2 * p.mesh.elements.size());  // 2 surfaces, quads split
  // Every copy sits at z = +-t/2 and every triangle's normal points away from the plate.
  for (std::size_t i = 0; i < im.node_count(); ++i)
    CHECK(std::abs(std::abs(im.reference_positions[3 * i + 2]) - kT / 2) < 1e-15);
  for (std::size_t t = 0; t < im.triangle_count(); ++t) {
    Eigen::Vector3d x[3];
    for (int a = 0; a < 3; ++a)
      for (int c = 0; c < 3; ++c)
        x[a](c) = im.reference_positions[3 * static_cast<std::size_t>(im.triangles[3 * t + a]) + c];
    const Eigen::Vector3d n = (x[1] - x[0]).cross(x[2] - x[0]);
    CHECK(n.z() * x[0].z() > 0);
  }
  // Tangential force F (+x) on the top copies of the tip nodes: force F plus moment
  // (t/2 e_z) x F = +F t/2 about y on the mid-surface. Beam theory for an end moment M:
  // tip rotation M L / (E I), deflection w = -M L^2 / (2 E I) (the stretched top fibre
  // bends the strip down).
  const double f_total = 1.0;
  std::vector<double> f(3 * im.node_count(), 0.0);
  const auto& tip = p.mesh.node_sets.at("xmax");
  int n_top = 0;
  for (std::size_t i = 0; i < im.node_count(); ++i)
    if (std::abs(im.reference_positions[3 * i] - kL) < 1e-12 &&
        im.reference_positions[3 * i + 2] > 0)
      ++n_top;
  REQUIRE(n_top == static_cast<int>(tip.size()));
  for (std::size_t i = 0; i < im.node_count(); ++i)
    if (std::abs(im.reference_positions[3 * i] - kL) < 1e-12 &&
        im.reference_positions[3 * i + 2] > 0)
      f[3 * i] = f_total / n_top;
  s.set_interface_forces(f);
  s.solve_static();
  const auto u = s.displacements();
  const double w = -u[3 * test::node_at(p.mesh, kL, kB / 2, 0) + 2];
  const double ei = kE * kB * kT * kT * kT / 12;
  const double w_beam = f_total * kT / 2 * kL * kL / (2 * ei);
  std::printf("shell offset moment: tip w = %.6e, beam theory %.6e m\n", w, w_beam);
  // Free edges under a pure end moment: E I (beam) except near the clamp (plate stiffness):
  // between the beam value and (1 - nu^2) times it. Without the offset moment w would be ~0.
  CHECK(w < w_beam * 1.0001);
  CHECK(w > (1 - kNu * kNu) * w_beam);
  // Reactions balance the applied force.
  const auto r = s.reaction_forces();
  double rx = 0;
  for (std::size_t i = 0; i < r.size(); i += 3) rx += r[i];
  CHECK(rx == Approx(-f_total).epsilon(1e-9));
  // Kinematics: the top copy follows x_mid + u + theta x (t/2 n).
  std::vector<double> pos(3 * im.node_count()), vel(pos.size()), acc(pos.size());
  s.interface_kinematics(pos, vel, acc);
  for (std::size_t i = 0; i < im.node_count(); ++i)
    if (std::abs(im.reference_positions[3 * i] - kL) < 1e-12 &&
        std::abs(im.reference_positions[3 * i + 1] - kB / 2) < 1e-12) {
      const double side = im.reference_positions[3 * i + 2] > 0 ? 1 : -1;
      // theta_y from the mid-surface slope: x-displacement of the copy = side t/2 theta_y.
      const double ux_copy = pos[3 * i] - im.reference_positions[3 * i];
      const double ux_mid = u[3 * test::node_at(p.mesh, kL, kB / 2, 0)];
      CHECK(std::abs(ux_copy - ux_mid) > 0);
      CHECK((ux_copy - ux_mid) * side > 0);  // the top fibre moves out, the bottom one back
    }
}

TEST_CASE("MITC4 passes the membrane and bending patch test on a distorted mesh", "[fem][shell]") {
  // Flat 3 x 3 patch, interior nodes moved in-plane. Boundary nodes get the exact values of
  // a constant membrane strain + constant curvature state (Kirchhoff kinematics, zero
  // transverse shear): u = a x + b y, v = c x + e y, w = (kx x^2 + ky y^2 + kxy x y) / 2,
  // theta_x = dw/dy, theta_y = -dw/dx (u(z) = theta x (z n)), theta_z = (c - b) / 2 (the
  // in-plane rotation the drilling penalty ties it to). Interior nodes must come out exact.
  Mesh m = plate_mesh_quad({0, 0, 0}, 1.0, 1.0, {3, 3});
  std::vector<bool> boundary(m.nodes.size(), false);
  for (const char* e : {"xmin", "xmax", "ymin", "ymax"})
    for (auto i : m.node_sets.at(e)) boundary[static_cast<std::size_t>(i)] = true;
  const double shift[4][2] = {{0.07, -0.05}, {-0.06, 0.04}, {0.05, 0.08}, {-0.08, -0.03}};
  int k = 0;
  for (std::size_t i = 0; i < m.nodes.size(); ++i)
    if (!boundary[i]) {
      m.nodes[i][0] += shift[k][0];
      m.nodes[i][1] += shift[k][1];
      ++k;
    }
  const auto p = test::make_problem(m, 200e9, 0.3, 7800, 0.01);
  const double a = 1e-3, b = 2e-4, c = -3e-4, e = 5e-4, kx = 2e-3, ky = -1e-3, kxy = 5e-4;
  const DofMap d = make_dof_map(p);
  const Eigen::MatrixXd kk(assemble_stiffness(p, d));
  Eigen::VectorXd exact(d.total);
  std::vector<Eigen::Index> in, bd;
  for (std::size_t i = 0; i < m.nodes.size(); ++i) {
    const double x = m.nodes[i][0], y = m.nodes[i][1];
    const double vals[6] = {a * x + b * y,
                            c * x + e * y,
                            0.5 * (kx * x * x + ky * y * y + kxy * x * y),
                            ky * y + 0.5 * kxy * x,
                            -(kx * x + 0.5 * kxy * y),
                            0.5 * (c - b)};
    for (int q = 0; q < 6; ++q) {
      exact(d.node_offset[i] + q) = vals[q];
      (boundary[i] ? bd : in).push_back(d.node_offset[i] + q);
    }
  }
  Eigen::MatrixXd kii(in.size(), in.size()), kib(in.size(), bd.size());
  Eigen::VectorXd xb(bd.size()), xi(in.size());
  for (std::size_t r = 0; r < in.size(); ++r) {
    xi(r) = exact(in[r]);
    for (std::size_t q = 0; q < in.size(); ++q) kii(r, q) = kk(in[r], in[q]);
    for (std::size_t q = 0; q < bd.size(); ++q) kib(r, q) = kk(in[r], bd[q]);
  }
  for (std::size_t q = 0; q < bd.size(); ++q) xb(q) = exact(bd[q]);
  const Eigen::VectorXd sol = kii.ldlt().solve(-kib * xb);
  const double err = (sol - xi).cwiseAbs().maxCoeff() / exact.cwiseAbs().maxCoeff();
  std::printf("MITC4 patch test: max interior error %.3e (relative)\n", err);
  CHECK(err < 1e-8);  // exact up to round-off (the stiffness spans 1e-3 .. 1e9)
}
