// Constant-stress states (exact for every element), gravity and reactions, the exterior
// interface surface of volume meshes, and input validation.
#include <catch2/catch.hpp>

#include "demfem/fem/fem_solver.hpp"
#include "fem_test_util.hpp"

using namespace demfem::fem;

namespace {

FemProblem tension_bar(bool tet, double stress) {
  const double l = 1.0, b = 0.2;
  Mesh m = tet ? box_mesh_tet({0, 0, 0}, {l, b, b}, {5, 2, 2})
               : box_mesh_hex({0, 0, 0}, {l, b, b}, {5, 2, 2});
  auto p = test::make_problem(std::move(m), 200e9, 0.3, 7800);
  // Symmetry (roller) supports on three faces: no rigid-body motion, free contraction.
  test::clamp(p, "xmin", {true, false, false, false, false, false});
  test::clamp(p, "ymin", {false, true, false, false, false, false});
  test::clamp(p, "zmin", {false, false, true, false, false, false});
  PressureLoad t;
  t.faces = p.mesh.surfaces.at("xmax");
  t.magnitude = -stress;  // negative pressure = tension
  t.amplitude = [](double) { return 1.0; };
  p.pressures.push_back(t);
  return p;
}

}  // namespace

TEST_CASE("uniaxial tension is exact for hex8 and tet4", "[fem][solid]") {
  for (bool tet : {false, true}) {
    const double sigma = 1e6, e = 200e9, nu = 0.3;
    const auto p = tension_bar(tet, sigma);
    FemSolver s(p);
    s.solve_static();
    const auto u = s.displacements();
    const auto corner = test::node_at(p.mesh, 1.0, 0.2, 0.2);
    // Exact: u_x = sigma L / E, u_y = u_z = -nu sigma b / E (relative tolerance 1e-9).
    CHECK(u[3 * corner] == Approx(sigma / e).epsilon(1e-9));
    CHECK(u[3 * corner + 1] == Approx(-nu * sigma * 0.2 / e).epsilon(1e-9));
    CHECK(u[3 * corner + 2] == Approx(-nu * sigma * 0.2 / e).epsilon(1e-9));
    const auto r = s.element_results();
    for (std::size_t i = 0; i < p.mesh.elements.size(); ++i) {
      CHECK(r.von_mises[i] == Approx(sigma).epsilon(1e-8));
      CHECK(r.strain[6 * i] == Approx(sigma / e).epsilon(1e-8));
      CHECK(r.max_principal_strain[i] == Approx(sigma / e).epsilon(1e-8));
    }
    // Reactions on the x = 0 face carry the load: sigma * area.
    const auto rf = s.reaction_forces();
    double rx = 0;
    for (std::size_t i = 0; i < rf.size(); i += 3) rx += rf[i];
    CHECK(rx == Approx(-sigma * 0.04).epsilon(1e-9));
  }
}

TEST_CASE("gravity: reactions equal the weight, consistent and lumped mass", "[fem][solid]") {
  for (auto lump : {MassLumping::consistent, MassLumping::lumped})
    for (int kind = 0; kind < 3; ++kind) {
      FemProblem p;
      if (kind == 2) {
        p = test::make_problem(plate_mesh_quad({0, 0, 0}, 1.0, 0.5, {4, 3}), 200e9, 0.3, 7800,
                               0.01);
      } else {
        p = test::make_problem(kind == 0 ? box_mesh_hex({0, 0, 0}, {1, 0.5, 0.2}, {4, 3, 2})
                                         : box_mesh_tet({0, 0, 0}, {1, 0.5, 0.2}, {4, 3, 2}),
                               200e9, 0.3, 7800);
      }
      p.mass = lump;
      test::clamp(p, "xmin");
      p.gravity = {0, 0, -9.81};
      const double volume = kind == 2 ? 1.0 * 0.5 * 0.01 : 0.1;
      FemSolver s(p);
      s.solve_static();
      const auto r = s.reaction_forces();
      double rz = 0;
      for (std::size_t i = 2; i < r.size(); i += 3) rz += r[i];
      CHECK(rz == Approx(7800 * volume * 9.81).epsilon(1e-9));
    }
}

TEST_CASE("interface surface of a volume mesh is closed, outward and complete",
          "[fem][interface]") {
  for (bool tet : {false, true}) {
    Mesh m = tet ? box_mesh_tet({0, 0, 0}, {2, 3, 4}, {2, 3, 4})
                 : box_mesh_hex({0, 0, 0}, {2, 3, 4}, {2, 3, 4});
    FemSolver s(test::make_problem(std::move(m), 1e9, 0.3, 1000));
    const auto& im = s.interface_mesh();
    // Surface nodes: all 3*4*5 nodes but the 1*2*3 interior ones; 2 triangles per square.
    CHECK(im.node_count() == 60 - 6);
    CHECK(im.triangle_count() == 2 * (2 * 12 + 2 * 8 + 2 * 6));
    // Divergence theorem: V = 1/3 sum (x . n) dA, exact for a closed outward surface; the
    // area vectors sum to zero.
    double v = 0;
    Eigen::Vector3d total = Eigen::Vector3d::Zero();
    for (std::size_t t = 0; t < im.triangle_count(); ++t) {
      Eigen::Vector3d x[3];
      for (int a = 0; a < 3; ++a)
        for (int c = 0; c < 3; ++c)
          x[a](c) =
              im.reference_positions[3 * static_cast<std::size_t>(im.triangles[3 * t + a]) + c];
      const Eigen::Vector3d an = 0.5 * (x[1] - x[0]).cross(x[2] - x[0]);
      v += (x[0] + x[1] + x[2]).dot(an) / 9.0;
      total += an;
    }
    CHECK(v == Approx(24.0).epsilon(1e-12));
    CHECK(total.norm() < 1e-12);
  }
  // A named surface restricts the interface to it.
  auto p = test::make_problem(box_mesh_hex({0, 0, 0}, {1, 1, 1}, {2, 2, 2}), 1e9, 0.3, 1000);
  p.interface_surface = "zmax";
  FemSolver s(p);
  CHECK(s.interface_mesh().node_count() == 9);
  CHECK(s.interface_mesh().triangle_count() == 8);
}

TEST_CASE("interface forces load the structure like the equivalent nodal loads",
          "[fem][interface]") {
  auto p = test::make_problem(box_mesh_hex({0, 0, 0}, {1, 0.2, 0.2}, {5, 1, 1}), 200e9, 0.3, 7800);
  test::clamp(p, "xmin");
  p.interface_surface = "xmax";
  FemSolver a(p);
  const auto& im = a.interface_mesh();
  REQUIRE(im.node_count() == 4);
  std::vector<double> f(12, 0.0);
  for (int i = 0; i < 4; ++i) f[3 * static_cast<std::size_t>(i) + 2] = -250.0;
  a.set_interface_forces(f);
  a.solve_static();
  NodalLoad nl;
  nl.nodes = p.mesh.node_sets.at("xmax");
  nl.force = {0, 0, -250.0};
  p.nodal_loads.push_back(nl);
  p.interface_surface.clear();
  FemSolver b(p);
  b.solve_static();
  const auto ua = a.displacements(), ub = b.displacements();
  for (std::size_t i = 0; i < ua.size(); ++i) CHECK(ua[i] == Approx(ub[i]).margin(1e-15));
  // Kinematics: positions are reference + displacement of the mapped mesh node.
  std::vector<double> pos(12), vel(12), acc(12);
  a.interface_kinematics(pos, vel, acc);
  for (std::size_t i = 0; i < 4; ++i) {
    const auto n =
        test::node_at(p.mesh, im.reference_positions[3 * i], im.reference_positions[3 * i + 1],
                      im.reference_positions[3 * i + 2]);
    CHECK(static_cast<std::size_t>(a.interface_mesh_nodes()[i]) == n);
    for (std::size_t c = 0; c < 3; ++c)
      CHECK(pos[3 * i + c] == im.reference_positions[3 * i + c] + ua[3 * n + c]);
  }
  CHECK_THROWS_WITH(a.set_interface_forces(std::vector<double>(5, 0.0)),
                    Catch::Contains("expected 12"));
}

TEST_CASE("bad input is rejected with a clear message", "[fem][validation]") {
  auto good = test::make_problem(box_mesh_hex({0, 0, 0}, {1, 1, 1}, {1, 1, 1}), 1e9, 0.3, 1000);
  test::clamp(good, "xmin");
  auto p = good;
  p.materials[0].youngs_modulus = -1;
  CHECK_THROWS_WITH(FemSolver(p), Catch::Contains("youngs_modulus"));
  p = good;
  p.materials[0].poisson_ratio = 0.5;
  CHECK_THROWS_WITH(FemSolver(p), Catch::Contains("poisson_ratio"));
  p = good;
  p.mesh.elements[0].nodes[3] = 99;
  CHECK_THROWS_WITH(FemSolver(p), Catch::Contains("out of range"));
  p = good;
  std::swap(p.mesh.elements[0].nodes[1], p.mesh.elements[0].nodes[3]);
  std::swap(p.mesh.elements[0].nodes[5], p.mesh.elements[0].nodes[7]);
  CHECK_THROWS_WITH(FemSolver(p), Catch::Contains("Jacobian"));
  p = good;
  p.interface_surface = "nope";
  CHECK_THROWS_WITH(FemSolver(p), Catch::Contains("'nope'"));
  p = good;
  p.bossak.alpha = 0.2;
  CHECK_THROWS_WITH(FemSolver(p), Catch::Contains("alpha"));
  p = good;
  p.constraints.clear();  // unconstrained: singular stiffness
  FemSolver free_body(p);
  CHECK_THROWS_WITH(free_body.solve_static(), Catch::Contains("not positive definite"));
  FemSolver s(good);
  CHECK_THROWS_WITH(s.advance(-1.0), Catch::Contains("dt"));
  CHECK_THROWS_WITH(s.advance(std::nan("")), Catch::Contains("dt"));
  auto shell = test::make_problem(plate_mesh_quad({0, 0, 0}, 1, 1, {1, 1}), 1e9, 0.3, 1000, 0.0);
  CHECK_THROWS_WITH(FemSolver(shell), Catch::Contains("thickness"));
}
