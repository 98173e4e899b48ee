// Bossak-Newmark time integration: energy conservation (alpha = 0), numerical dissipation
// (alpha < 0), second-order convergence against the exact modal solution of the
// semi-discrete system, and bitwise-identical continuation after save/restore.
#include <catch2/catch.hpp>

#include <cstdio>
#include <filesystem>
#include <random>

#include "demfem/fem/fem_solver.hpp"
#include "demfem/io/h5_file.hpp"
#include "fem_test_util.hpp"

using namespace demfem::fem;

namespace {

constexpr double kE = 210e9, kRho = 7850;

/// Steel cantilever along x, clamped at x = 0, tip load in z on the xmax nodes.
FemProblem cantilever(int nx, double l, double h, TimeFunction amp, double tip_force) {
  auto p = test::make_problem(box_mesh_hex({0, 0, 0}, {l, h, h}, {nx, 1, 1}), kE, 0.3, kRho);
  test::clamp(p, "xmin");
  NodalLoad f;
  f.nodes = p.mesh.node_sets.at("xmax");
  f.force = {0, 0, tip_force / static_cast<double>(f.nodes.size())};
  f.amplitude = std::move(amp);
  p.nodal_loads.push_back(f);
  return p;
}

double first_period(const FemProblem& p) {
  return 2 * M_PI / std::sqrt(test::modes(p).omega2(0));
}

}  // namespace

TEST_CASE("Bossak-Newmark alpha = 0 conserves energy in free vibration", "[fem][dynamics]") {
  // Released from the static deflection under a tip load (load off for t > 0).
  auto p = cantilever(
      10, 1.0, 0.1, [](double t) { return t <= 0 ? 1.0 : 0.0; }, 1000.0);
  p.bossak = {0.0, 0.25, 0.5};
  const double period = first_period(p);
  FemSolver s(p);
  s.solve_static();
  const double dt = period / 50;
  s.advance(dt);  // the step that releases the load; free vibration from here on
  const double e1 = s.kinetic_energy() + s.strain_energy();
  double worst = 0;
  for (int i = 0; i < 5 * 50; ++i) {
    s.advance(dt);
    worst = std::max(worst, std::abs(s.kinetic_energy() + s.strain_energy() - e1) / e1);
  }
  std::printf("alpha = 0: max relative energy change over 5 periods %.3e\n", worst);
  CHECK(worst < 1e-6);  // task tolerance: 1e-6 per period (here over five)
  CHECK(s.kinetic_energy() > 0);
}

TEST_CASE("Bossak-Newmark alpha < 0 dissipates energy", "[fem][dynamics]") {
  auto p = cantilever(
      10, 1.0, 0.1, [](double t) { return t <= 0 ? 1.0 : 0.0; }, 1000.0);
  p.bossak = {-0.1, 0.3025, 0.6};
  const double period = first_period(p);
  FemSolver s(p);
  s.solve_static();
  const double dt = period / 10;  // coarse: the fundamental is damped visibly
  s.advance(dt);
  const double e1 = s.kinetic_energy() + s.strain_energy();
  // Energy at the end of each period (the discrete energy may exchange within a period).
  std::vector<double> per_period;
  for (int i = 1; i <= 100; ++i) {
    s.advance(dt);
    if (i % 10 == 0) per_period.push_back(s.kinetic_energy() + s.strain_energy());
  }
  std::printf("alpha = -0.1: energy after 10 periods %.4f of the initial\n",
              per_period.back() / e1);
  CHECK(per_period.back() < 0.95 * e1);  // decays (alpha = 0 keeps it to 1e-12, above)
  for (std::size_t i = 1; i < per_period.size(); ++i) CHECK(per_period[i] < per_period[i - 1]);
}

TEST_CASE("Bossak-Newmark converges with second order in dt", "[fem][dynamics]") {
  // Forced from rest by F(t) = P (1 - cos(W t)) (zero load and load rate at t = 0, so the
  // stiff modes are barely excited); the reference is the exact solution of M u'' + K u = F
  // by modal superposition (independent of the integrator).
  const double l = 0.4, h = 0.1, force = 1000.0;
  auto p0 = cantilever(4, l, h, {}, force);
  const auto m = test::modes(p0);
  const double w1 = std::sqrt(m.omega2(0)), big_w = 0.5 * w1, period = 2 * M_PI / w1;
  const double t_end = 2 * period;
  const auto tip = test::node_at(p0.mesh, l, h, h);
  const auto tip_dof = m.dofs.reduced[static_cast<std::size_t>(m.dofs.node_offset[tip] + 2)];
  // Modal load phi^T f (phi mass-normalised), f = unit-amplitude load on the free DOFs.
  const DofMap& d = m.dofs;
  Eigen::VectorXd f = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(d.free.size()));
  const Eigen::VectorXd ff = nodal_load_vector(p0, d, p0.nodal_loads[0]);
  for (std::size_t i = 0; i < d.free.size(); ++i) f(static_cast<Eigen::Index>(i)) = ff(d.free[i]);
  // Exact tip displacement at time t by modal superposition.
  auto exact = [&](double t) {
    double u = 0;
    for (Eigen::Index j = 0; j < m.omega2.size(); ++j) {
      const double wj = std::sqrt(m.omega2(j)), fj = m.shapes.col(j).dot(f);
      const double w2 = wj * wj, den = w2 - big_w * big_w;
      u += m.shapes(tip_dof, j) * fj *
           (1 / w2 - std::cos(big_w * t) / den + big_w * big_w / (w2 * den) * std::cos(wj * t));
    }
    return u;
  };
  for (const BossakParameters bp : {BossakParameters{0.0, 0.25, 0.5}, BossakParameters{}}) {
    double err[3];
    for (int k = 0; k < 3; ++k) {
      auto p = cantilever(
          4, l, h, [big_w](double t) { return 1 - std::cos(big_w * t); }, force);
      p.bossak = bp;
      FemSolver s(p);
      const int steps = 80 << k, every = 1 << k;
      // Max error over the sample times shared by the three runs (40 per period).
      err[k] = 0;
      for (int i = 1; i <= steps; ++i) {
        s.advance(t_end / steps);
        if (i % every == 0)
          err[k] = std::max(err[k], std::abs(s.displacements()[3 * tip + 2] - exact(s.time())));
      }
    }
    std::printf("alpha = %.2f: max errors %.3e %.3e %.3e (tip amplitude ~%.3e), ratios %.3f %.3f\n",
                bp.alpha, err[0], err[1], err[2], std::abs(exact(period / 2)), err[0] / err[1],
                err[1] / err[2]);
    // Second order: halving dt divides the error by 4 (tolerance 3.5 .. 4.5).
    CHECK(err[0] / err[1] > 3.5);
    CHECK(err[0] / err[1] < 4.5);
    CHECK(err[1] / err[2] > 3.5);
    CHECK(err[1] / err[2] < 4.5);
  }
}

TEST_CASE("Rayleigh damping matches the exact damped modal solution", "[fem][dynamics]") {
  // C = cm M + ck K is diagonal in the modes: zeta_j = cm / (2 w_j) + ck w_j / 2. Forced
  // from rest by P (1 - cos(W t)); each mode solved exactly (damped oscillator).
  const double l = 0.4, h = 0.1, force = 1000.0;
  auto p = cantilever(4, l, h, {}, force);
  const auto m = test::modes(p);
  const double w1 = std::sqrt(m.omega2(0)), big_w = 0.5 * w1, period = 2 * M_PI / w1;
  const double zeta = 0.05;
  p.damping = {zeta * w1, zeta / w1};  // zeta_1 = 5 %
  const auto tip = test::node_at(p.mesh, l, h, h);
  const DofMap& d = m.dofs;
  const auto tip_dof = d.reduced[static_cast<std::size_t>(d.node_offset[tip] + 2)];
  Eigen::VectorXd f = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(d.free.size()));
  const Eigen::VectorXd ff = nodal_load_vector(p, d, p.nodal_loads[0]);
  for (std::size_t i = 0; i < d.free.size(); ++i) f(static_cast<Eigen::Index>(i)) = ff(d.free[i]);
  auto exact = [&](double t, bool damped) {
    double u = 0;
    for (Eigen::Index j = 0; j < m.omega2.size(); ++j) {
      const double wj = std::sqrt(m.omega2(j)), fj = m.shapes.col(j).dot(f);
      const double z =
          damped ? p.damping.mass_factor / (2 * wj) + p.damping.stiffness_factor * wj / 2 : 0.0;
      const double a = wj * wj - big_w * big_w, b = 2 * z * wj * big_w, dn = a * a + b * b;
      // Particular: fj / wj^2 - fj (a cos Wt + b sin Wt) / dn.
      const double qp0 = fj / (wj * wj) - fj * a / dn, dqp0 = -fj * b * big_w / dn;
      double q = fj / (wj * wj) - fj * (a * std::cos(big_w * t) + b * std::sin(big_w * t)) / dn;
      if (z < 1) {
        const double wd = wj * std::sqrt(1 - z * z);
        const double ca = -qp0, cb = (-dqp0 + z * wj * ca) / wd;
        q += std::exp(-z * wj * t) * (ca * std::cos(wd * t) + cb * std::sin(wd * t));
      } else {
        // Overdamped stiff modes: their homogeneous part is negligible here but keep it
        // exact: roots r1,2 = -wj (z -+ sqrt(z^2 - 1)).
        const double sq = std::sqrt(z * z - 1), r1 = -wj * (z - sq), r2 = -wj * (z + sq);
        const double c2 = (dqp0 - r1 * qp0) / (r1 - r2), c1 = -qp0 - c2;
        q += c1 * std::exp(r1 * t) + c2 * std::exp(r2 * t);
      }
      u += m.shapes(tip_dof, j) * q;
    }
    return u;
  };
  p.bossak = {0.0, 0.25, 0.5};
  p.nodal_loads[0].amplitude = [big_w](double t) { return 1 - std::cos(big_w * t); };
  FemSolver s(p);
  const int steps = 320;  // 160 per period over 2 periods
  double err = 0, amp = 0, damping_effect = 0;
  for (int i = 1; i <= steps; ++i) {
    s.advance(2 * period / steps);
    const double ue = exact(s.time(), true);
    err = std::max(err, std::abs(s.displacements()[3 * tip + 2] - ue));
    amp = std::max(amp, std::abs(ue));
    damping_effect = std::max(damping_effect, std::abs(exact(s.time(), false) - ue));
  }
  std::printf("Rayleigh damping: max error %.3e, amplitude %.3e, damped vs undamped %.3e\n", err,
              amp, damping_effect);
  // Tolerance 0.2 % of the amplitude (the integrator's own error at 160 steps per period is
  // ~0.1 %); damping changes the response by far more than that.
  CHECK(err < 2e-3 * amp);
  CHECK(damping_effect > 20 * err);
}

TEST_CASE("save/restore mid-run continues bitwise identically", "[fem][dynamics][restart]") {
  auto p = cantilever(
      6, 0.6, 0.1, [](double t) { return std::sin(3000 * t) + 0.5; }, 500.0);
  p.damping = {5.0, 1e-6};
  const auto dir = std::filesystem::temp_directory_path() /
                   ("demfem_fem_restart_" + std::to_string(std::random_device{}()));
  std::filesystem::create_directories(dir);
  FemSolver a(p);
  std::vector<double> f(3 * a.interface_mesh().node_count());
  for (std::size_t i = 0; i < f.size(); ++i) f[i] = 0.01 * static_cast<double>(i % 7) - 0.02;
  a.set_interface_forces(f);
  for (int i = 0; i < 10; ++i) a.advance(1e-5);
  {
    demfem::io::H5File file(dir / "state.h5", demfem::io::H5File::Mode::create);
    a.save(file, "fem");
  }
  for (int i = 0; i < 10; ++i) a.advance(1e-5);
  a.advance(2e-5);  // a dt change refactorises

  FemSolver b(p);
  {
    demfem::io::H5File file(dir / "state.h5", demfem::io::H5File::Mode::read);
    b.restore(file, "fem");
  }
  CHECK(b.step_count() == 10);
  for (int i = 0; i < 10; ++i) b.advance(1e-5);
  b.advance(2e-5);
  CHECK(a.time() == b.time());
  CHECK(a.step_count() == b.step_count());
  CHECK(a.displacements() == b.displacements());  // bitwise
  CHECK(a.velocities() == b.velocities());
  CHECK(a.accelerations() == b.accelerations());
  std::vector<double> pa(f.size()), va(f.size()), aa(f.size()), pb(f.size()), vb(f.size()),
      ab(f.size());
  a.interface_kinematics(pa, va, aa);
  b.interface_kinematics(pb, vb, ab);
  CHECK(pa == pb);
  CHECK(va == vb);
  // Restoring into a different model is refused with a message.
  FemSolver c(cantilever(3, 0.6, 0.1, {}, 1.0));
  demfem::io::H5File file(dir / "state.h5", demfem::io::H5File::Mode::read);
  CHECK_THROWS_WITH(c.restore(file, "fem"), Catch::Contains("different DOF count"));
  file.close();
  std::filesystem::remove_all(dir);
}
