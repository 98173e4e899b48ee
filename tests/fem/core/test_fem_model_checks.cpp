// Issue 19, defects 2 and 15: models that pass a reader but cannot be solved are refused with
// a message naming what is wrong (the sparse solver no longer crashes or returns garbage),
// orphan nodes are left out, a mechanism names its free nodes, element errors name the file
// and line, and user-set Bossak parameters are checked for stability.
#include <catch2/catch.hpp>

#include <cmath>
#include <cstdio>

#include "demfem/fem/fem_solver.hpp"
#include "demfem_test/error_of.hpp"
#include "fem_test_util.hpp"

using namespace demfem::fem;
using Catch::Contains;

namespace {

const SolverBackend kBackends[] = {SolverBackend::cholmod, SolverBackend::simplicial_ldlt};

SparseMatrix dense_to_sparse(const Eigen::MatrixXd& d) {
  return d.sparseView();
}

std::string factorize_error(const SparseMatrix& a, SolverBackend b) {
  if (b == SolverBackend::cholmod && !cholmod_available()) return "skipped";
  SparseSpdSolver s(b);
  return demfem::test::error_of<SingularMatrixError>([&] { s.factorize(a, "test matrix"); },
                                                     "no error");
}

/// Two 1 m cubes of 2 x 2 x 2 hex8 sharing only the edge x = 1, z = 1 (along y): the second
/// can turn about it (a hinge). The first is clamped at x = 0.
FemProblem hinge() {
  const Mesh a = box_mesh_hex({0, 0, 0}, {1, 1, 1}, {2, 2, 2});
  const Mesh c = box_mesh_hex({1, 0, 1}, {2, 1, 2}, {2, 2, 2});
  Mesh m = a;
  std::vector<std::int32_t> map;
  for (const auto& n : c.nodes) {
    std::int32_t found = -1;
    for (std::size_t i = 0; i < a.nodes.size(); ++i)
      if (a.nodes[i] == n) found = static_cast<std::int32_t>(i);
    if (found < 0) {
      found = static_cast<std::int32_t>(m.nodes.size());
      m.nodes.push_back(n);
    }
    map.push_back(found);
  }
  for (auto e : c.elements) {
    for (auto& n : e.nodes) n = map[static_cast<std::size_t>(n)];
    m.elements.push_back(e);
  }
  m.node_labels.clear();
  m.element_labels.clear();
  for (std::size_t i = 0; i < m.nodes.size(); ++i) m.node_labels.push_back(100 + std::int64_t(i));
  auto p = test::make_problem(m, 210e9, 0.3, 7850);
  p.constraints.push_back({a.node_sets.at("xmin")});
  return p;
}

}  // namespace

TEST_CASE("sparse solver refuses singular and non-positive matrices, never crashes",
          "[fem][checks]") {
  for (auto b : kBackends) {
    if (b == SolverBackend::cholmod && !cholmod_available()) continue;
    INFO(backend_name(b));
    // An all-zero matrix (the mass matrix of density 0: it crashed CHOLMOD with SIGSEGV).
    SparseMatrix zero(6, 6);
    CHECK_THAT(factorize_error(zero, b),
               Contains("test matrix has a zero diagonal entry in row 0"));
    Eigen::MatrixXd d = Eigen::MatrixXd::Identity(3, 3);
    d(1, 1) = -2;
    CHECK_THAT(factorize_error(dense_to_sparse(d), b),
               Contains("negative diagonal entry in row 1"));
    d(1, 1) = NAN;
    CHECK_THAT(factorize_error(dense_to_sparse(d), b), Contains("non-finite entry"));
    // Exactly singular: rows 0 and 1 equal.
    Eigen::MatrixXd s(3, 3);
    s << 2, 2, 0, 2, 2, 0, 0, 0, 1;
    CHECK_THAT(factorize_error(dense_to_sparse(s), b),
               Contains("test matrix") && (Contains("not positive definite") ||
                                           Contains("singular to working precision")));
    // Singular to working precision: a pivot of 1e-16 of its diagonal.
    s << 1, 1, 0, 1, 1 + 1e-16 * 4, 0, 0, 0, 1;
    CHECK(factorize_error(dense_to_sparse(s), b) != "no error");
    // Indefinite.
    s << 1, 2, 0, 2, 1, 0, 0, 0, 1;
    CHECK_THAT(factorize_error(dense_to_sparse(s), b), Contains("not positive definite"));
    // A well-posed SPD matrix passes and solves.
    s << 4, 1, 0, 1, 3, 1, 0, 1, 2;
    SparseSpdSolver ok(b);
    ok.factorize(dense_to_sparse(s), "spd");
    Eigen::VectorXd x, rhs(3);
    rhs << 1, 2, 3;
    ok.solve(rhs, x);
    CHECK((s * x - rhs).norm() < 1e-12);
    CHECK(ok.smallest_pivot_ratio() > 0.5);
  }
}

TEST_CASE("density 0: static analysis runs, dynamics and gravity are refused by name",
          "[fem][checks]") {
  auto p = test::make_problem(box_mesh_hex({0, 0, 0}, {1, 0.1, 0.1}, {4, 1, 1}), 210e9, 0.3, 0.0);
  test::clamp(p, "xmin");
  p.nodal_loads.push_back({p.mesh.node_sets.at("xmax"), {0, 0, -100}, {}});
  {
    FemSolver s(p);
    s.solve_static();  // no mass needed
    CHECK(s.strain_energy() > 0);
    // Issue 19: this crashed fem_server (SIGSEGV in the sparse factorisation).
    CHECK_THROWS_WITH(s.advance(1e-4), Contains("a dynamic analysis needs mass") &&
                                           Contains("material 'steel'") &&
                                           Contains("has density 0"));
  }
  p.gravity = {0, 0, -9.81};
  CHECK_THROWS_WITH(FemSolver(p),
                    Contains("gravity is given but element") && Contains("density 0"));
}

TEST_CASE("a hinge (mechanism) is refused, naming the free nodes; both backends", "[fem][checks]") {
  for (auto b : kBackends) {
    if (b == SolverBackend::cholmod && !cholmod_available()) continue;
    INFO(backend_name(b));
    FemSolver s(hinge(), b);
    // Issue 19: a mechanism returned displacements of 5e9 m with exit 0.
    try {
      s.solve_static();
      FAIL("a hinge was solved");
    } catch (const FemModelError& e) {
      const std::string msg = e.what();
      INFO(msg);
      // The second cube has 27 nodes, 3 of them on the shared edge: 24 move freely.
      CHECK_THAT(msg, Contains("24 of 51 nodes can move without deforming any element") &&
                          Contains("a mechanism"));
      // Node labels of the second cube start at 100 + 27 (the first cube has 27 nodes).
      CHECK_THAT(msg, Contains("Free nodes: node 127"));
      CHECK_THAT(msg, Contains("stiffness matrix"));
    }
  }
}

TEST_CASE("an unconstrained body is refused as a rigid-body motion", "[fem][checks]") {
  auto p = test::make_problem(box_mesh_tet({0, 0, 0}, {1, 1, 1}, {2, 2, 2}), 70e9, 0.33, 2700);
  p.nodal_loads.push_back({p.mesh.node_sets.at("xmax"), {1, 0, 0}, {}});
  FemSolver s(p);
  CHECK_THROWS_WITH(s.solve_static(), Contains("the whole structure can move as a rigid body") &&
                                          Contains("Add clamps"));
  // The same body in dynamics is fine: the mass holds it.
  FemSolver d(p);
  d.advance(1e-4);
  CHECK(d.displacements()[0] != 0.0);
}

TEST_CASE("orphan nodes are left out of the system and keep zero displacement", "[fem][checks]") {
  auto ref =
      test::make_problem(box_mesh_hex({0, 0, 0}, {1, 0.1, 0.1}, {6, 1, 1}), 210e9, 0.3, 7850);
  test::clamp(ref, "xmin");
  PressureLoad q;
  q.faces = ref.mesh.surfaces.at("zmax");
  q.magnitude = 1e4;
  ref.pressures.push_back(q);
  auto with = ref;
  // Two points no element uses (as Gmsh and CAE exports keep them), one far away.
  with.mesh.nodes.push_back({5, 5, 5});
  with.mesh.nodes.push_back({0.5, 0.05, 0.05});
  CHECK(orphan_nodes(with.mesh).size() == 2);
  FemSolver a(ref), b(with);
  a.solve_static();
  b.solve_static();  // Issue 19: aborted with "rigid-body motion"
  const auto ua = a.displacements(), ub = b.displacements();
  for (std::size_t i = 0; i < ua.size(); ++i) CHECK(ua[i] == ub[i]);  // bitwise the same
  for (std::size_t i = ua.size(); i < ub.size(); ++i) CHECK(ub[i] == 0.0);
  CHECK(b.free_dof_count() == a.free_dof_count());
  // Dynamics too (the orphan has no mass either).
  FemSolver c(with);
  c.advance(1e-4);
  // A load on an orphan would vanish: refused.
  with.nodal_loads.push_back(
      {{static_cast<std::int32_t>(with.mesh.nodes.size() - 1)}, {0, 0, 1}, {}});
  CHECK_THROWS_WITH(FemSolver(with), Contains("belongs to no element"));
}

TEST_CASE("collapsed and inverted elements are refused with their file and line", "[fem][checks]") {
  SECTION("hex with its top face collapsed onto the bottom") {
    Mesh m = box_mesh_hex({0, 0, 0}, {1, 1, 1}, {1, 1, 1});
    for (std::size_t n = 4; n < 8; ++n) m.nodes[n][2] = 1e-9;  // all four top nodes down
    m.source_files = {"deck.inp"};
    m.element_sources = {{0, 42, -1}};
    auto p = test::make_problem(m, 1e9, 0.3, 1000);
    CHECK_THROWS_WITH(FemSolver(p), Contains("element 1 (deck.inp:42): collapsed"));
  }
  SECTION("tet with four coplanar nodes") {
    Mesh m = box_mesh_tet({0, 0, 0}, {1, 1, 1}, {1, 1, 1});
    m.elements.resize(1);
    m.element_labels.resize(1);
    const auto& e = m.elements[0];
    // Move the fourth node into the plane of the other three.
    const auto& a = m.nodes[static_cast<std::size_t>(e.nodes[0])];
    const auto& b = m.nodes[static_cast<std::size_t>(e.nodes[1])];
    const auto& c = m.nodes[static_cast<std::size_t>(e.nodes[2])];
    m.nodes[static_cast<std::size_t>(e.nodes[3])] = {
        (a[0] + b[0] + c[0]) / 3 + 1e-12, (a[1] + b[1] + c[1]) / 3, (a[2] + b[2] + c[2]) / 3};
    m.instance_names = {"PART-1-1"};
    m.source_files = {"deck.inp"};
    m.element_sources = {{0, 7, 0}};
    auto p = test::make_problem(m, 1e9, 0.3, 1000);
    CHECK_THROWS_WITH(FemSolver(p), Contains("element PART-1-1.1 (deck.inp:7)") &&
                                        (Contains("collapsed") || Contains("non-positive")));
  }
  SECTION("inverted hex") {
    Mesh m = box_mesh_hex({0, 0, 0}, {1, 1, 1}, {1, 1, 1});
    std::swap(m.elements[0].nodes[0], m.elements[0].nodes[4]);
    std::swap(m.elements[0].nodes[1], m.elements[0].nodes[5]);
    std::swap(m.elements[0].nodes[2], m.elements[0].nodes[6]);
    std::swap(m.elements[0].nodes[3], m.elements[0].nodes[7]);
    CHECK_THROWS_WITH(FemSolver(test::make_problem(m, 1e9, 0.3, 1000)),
                      Contains("non-positive Jacobian"));
  }
  SECTION("shell thinner than 1e-5 of its element") {
    auto p = test::make_problem(plate_mesh_quad({0, 0, 0}, 1, 1, {2, 2}), 1e9, 0.3, 1000, 1e-7);
    CHECK_THROWS_WITH(FemSolver(p), Contains("below 1e-5 of its longest edge"));
  }
}

TEST_CASE("a static displacement larger than the model is refused", "[fem][checks]") {
  auto p = test::make_problem(box_mesh_hex({0, 0, 0}, {1, 0.1, 0.1}, {4, 1, 1}), 210e9, 0.3, 7850);
  test::clamp(p, "xmin");
  p.nodal_loads.push_back({p.mesh.node_sets.at("xmax"), {0, 0, -1e13}, {}});  // absurd load
  FemSolver s(p);
  CHECK_THROWS_WITH(s.solve_static(), Contains("more than the size of the model") &&
                                          Contains("check the load magnitudes"));
}

TEST_CASE("non-zero prescribed displacements: a bar pulled by its end (static)", "[fem][checks]") {
  // Bar 1 x 0.1 x 0.1 m, x = 0 on rollers (u_x = 0, one line also in y, z), x = 1 pulled to
  // u_x = d. Exact: uniform strain d / L, u_x(x) = d x / L, reaction E A d / L.
  const double e = 200e9, d = 1e-4;
  for (bool tet : {false, true}) {
    Mesh m = tet ? box_mesh_tet({0, 0, 0}, {1, 0.1, 0.1}, {5, 1, 1})
                 : box_mesh_hex({0, 0, 0}, {1, 0.1, 0.1}, {5, 1, 1});
    auto p = test::make_problem(m, e, 0.0, 7850);
    p.constraints.push_back(
        {p.mesh.node_sets.at("xmin"), {true, false, false, false, false, false}});
    p.constraints.push_back(
        {p.mesh.node_sets.at("ymin"), {false, true, false, false, false, false}});
    p.constraints.push_back(
        {p.mesh.node_sets.at("zmin"), {false, false, true, false, false, false}});
    Constraint pull{p.mesh.node_sets.at("xmax"), {true, false, false, false, false, false}};
    pull.value[0] = d;
    p.constraints.push_back(pull);
    FemSolver s(p);
    s.solve_static();
    const auto u = s.displacements();
    for (std::size_t n = 0; n < p.mesh.nodes.size(); ++n)
      CHECK(u[3 * n] == Approx(d * p.mesh.nodes[n][0]).margin(1e-12));
    const auto r = s.reaction_forces();
    double rx = 0;
    for (auto n : p.mesh.node_sets.at("xmax")) rx += r[3 * static_cast<std::size_t>(n)];
    CHECK(rx == Approx(e * 0.01 * d / 1.0).epsilon(1e-9));
    CHECK(s.strain_energy() == Approx(0.5 * e * 0.01 * d * d).epsilon(1e-9));
    // Dynamics would need the prescribed velocity and acceleration: refused.
    CHECK_THROWS_WITH(s.advance(1e-4), Contains("static analysis only"));
  }
}

TEST_CASE("Bossak spectral radius: stable defaults, and known unstable parameters",
          "[fem][checks]") {
  // Defaults: unconditionally stable, dissipative at high frequency.
  BossakParameters def;
  for (double w : {1e-3, 0.1, 1.0, 10.0, 1e3, 1e6}) CHECK(bossak_spectral_radius(def, w) <= 1.0);
  CHECK(bossak_spectral_radius(def, 1e6) < 0.95);
  // Trapezoidal rule (alpha 0, beta 1/4, gamma 1/2) conserves: radius 1 at every frequency.
  const BossakParameters trap{0.0, 0.25, 0.5};
  for (double w : {0.1, 1.0, 100.0})
    CHECK(bossak_spectral_radius(trap, w) == Approx(1.0).epsilon(1e-12));
  // Central difference (beta 0, gamma 1/2): stable only for omega dt <= 2 (exact bound).
  const BossakParameters cd{0.0, 0.0, 0.5};
  CHECK(bossak_spectral_radius(cd, 1.99) <= 1.0 + 1e-12);
  CHECK(bossak_spectral_radius(cd, 2.01) > 1.0);
  // beta < gamma / 2 (here 0.2 < 0.3): conditionally stable, unstable at large omega dt.
  const BossakParameters cond{0.0, 0.2, 0.6};
  CHECK(bossak_spectral_radius(cond, 1e4) > 1.0);
}
