// The two sparse factorisations (CHOLMOD, Eigen SimplicialLDLT) solve the same systems:
// static and dynamic results agree to round-off.
#include <catch2/catch.hpp>

#include "demfem/fem/fem_solver.hpp"
#include "fem_test_util.hpp"

using namespace demfem::fem;

TEST_CASE("CHOLMOD and SimplicialLDLT give the same static and dynamic results", "[fem][solver]") {
  auto p =
      test::make_problem(box_mesh_hex({0, 0, 0}, {1.0, 0.1, 0.1}, {20, 2, 2}), 210e9, 0.3, 7850);
  test::clamp(p, "xmin");
  PressureLoad q;
  q.faces = p.mesh.surfaces.at("zmax");
  q.magnitude = 5000.0;
  q.amplitude = [](double t) { return 1.0 + std::sin(2000 * t); };
  p.pressures.push_back(q);
  std::vector<std::vector<double>> stat, dyn;
  std::vector<SolverBackend> backends{SolverBackend::simplicial_ldlt};
  if (cholmod_available()) backends.push_back(SolverBackend::cholmod);
  for (auto b : backends) {
    FemSolver s(p, b);
    CHECK(s.solver_backend() == b);
    s.solve_static();
    stat.push_back(s.displacements());
    for (int i = 0; i < 20; ++i) s.advance(1e-4);
    dyn.push_back(s.displacements());
  }
  if (backends.size() < 2) return;
  // Different factorisations: agreement to 1e-9 of the largest displacement.
  for (auto* r : {&stat, &dyn}) {
    double umax = 0;
    for (double v : (*r)[0]) umax = std::max(umax, std::abs(v));
    REQUIRE(umax > 0);
    for (std::size_t i = 0; i < (*r)[0].size(); ++i)
      CHECK(std::abs((*r)[0][i] - (*r)[1][i]) < 1e-9 * umax);
  }
}
