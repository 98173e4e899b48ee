// hex8 with full integration and the mean-dilatation B-bar (SolidFormulation::
// selective_reduced, the Abaqus C3D8 formulation): patch test, rigid-body modes, freedom from
// volumetric locking against Lame's thick cylinder, Abaqus' own C3D8 figures on the Getting
// Started cantilever (shear locking), and convergence on the fixed-fixed beam.
#include <catch2/catch.hpp>

#include <cmath>
#include <cstdio>
#include <random>

#include "demfem/fem/fem_solver.hpp"
#include "fem_test_util.hpp"

using namespace demfem::fem;

namespace {

void use_bbar(Mesh& m) {
  for (auto& e : m.elements) e.formulation = SolidFormulation::selective_reduced;
}

/// Quarter of a thick cylinder a <= r <= b, 0 <= theta <= 90 deg, 0 <= z <= t, nr x nt x 1
/// hex8 (node order: r, then theta, then z, so that the Jacobian is positive).
Mesh quarter_cylinder(double a, double b, double t, int nr, int nt) {
  Mesh m;
  auto id = [&](int i, int j, int k) { return (k * (nt + 1) + j) * (nr + 1) + i; };
  for (int k = 0; k <= 1; ++k)
    for (int j = 0; j <= nt; ++j)
      for (int i = 0; i <= nr; ++i) {
        const double r = a + (b - a) * i / nr, th = M_PI / 2 * j / nt;
        m.nodes.push_back({r * std::cos(th), r * std::sin(th), t * k});
      }
  for (int j = 0; j < nt; ++j)
    for (int i = 0; i < nr; ++i) {
      Element e;
      e.nodes = {id(i, j, 0), id(i + 1, j, 0), id(i + 1, j + 1, 0), id(i, j + 1, 0),
                 id(i, j, 1), id(i + 1, j, 1), id(i + 1, j + 1, 1), id(i, j + 1, 1)};
      m.elements.push_back(e);
    }
  return m;
}

/// Radial displacement at the inner radius of a plane-strain thick cylinder under internal
/// pressure p; returns (FEM, Lame).
std::pair<double, double> lame_cylinder(SolidFormulation f, double nu) {
  const double a = 0.1, b = 0.2, t = 0.01, e = 1e9, p = 1e6;
  const int nr = 8, nt = 16;
  auto prob = test::make_problem(quarter_cylinder(a, b, t, nr, nt), e, nu, 1000);
  for (auto& el : prob.mesh.elements) el.formulation = f;
  std::vector<std::int32_t> x0, y0, all;
  for (std::size_t n = 0; n < prob.mesh.nodes.size(); ++n) {
    const auto& x = prob.mesh.nodes[n];
    if (std::abs(x[0]) < 1e-12) x0.push_back(static_cast<std::int32_t>(n));
    if (std::abs(x[1]) < 1e-12) y0.push_back(static_cast<std::int32_t>(n));
    all.push_back(static_cast<std::int32_t>(n));
  }
  // Symmetry planes and plane strain (u_z = 0 everywhere).
  prob.constraints.push_back({x0, {true, false, false, false, false, false}});
  prob.constraints.push_back({y0, {false, true, false, false, false, false}});
  prob.constraints.push_back({all, {false, false, true, false, false, false}});
  PressureLoad load;
  for (int j = 0; j < nt; ++j) load.faces.push_back({j * nr, 5});  // S6: the r = a face
  load.magnitude = p;
  prob.pressures.push_back(load);
  FemSolver s(std::move(prob));
  s.solve_static();
  const auto u = s.displacements();
  // Node at r = a, theta = 45 deg.
  const std::size_t n = static_cast<std::size_t>((nt / 2) * (nr + 1));
  const double ur = (u[3 * n] + u[3 * n + 1]) / std::sqrt(2.0);
  const double lame = (1 + nu) * p * a * a / (e * (b * b - a * a)) * ((1 - 2 * nu) * a + b * b / a);
  return {ur, lame};
}

double fixed_beam_deflection(SolidFormulation f, int nx, int ny) {
  const auto r = test::fixed_beam(nx, ny, f);
  CHECK(r.reaction_z == Approx(500.0).epsilon(1e-9));
  return r.deflection;
}

}  // namespace

TEST_CASE("hex8 B-bar passes the patch test on a distorted mesh, also near incompressibility",
          "[fem][bbar]") {
  for (double nu : {0.3, 0.4999}) {
    Mesh m = box_mesh_hex({0, 0, 0}, {1, 1, 1}, {3, 3, 3});
    std::vector<bool> boundary(m.nodes.size(), false);
    for (const char* s : {"xmin", "xmax", "ymin", "ymax", "zmin", "zmax"})
      for (auto i : m.node_sets.at(s)) boundary[static_cast<std::size_t>(i)] = true;
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> jitter(-0.1, 0.1);
    for (std::size_t i = 0; i < m.nodes.size(); ++i)
      if (!boundary[i])
        for (auto& c : m.nodes[i]) c += jitter(rng);
    use_bbar(m);
    // Linear field on the boundary: the interior must follow it exactly (constant strain).
    auto p = test::make_problem(m, 210e9, nu, 7850);
    const Eigen::Matrix3d a =
        (Eigen::Matrix3d() << 1e-3, 2e-4, -3e-4, 5e-4, -2e-3, 1e-4, -4e-4, 3e-4, 1.5e-3).finished();
    std::vector<std::int32_t> bnodes;
    for (std::size_t i = 0; i < m.nodes.size(); ++i)
      if (boundary[i]) {
        const auto& x = m.nodes[i];
        const Eigen::Vector3d u = a * Eigen::Vector3d(x[0], x[1], x[2]);
        Constraint c;
        c.nodes = {static_cast<std::int32_t>(i)};
        c.value = {u(0), u(1), u(2), 0, 0, 0};
        p.constraints.push_back(c);
      }
    FemSolver s(std::move(p));
    s.solve_static();
    const auto u = s.displacements();
    double err = 0, size = 0;
    for (std::size_t i = 0; i < m.nodes.size(); ++i) {
      const auto& x = m.nodes[i];
      const Eigen::Vector3d ex = a * Eigen::Vector3d(x[0], x[1], x[2]);
      for (int c = 0; c < 3; ++c) {
        err = std::max(err, std::abs(u[3 * i + static_cast<std::size_t>(c)] - ex(c)));
        size = std::max(size, std::abs(ex(c)));
      }
    }
    INFO("nu = " << nu << ", relative error " << err / size);
    CHECK(err / size < 1e-9);  // exact up to round-off; a failed patch test gives ~1e-2
    // Centroid strain of every element is the constant strain of the field.
    const auto r = s.element_results();
    const Eigen::Matrix3d eps = 0.5 * (a + a.transpose());
    for (std::size_t e = 0; e < m.elements.size(); ++e) {
      CHECK(r.strain[6 * e + 0] == Approx(eps(0, 0)).epsilon(1e-8));
      CHECK(r.strain[6 * e + 3] == Approx(2 * eps(0, 1)).epsilon(1e-8));
    }
  }
}

TEST_CASE("hex8 B-bar element stiffness has exactly the six rigid-body null modes", "[fem][bbar]") {
  Mesh m = box_mesh_hex({0, 0, 0}, {1, 1, 1}, {1, 1, 1});
  m.nodes[7] = {1.2, 1.1, 0.9};
  use_bbar(m);
  const auto p = test::make_problem(m, 1.0, 0.3, 1.0);
  const DofMap d = make_dof_map(p);
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(Eigen::MatrixXd(assemble_stiffness(p, d)));
  const auto ev = es.eigenvalues();
  int zeros = 0;
  for (Eigen::Index i = 0; i < ev.size(); ++i) zeros += std::abs(ev(i)) < 1e-10 * ev.maxCoeff();
  CHECK(zeros == 6);
  CHECK(ev.minCoeff() > -1e-10 * ev.maxCoeff());
}

TEST_CASE("hex8 B-bar does not lock volumetrically: Lame's thick cylinder", "[fem][bbar]") {
  // Plane strain, p = 1 MPa inside, a = 0.1, b = 0.2 m, 8 x 16 elements in a quarter.
  // Reference: Lame, u(a) = (1 + nu) p a^2 / (E (b^2 - a^2)) ((1 - 2 nu) a + b^2 / a).
  for (double nu : {0.3, 0.49, 0.4999}) {
    const auto [fem, lame] = lame_cylinder(SolidFormulation::selective_reduced, nu);
    const auto [im, lame2] = lame_cylinder(SolidFormulation::incompatible_modes, nu);
    std::printf(
        "Lame cylinder, nu = %.4f: B-bar %.6e, incompatible modes %.6e, Lame %.6e m "
        "(%+.3f %%, %+.3f %%)\n",
        nu, fem, im, lame, 100 * (fem / lame - 1), 100 * (im / lame2 - 1));
    // Faceted circle (16 facets on 90 deg) and 8 elements through the wall: 1 %.
    CHECK(fem == Approx(lame).epsilon(0.01));
  }
}

TEST_CASE("hex8 B-bar reproduces Abaqus C3D8 on the Getting Started cantilever", "[fem][bbar]") {
  // Abaqus "Getting Started", element formulation and integration: a cantilever 150 mm long,
  // 2.5 mm wide, 5 mm deep, E = 70 GPa, nu = 0, 5 N at the tip; beam theory 3.09 mm. Meshes
  // depth x length 1x6, 2x12, 4x12, 8x24 (one element across the width). The guide: with
  // C3D8 "even a fine mesh (8 x 24) still predicts a tip displacement that is only 56 % of
  // the theoretical value", and "for the linear, fully integrated elements it makes no
  // difference how many elements there are through the thickness" (2x12 vs 4x12).
  const int meshes[4][2] = {{1, 6}, {2, 12}, {4, 12}, {8, 24}};
  const double beam = 5.0 * 0.15 * 0.15 * 0.15 / (3 * 70e9 * 0.0025 * 0.005 * 0.005 * 0.005 / 12);
  double ratio[2][4];
  for (int f = 0; f < 2; ++f)
    for (int k = 0; k < 4; ++k) {
      auto p = test::make_problem(
          box_mesh_hex({0, 0, 0}, {0.150, 0.0025, 0.005}, {meshes[k][1], 1, meshes[k][0]}), 70e9,
          0.0, 2700);
      for (auto& e : p.mesh.elements)
        e.formulation =
            f == 0 ? SolidFormulation::selective_reduced : SolidFormulation::incompatible_modes;
      test::clamp(p, "xmin");
      const auto tip = p.mesh.node_sets.at("xmax");
      p.nodal_loads.push_back({tip, {0, 0, 5.0 / static_cast<double>(tip.size())}, {}});
      FemSolver s(std::move(p));
      s.solve_static();
      const auto u = s.displacements();
      double w = 0;
      for (auto n : tip) w += u[3 * static_cast<std::size_t>(n) + 2];
      ratio[f][k] = w / static_cast<double>(tip.size()) / beam;
    }
  std::printf(
      "Getting Started cantilever, tip / beam theory (1x6, 2x12, 4x12, 8x24): B-bar %.3f "
      "%.3f %.3f %.3f; incompatible modes %.3f %.3f %.3f %.3f\n",
      ratio[0][0], ratio[0][1], ratio[0][2], ratio[0][3], ratio[1][0], ratio[1][1], ratio[1][2],
      ratio[1][3]);
  CHECK(ratio[0][3] == Approx(0.56).margin(0.01));          // "only 56 %"
  CHECK(ratio[0][2] == Approx(ratio[0][1]).epsilon(0.03));  // "no difference"
  CHECK(ratio[0][0] < ratio[0][1]);                         // coarsest locks most
  for (int k = 1; k < 4; ++k) CHECK(ratio[1][k] == Approx(1.0).epsilon(0.01));  // C3D8I: no locking
}

TEST_CASE("hex8 B-bar in bending: converges to the fixed-fixed beam", "[fem][bbar]") {
  // The fixed-fixed beam of test_fem_beam.cpp (converged 3-D value 8.2192e-7 m, Richardson
  // from incompatible modes; docs/verification.md). Cubic elements, two or more through the
  // depth: little shear locking.
  const double w_inf = 8.2192e-7;
  const double b50 = fixed_beam_deflection(SolidFormulation::selective_reduced, 20, 2);
  const double b25 = fixed_beam_deflection(SolidFormulation::selective_reduced, 40, 4);
  const double i50 = fixed_beam_deflection(SolidFormulation::incompatible_modes, 20, 2);
  std::printf(
      "fixed beam, B-bar: w50 = %.5e (%+.2f %%), w25 = %.5e (%+.2f %%); incompatible "
      "modes w50 = %.5e (%+.2f %%)\n",
      b50, 100 * (b50 / w_inf - 1), b25, 100 * (b25 / w_inf - 1), i50, 100 * (i50 / w_inf - 1));
  CHECK(b50 < i50);  // a little stiffer than incompatible modes
  CHECK(b50 < b25);  // converging from below
  CHECK(b25 < w_inf);
  CHECK(std::abs(b25 - w_inf) < 0.5 * std::abs(b50 - w_inf));  // the error at least halves
}
