// Natural frequencies of the clamped steel beam of thesis table 4.1 (1000 x 100 x 100 mm,
// both end faces clamped) by shift-invert Lanczos (compute_modes) on three hex8 meshes:
// Richardson extrapolation of each bending frequency, compared with Timoshenko beam theory
// (clamped-clamped frequency equation, demfem_test/timoshenko_beam.hpp) and bracketed by
// Euler-Bernoulli; and Lanczos against the dense eigensolver on small solid and shell models,
// consistent and lumped mass. docs/verification.md has the tables.
#include <catch2/catch.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <map>

#include "demfem/fem/modal_analysis.hpp"
#include "demfem_test/timoshenko_beam.hpp"
#include "fem_test_util.hpp"

using namespace demfem::fem;

namespace {

enum class ModeKind { bending, torsion, axial };

/// What a mode of the beam is: per cross-section (nodes of equal x) the least-squares section
/// translation (a_y, a_z) and rotation theta about x of the transverse displacements, and the
/// mean axial displacement; the largest of the three contents names the mode.
ModeKind classify(const Mesh& mesh, const DofMap& dofs, const Eigen::VectorXd& phi) {
  std::map<long, std::vector<std::size_t>> stations;
  for (std::size_t n = 0; n < mesh.nodes.size(); ++n)
    stations[std::lround(mesh.nodes[n][0] * 1e6)].push_back(n);
  auto value = [&](std::size_t n, int c) {
    const auto r = dofs.reduced[static_cast<std::size_t>(dofs.node_offset[n] + c)];
    return r < 0 ? 0.0 : phi(r);
  };
  double bend = 0, twist = 0, axial = 0;
  for (const auto& [x, nodes] : stations) {
    double yc = 0, zc = 0;
    for (auto n : nodes) {
      yc += mesh.nodes[n][1] / static_cast<double>(nodes.size());
      zc += mesh.nodes[n][2] / static_cast<double>(nodes.size());
    }
    Eigen::Matrix3d a = Eigen::Matrix3d::Zero();
    Eigen::Vector3d b = Eigen::Vector3d::Zero();
    double ux = 0, r2 = 0;
    for (auto n : nodes) {
      const double y = mesh.nodes[n][1] - yc, z = mesh.nodes[n][2] - zc;
      // u_y = a_y - theta z, u_z = a_z + theta y
      const Eigen::Vector3d gy(1, 0, -z), gz(0, 1, y);
      a += gy * gy.transpose() + gz * gz.transpose();
      b += gy * value(n, 1) + gz * value(n, 2);
      ux += value(n, 0);
      r2 += y * y + z * z;
    }
    const Eigen::Vector3d s = a.ldlt().solve(b);
    const double k = static_cast<double>(nodes.size());
    bend += k * (s(0) * s(0) + s(1) * s(1));
    twist += s(2) * s(2) * r2;
    axial += ux * ux / k;
  }
  if (bend >= twist && bend >= axial) return ModeKind::bending;
  return twist >= axial ? ModeKind::torsion : ModeKind::axial;
}

struct BeamModes {
  std::vector<double> bending_hz;  ///< distinct bending frequencies (y/z pairs merged)
  std::vector<double> torsion_hz, axial_hz;
  std::size_t free_dofs = 0;
  double seconds = 0.0;
  double max_residual = 0.0;
  double orthogonality = 0.0;  ///< max |Phi^T M Phi - I|
};

BeamModes beam_modes(int nx, int ny, int count) {
  auto p =
      test::make_problem(box_mesh_hex({0, 0, 0}, {1.0, 0.1, 0.1}, {nx, ny, ny}), 210e9, 0.3, 7800);
  test::clamp(p, "xmin");
  test::clamp(p, "xmax");
  const DofMap dofs = make_dof_map(p);
  const SparseMatrix k = reduce_matrix(assemble_stiffness(p, dofs), dofs);
  const SparseMatrix m = reduce_matrix(assemble_mass(p, dofs), dofs);
  ModalOptions o;
  o.count = count;
  const auto t0 = std::chrono::steady_clock::now();
  const ModeSet modes = compute_modes(k, m, o);
  BeamModes r;
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r.free_dofs = dofs.free.size();
  r.max_residual = modes.residual.maxCoeff();
  const Eigen::MatrixXd g = modes.shapes.transpose() * (m * modes.shapes);
  r.orthogonality = (g - Eigen::MatrixXd::Identity(count, count)).cwiseAbs().maxCoeff();
  for (int j = 0; j < count; ++j) {
    const double hz = std::sqrt(modes.omega2(j)) / (2 * M_PI);
    switch (classify(p.mesh, dofs, modes.shapes.col(j))) {
      case ModeKind::bending:
        // The square section bends alike about y and z: merge the pair.
        if (r.bending_hz.empty() || hz > r.bending_hz.back() * (1 + 1e-6))
          r.bending_hz.push_back(hz);
        break;
      case ModeKind::torsion:
        r.torsion_hz.push_back(hz);
        break;
      case ModeKind::axial:
        r.axial_hz.push_back(hz);
        break;
    }
  }
  return r;
}

demfem::test::BeamSection thesis_beam() {
  demfem::test::BeamSection s;
  s.length = 1.0;
  s.youngs_modulus = 210e9;
  s.poisson_ratio = 0.3;
  s.density = 7800;
  s.area = 0.01;
  s.second_moment = 1e-4 / 12;
  return s;
}

}  // namespace

TEST_CASE(
    "Timoshenko reference: the clamped-clamped frequency equation tends to Euler-Bernoulli "
    "for a slender beam and lies below it for a thick one",
    "[fem][modal]") {
  auto s = thesis_beam();
  s.area = 1e-6;  // 1 mm square, L/h = 1000
  s.second_moment = 1e-12 / 12;
  const auto eb = demfem::test::euler_bernoulli_clamped(s, 5);
  const auto t = demfem::test::timoshenko_clamped(s, 5);
  for (int n = 0; n < 5; ++n)
    CHECK(t[static_cast<std::size_t>(n)] / eb[static_cast<std::size_t>(n)] ==
          Approx(1).epsilon(1e-4));
  const auto thick = thesis_beam();
  const auto eb10 = demfem::test::euler_bernoulli_clamped(thick, 5);
  const auto t10 = demfem::test::timoshenko_clamped(thick, 5);
  for (int n = 0; n < 5; ++n)
    CHECK(t10[static_cast<std::size_t>(n)] < eb10[static_cast<std::size_t>(n)]);
}

TEST_CASE(
    "clamped beam: the first five bending frequencies converge under refinement and agree "
    "with Timoshenko beam theory",
    "[fem][modal]") {
  const int count = 22;  // 5 bending pairs, torsion and axial modes below bending mode 5
  const int sizes[3] = {20, 40, 80};
  std::vector<BeamModes> runs;
  for (int nx : sizes) {
    runs.push_back(beam_modes(nx, nx / 10, count));
    const auto& r = runs.back();
    std::printf(
        "beam modes %d x %d x %d (%zu free DOF): %.2f s, max residual %.2e, "
        "|Phi^T M Phi - I| %.1e\n",
        nx, nx / 10, nx / 10, r.free_dofs, r.seconds, r.max_residual, r.orthogonality);
    CHECK(r.max_residual < 1e-8);
    CHECK(r.orthogonality < 1e-9);
    REQUIRE(r.bending_hz.size() >= 5);
  }
  const auto s = thesis_beam();
  const auto eb = demfem::test::euler_bernoulli_clamped(s, 5);
  const auto t = demfem::test::timoshenko_clamped(s, 5);
  auto sc = s;
  sc.shear_coefficient = demfem::test::cowper_rectangle(s.poisson_ratio);
  const auto tc = demfem::test::timoshenko_clamped(sc, 5);
  for (std::size_t n = 0; n < 5; ++n) {
    const double f1 = runs[0].bending_hz[n], f2 = runs[1].bending_hz[n], f3 = runs[2].bending_hz[n];
    // Richardson with the observed order (the meshes halve h).
    const double order = std::log2((f1 - f2) / (f2 - f3));
    const double inf = f3 + (f3 - f2) / (std::pow(2.0, order) - 1.0);
    const double timo = t[n] / (2 * M_PI), cowper = tc[n] / (2 * M_PI), ebn = eb[n] / (2 * M_PI);
    std::printf(
        "bending mode %zu: %.2f, %.2f, %.2f Hz -> Richardson %.2f Hz (order %.2f); "
        "coarse %+.2f %%; Timoshenko %.2f Hz (k = 5/6, %+.2f %%), %.2f Hz (Cowper, "
        "%+.2f %%); Euler-Bernoulli %.2f Hz\n",
        n + 1, f1, f2, f3, inf, order, 100 * (f1 / inf - 1), timo, 100 * (inf / timo - 1), cowper,
        100 * (inf / cowper - 1), ebn);
    // Converges from above (a conforming-mass displacement model is stiff), at an order
    // near 2.
    CHECK(f1 > f2);
    CHECK(f2 > f3);
    CHECK(order > 1.5);
    CHECK(order < 2.6);
    // The coarse mesh of the CI beam cases (50 mm elements, 8 to 4 elements per half wave for
    // modes 1 to 5) is stiff by O((h beta_n)^2): within 12 % of the converged value for all
    // five, within 3 % for mode 1 (the one that dominates the beam cases' response).
    CHECK(f1 > inf);
    CHECK(f1 / inf - 1 < (n == 0 ? 0.03 : 0.12));
    // Between Timoshenko and Euler-Bernoulli, and within 2.5 % of Timoshenko (see
    // docs/verification.md: the clamped faces of the solid hold the section plane and stop its
    // Poisson contraction, which stiffens it against the theory, as in the static case).
    CHECK(inf > timo);
    CHECK(inf > cowper);
    CHECK(inf < ebn);
    CHECK(std::abs(inf / timo - 1) < 0.025);
  }
}

TEST_CASE(
    "shift-invert Lanczos agrees with the dense eigensolver: solids and shells, consistent "
    "and lumped mass, clamped DOFs eliminated",
    "[fem][modal]") {
  struct Model {
    const char* name;
    FemProblem problem;
  };
  std::vector<Model> models;
  {
    auto p =
        test::make_problem(box_mesh_hex({0, 0, 0}, {1.0, 0.1, 0.05}, {16, 2, 2}), 210e9, 0.3, 7800);
    test::clamp(p, "xmin");
    models.push_back({"hex8 cantilever", p});
  }
  {
    auto p =
        test::make_problem(box_mesh_tet({0, 0, 0}, {0.5, 0.1, 0.1}, {8, 2, 2}), 70e9, 0.33, 2700);
    test::clamp(p, "xmin");
    test::clamp(p, "xmax", {false, false, true, false, false, false});  // z only: a support
    models.push_back({"tet4 beam, one end clamped, the other on a z support", p});
  }
  {
    auto p =
        test::make_problem(plate_mesh_quad({0, 0, 0}, 0.4, 0.3, {10, 8}), 200e9, 0.3, 7850, 0.004);
    test::clamp(p, "xmin");
    test::clamp(p, "ymin", {false, false, true, false, false, false});
    models.push_back({"MITC4 plate, one edge clamped, one simply supported", p});
  }
  for (const auto& model : models) {
    for (MassLumping lump : {MassLumping::consistent, MassLumping::lumped}) {
      FemProblem p = model.problem;
      p.mass = lump;
      const DofMap dofs = make_dof_map(p);
      const SparseMatrix k = reduce_matrix(assemble_stiffness(p, dofs), dofs);
      const SparseMatrix m = reduce_matrix(assemble_mass(p, dofs), dofs);
      REQUIRE(k.rows() > 200);  // large enough for Lanczos, not the dense path
      ModalOptions o;
      o.count = 8;
      const ModeSet lanczos = compute_modes(k, m, o);
      CHECK(lanczos.method.find("Lanczos") != std::string::npos);
      const Eigen::MatrixXd kd(k), md(m);
      Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> dense(kd, md);
      const Eigen::MatrixXd g = lanczos.shapes.transpose() * (m * lanczos.shapes);
      const Eigen::MatrixXd h = lanczos.shapes.transpose() * (k * lanczos.shapes);
      double worst = 0;
      for (int j = 0; j < o.count; ++j) {
        worst = std::max(worst, std::abs(lanczos.omega2(j) / dense.eigenvalues()(j) - 1));
        CHECK(h(j, j) == Approx(lanczos.omega2(j)).epsilon(1e-9));
      }
      // Both solvers carry errors of about cond(K) eps (cond ~ 1e8 here) in omega^2.
      std::printf(
          "%s (%s mass, %ld free DOF): first %d omega^2 agree with the dense solver to "
          "%.1e, mode 1 %.3f Hz\n",
          model.name, lump == MassLumping::lumped ? "lumped" : "consistent",
          static_cast<long>(k.rows()), o.count, worst, std::sqrt(lanczos.omega2(0)) / (2 * M_PI));
      CHECK(worst < 1e-8);
      CHECK((g - Eigen::MatrixXd::Identity(o.count, o.count)).cwiseAbs().maxCoeff() < 1e-9);
      CHECK(lanczos.residual.maxCoeff() < 1e-8);
    }
  }
}

TEST_CASE("modal analysis refuses what it cannot compute", "[fem][modal]") {
  auto p =
      test::make_problem(box_mesh_hex({0, 0, 0}, {1.0, 0.1, 0.1}, {10, 1, 1}), 210e9, 0.3, 7800);
  const DofMap free_dofs = make_dof_map(p);  // no clamp: six rigid-body modes at omega = 0
  const SparseMatrix k = reduce_matrix(assemble_stiffness(p, free_dofs), free_dofs);
  const SparseMatrix m = reduce_matrix(assemble_mass(p, free_dofs), free_dofs);
  ModalOptions o;
  o.count = 10;
  // sigma = 0 on a free body (K singular: its factorisation may pass on round-off pivots, or
  // be refused) and a negative shift: six rigid-body modes at omega^2 ~ 0 to round-off, then
  // the first elastic ones, the same either way.
  ModeSet ref;
  for (double shift : {-1e3, 0.0}) {
    o.shift = shift;
    ModeSet r;
    try {
      r = compute_modes(k, m, o);
    } catch (const SingularMatrixError&) {
      CHECK(shift == 0.0);
      continue;
    }
    for (int j = 0; j < 6; ++j) CHECK(std::abs(r.omega2(j)) < 1e-9 * r.omega2(6));
    CHECK(r.residual.maxCoeff() < 1e-8);
    CHECK(r.omega2(6) > 1e4);
    if (ref.omega2.size() == 0) ref = r;
    CHECK(r.omega2(6) == Approx(ref.omega2(6)).epsilon(1e-10));
  }
  o.count = 0;
  CHECK_THROWS_AS(compute_modes(k, m, o), std::invalid_argument);
  o.count = static_cast<int>(k.rows()) + 1;
  CHECK_THROWS_AS(compute_modes(k, m, o), std::invalid_argument);
}

TEST_CASE("modal analysis: the dense solver's switch is announced, refused above memory",
          "[fem][modal]") {
  // Issue 34, item 14: asking for nearly all modes switched to the dense solver silently
  // (10^4 modes ended in bad_alloc). 41 x 2 x 2 nodes, no clamp: 492 free DOFs; Lanczos takes
  // up to 245 modes (its 2 x 245 + 1 = 491 vectors < 492).
  auto p =
      test::make_problem(box_mesh_hex({0, 0, 0}, {4.0, 0.1, 0.1}, {40, 1, 1}), 210e9, 0.3, 7800);
  const DofMap dofs = make_dof_map(p);
  REQUIRE(dofs.free.size() == 492);
  CHECK(max_lanczos_modes(492) == 245);
  CHECK_FALSE(uses_dense_modes(492, 245));
  CHECK(uses_dense_modes(492, 246));
  CHECK(uses_dense_modes(132, 10));  // small models: always dense, without a warning
  CHECK(dense_modes_warning(132, 10).empty());
  CHECK(dense_modes_warning(492, 245).empty());
  CHECK_THAT(dense_modes_warning(492, 250),
             Catch::Contains("250 modes of 492 free DOFs: more than shift-invert Lanczos can "
                             "compute (at most 245") &&
                 Catch::Contains("the dense eigensolver runs instead: about 0.0116 GB") &&
                 Catch::Contains("ask for at most 245 modes"));
  // 6 n^2 doubles; the time grows as n^3
  CHECK(dense_modes_cost(1000).bytes == 48e6);
  CHECK(dense_modes_cost(2000).seconds == 8.0 * dense_modes_cost(1000).seconds);

  const SparseMatrix k = reduce_matrix(assemble_stiffness(p, dofs), dofs);
  const SparseMatrix m = reduce_matrix(assemble_mass(p, dofs), dofs);
  ModalOptions o;
  o.count = 250;
  o.shift = -1e3;
  o.memory_available = 10'000'000;  // 10 MB: less than the 11.6 MB the dense matrices take
  CHECK_THROWS_WITH(compute_modes(k, m, o),
                    Catch::Contains("250 modes of 492 free DOFs need the dense eigensolver "
                                    "(shift-invert Lanczos computes at most 245 of them), whose "
                                    "matrices take 0.0116 GB, more than the 0.01 GB of memory "
                                    "available (MemAvailable); ask for at most 245 modes"));
  o.memory_available = 12'000'000;
  const ModeSet r = compute_modes(k, m, o);
  CHECK(r.method == "dense");
  CHECK(r.omega2.size() == 250);
  // MemAvailable is read from /proc/meminfo (Linux): some memory is always available.
  CHECK(available_memory_bytes() > 0);
}
