// First three bending frequencies of slender cantilevers (solid hex8 and MITC4 shell)
// against Euler-Bernoulli theory: omega_n = (beta_n L)^2 sqrt(E I / (rho A L^4)).
#include <catch2/catch.hpp>

#include <cstdio>

#include "fem_test_util.hpp"

using namespace demfem::fem;

namespace {
constexpr double kBetaL[3] = {1.8751040687, 4.6940911330, 7.8547574382};

/// Frequencies (rad/s) of the first three modes dominated by z displacement.
std::vector<double> z_bending(const FemProblem& p, const test::Modes& m) {
  std::vector<double> out;
  for (Eigen::Index j = 0; j < m.omega2.size() && out.size() < 3; ++j) {
    double uz = 0, uxy = 0;
    for (std::size_t n = 0; n < p.mesh.nodes.size(); ++n)
      for (int c = 0; c < 3; ++c) {
        const auto r = m.dofs.reduced[static_cast<std::size_t>(m.dofs.node_offset[n] + c)];
        if (r < 0) continue;
        const double v = m.shapes(r, j) * m.shapes(r, j);
        (c == 2 ? uz : uxy) += v;
      }
    if (uz > 0.9 * (uz + uxy)) out.push_back(std::sqrt(m.omega2(j)));
  }
  return out;
}

// The first three bending frequencies `w` (rad/s) of a cantilever against Euler-Bernoulli's
// beta_n^2 c (c = sqrt(E I / (rho A L^4))), each within the task's tolerance of 2 %.
void check_euler_bernoulli(const char* what, const std::vector<double>& w, double c) {
  for (int n = 0; n < 3; ++n) {
    const double ref = kBetaL[n] * kBetaL[n] * c;
    std::printf("%s mode %d: %.4f Hz, Euler-Bernoulli %.4f Hz (%.3f %%)\n", what, n + 1,
                w[n] / (2 * M_PI), ref / (2 * M_PI), 100 * (w[n] / ref - 1));
    CHECK(std::abs(w[n] / ref - 1) < 0.02);  // task tolerance: 2 %
  }
}
}  // namespace

TEST_CASE("solid cantilever: first three bending frequencies (hex8)", "[fem][modal]") {
  // L = 1 m, b = 40 mm, h = 20 mm (L/h = 50: shear and rotary inertia < 0.5 % on mode 3).
  const double l = 1.0, b = 0.04, h = 0.02, e = 210e9, rho = 7850;
  auto p = test::make_problem(box_mesh_hex({0, 0, 0}, {l, b, h}, {50, 2, 1}), e, 0.3, rho);
  test::clamp(p, "xmin");
  const auto m = test::modes(p);
  const auto w = z_bending(p, m);
  REQUIRE(w.size() == 3);
  const double c = std::sqrt(e * b * h * h * h / 12 / (rho * b * h * l * l * l * l));
  check_euler_bernoulli("solid cantilever", w, c);
}

TEST_CASE("shell cantilever: first three bending frequencies (MITC4)", "[fem][modal]") {
  // Narrow strip L = 0.5 m, b = 20 mm, t = 2 mm. With free long edges linear plate theory
  // gives the beam stiffness E I (anticlastic curvature is free: M_y = 0 gives
  // M_x = E t^3/12 kappa_x), so Euler-Bernoulli with E (not E / (1 - nu^2)) is the
  // reference; the clamp restrains anticlastic curvature only within ~b of the root.
  const double l = 0.5, b = 0.02, t = 0.002, e = 210e9, rho = 7850;
  auto p = test::make_problem(plate_mesh_quad({0, 0, 0}, l, b, {50, 2}), e, 0.3, rho, t);
  test::clamp(p, "xmin");
  const auto m = test::modes(p);
  const auto w = z_bending(p, m);
  REQUIRE(w.size() == 3);
  const double c = std::sqrt(e * b * t * t * t / 12 / (rho * b * t * l * l * l * l));
  check_euler_bernoulli("shell cantilever", w, c);
}
