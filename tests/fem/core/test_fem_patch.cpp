// Patch tests: a linear displacement field (constant strain) is reproduced exactly by
// hex8 with incompatible modes on a distorted mesh and by tet4; rigid-body modes carry no
// strain energy.
#include <catch2/catch.hpp>

#include <random>

#include "demfem/fem/fem_solver.hpp"
#include "fem_test_util.hpp"

using namespace demfem::fem;

namespace {

/// Linear field u = A x + c.
Eigen::Vector3d field(const std::array<double, 3>& x) {
  Eigen::Matrix3d a;
  a << 1e-3, 2e-4, -3e-4, 5e-4, -2e-3, 1e-4, -4e-4, 3e-4, 1.5e-3;
  return a * Eigen::Vector3d(x[0], x[1], x[2]) + Eigen::Vector3d(1e-4, -2e-4, 3e-4);
}

/// Prescribes the field on the boundary, solves for the interior; returns the max
/// interior error relative to the field's size.
double patch_error(const FemProblem& p, const std::vector<bool>& boundary) {
  const DofMap d = make_dof_map(p);
  const Eigen::MatrixXd k(assemble_stiffness(p, d));
  const auto n = static_cast<Eigen::Index>(p.mesh.nodes.size());
  std::vector<Eigen::Index> in, bd;
  Eigen::VectorXd ub = Eigen::VectorXd::Zero(3 * n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const auto u = field(p.mesh.nodes[static_cast<std::size_t>(i)]);
    for (int c = 0; c < 3; ++c) {
      (boundary[static_cast<std::size_t>(i)] ? bd : in).push_back(3 * i + c);
      ub(3 * i + c) = u(c);
    }
  }
  Eigen::MatrixXd kii(in.size(), in.size()), kib(in.size(), bd.size());
  Eigen::VectorXd xb(bd.size()), exact(in.size());
  for (std::size_t a = 0; a < in.size(); ++a) {
    exact(a) = ub(in[a]);
    for (std::size_t b = 0; b < in.size(); ++b) kii(a, b) = k(in[a], in[b]);
    for (std::size_t b = 0; b < bd.size(); ++b) kib(a, b) = k(in[a], bd[b]);
  }
  for (std::size_t b = 0; b < bd.size(); ++b) xb(b) = ub(bd[b]);
  const Eigen::VectorXd ui = kii.ldlt().solve(-kib * xb);
  return (ui - exact).cwiseAbs().maxCoeff() / ub.cwiseAbs().maxCoeff();
}

std::vector<bool> box_boundary(const Mesh& m) {
  std::vector<bool> b(m.nodes.size(), false);
  for (const char* s : {"xmin", "xmax", "ymin", "ymax", "zmin", "zmax"})
    for (auto i : m.node_sets.at(s)) b[static_cast<std::size_t>(i)] = true;
  return b;
}

}  // namespace

TEST_CASE("hex8 incompatible modes pass the patch test on a distorted mesh", "[fem][patch]") {
  Mesh m = box_mesh_hex({0, 0, 0}, {1, 1, 1}, {3, 3, 3});
  const auto boundary = box_boundary(m);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> jitter(-0.1, 0.1);  // +-30 % of the 1/3 spacing
  for (std::size_t i = 0; i < m.nodes.size(); ++i)
    if (!boundary[i])
      for (auto& c : m.nodes[i]) c += jitter(rng);
  const auto p = test::make_problem(m, 210e9, 0.3, 7850);
  // Exact up to round-off: tolerance 1e-9 relative (a failed patch test gives ~1e-2).
  CHECK(patch_error(p, boundary) < 1e-9);
}

TEST_CASE("hex8 patch test with one strongly displaced interior node", "[fem][patch]") {
  // Eight elements around a centre node moved by 10-20 % of the box: every element is a
  // general (non-parallelepiped) hexahedron, where Wilson's modes without Taylor's
  // correction fail the patch test.
  Mesh m = box_mesh_hex({0, 0, 0}, {1, 1, 1}, {2, 2, 2});
  const auto boundary = box_boundary(m);
  const auto c = test::node_at(m, 0.5, 0.5, 0.5);
  m.nodes[c] = {0.62, 0.41, 0.57};
  CHECK(patch_error(test::make_problem(m, 100e9, 0.25, 1000), boundary) < 1e-9);
}

TEST_CASE("tet4 passes the patch test", "[fem][patch]") {
  Mesh m = box_mesh_tet({0, 0, 0}, {1, 2, 1}, {3, 3, 3});
  const auto boundary = box_boundary(m);
  CHECK(patch_error(test::make_problem(m, 70e9, 0.33, 2700), boundary) < 1e-9);
}

TEST_CASE("element stiffness has exactly the six rigid-body null modes", "[fem][patch]") {
  for (bool tet : {false, true}) {
    Mesh m = tet ? box_mesh_tet({0, 0, 0}, {1, 1, 1}, {1, 1, 1})
                 : box_mesh_hex({0, 0, 0}, {1, 1, 1}, {1, 1, 1});
    m.nodes[7] = {1.2, 1.1, 0.9};  // distort the (1, 1, 1) corner
    const auto p = test::make_problem(m, 1.0, 0.3, 1.0);
    const DofMap d = make_dof_map(p);
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(Eigen::MatrixXd(assemble_stiffness(p, d)));
    const auto ev = es.eigenvalues();
    const double top = ev.maxCoeff();
    // Relative tolerance 1e-10 for "zero" eigenvalues.
    int zeros = 0;
    for (Eigen::Index i = 0; i < ev.size(); ++i) zeros += std::abs(ev(i)) < 1e-10 * top;
    INFO((tet ? "tet4" : "hex8") << " min " << ev.minCoeff() << " top " << top);
    CHECK(zeros == 6);
    CHECK(ev.minCoeff() > -1e-10 * top);
  }
}
