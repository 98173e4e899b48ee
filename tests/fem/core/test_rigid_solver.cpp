// RigidSolver (the rigid-body backend's engine): mass, centre of mass and inertia from the
// mesh against the closed forms of a box; the spring-mass oscillation and statics against
// theory; interface kinematics as the rigid motion; bitwise restart.
#include <catch2/catch.hpp>

#include <cstdio>

#include "demfem/fem/rigid_solver.hpp"
#include "demfem/io/h5_file.hpp"
#include "demfem_test/temp_dir.hpp"
#include "fem_test_util.hpp"

using namespace demfem::fem;

namespace {
// A steel block 1.0 x 0.2 x 0.1 m, 10 x 2 x 1 hex8, with the beam's clamps (which the rigid
// body does not use).
FemProblem block(MassLumping mass = MassLumping::consistent) {
  auto p =
      test::make_problem(box_mesh_hex({0, 0, 0}, {1.0, 0.2, 0.1}, {10, 2, 1}), 210e9, 0.3, 7800);
  test::clamp(p, "xmin");
  p.mass = mass;
  return p;
}
}  // namespace

TEST_CASE("rigid body: mass, centre of mass and inertia of a box from the mesh", "[fem][rigid]") {
  const double a = 1.0, b = 0.2, c = 0.1, m = 7800 * a * b * c;
  RigidSolver r(block(), {});
  CHECK(r.mass() == Approx(m).epsilon(1e-12));
  const auto com = r.centre_of_mass();
  CHECK(com[0] == Approx(0.5).epsilon(1e-12));
  CHECK(com[1] == Approx(0.1).epsilon(1e-12));
  CHECK(com[2] == Approx(0.05).epsilon(1e-12));
  const auto j = r.inertia();
  // The consistent mass interpolates a rigid rotation exactly: the box's inertia exactly.
  CHECK(j[0] == Approx(m * (b * b + c * c) / 12).epsilon(1e-12));
  CHECK(j[4] == Approx(m * (a * a + c * c) / 12).epsilon(1e-12));
  CHECK(j[8] == Approx(m * (a * a + b * b) / 12).epsilon(1e-12));
  CHECK(std::abs(j[1]) < 1e-12 * j[0]);
  // Lumped: point masses at the nodes, the right mass and centre, a larger inertia.
  RigidSolver l(block(MassLumping::lumped), {});
  CHECK(l.mass() == Approx(m).epsilon(1e-12));
  CHECK(l.centre_of_mass()[0] == Approx(0.5).epsilon(1e-12));
  CHECK(l.inertia()[8] > j[8]);
}

TEST_CASE("rigid body on springs: statics, the oscillation and a tilt against theory",
          "[fem][rigid]") {
  const double m = 7800 * 1.0 * 0.2 * 0.1, k = 1e6;
  RigidSettings rs;
  rs.springs.push_back({{0.0, 0.1, 0.0}, {0, 0, k}, {0, 0, 0}});
  rs.springs.push_back({{1.0, 0.1, 0.0}, {0, 0, k}, {0, 0, 0}});
  rs.fixed = {true, true, false, true, false, true};  // z and the rotation about y are free
  FemProblem p = block();
  p.gravity = {0, 0, -9.81};
  p.bossak = {0.0, 0.25, 0.5};  // trapezoidal rule: no numerical damping
  {
    RigidSolver r(p, rs);
    r.solve_static();
    CHECK(r.coordinates()[2] == Approx(-m * 9.81 / (2 * k)).epsilon(1e-12));
    CHECK(std::abs(r.coordinates()[4]) < 1e-15);
  }
  {
    // Released from rest without its static deflection: z(t) = -(mg / 2k)(1 - cos w t).
    RigidSolver r(p, rs);
    const double w = std::sqrt(2 * k / m), zs = m * 9.81 / (2 * k), dt = 2 * M_PI / w / 400;
    double worst = 0;
    for (int i = 1; i <= 800; ++i) {
      r.advance(dt);
      worst = std::max(worst, std::abs(r.coordinates()[2] + zs * (1 - std::cos(w * i * dt))));
    }
    std::printf("rigid body on springs: 2 periods of %.4f Hz, max error %.2e of %.2e m\n",
                w / (2 * M_PI), worst, 2 * zs);
    CHECK(worst < 1e-3 * zs);  // trapezoidal rule, 400 steps per period: (w dt)^2 / 12 phase
  }
  {
    // A load on the interface at x = 0.75: a tilt about y through the spring couple.
    RigidSolver r(p, rs);
    std::vector<double> f(3 * r.interface_mesh().node_count(), 0.0);
    std::size_t at = 0;
    for (std::size_t i = 0; i < r.interface_mesh().node_count(); ++i) {
      const double* x = &r.interface_mesh().reference_positions[3 * i];
      if (std::abs(x[0] - 0.8) < 1e-9 && std::abs(x[1] - 0.1) < 1e-9 && std::abs(x[2] - 0.1) < 1e-9)
        at = i;
    }
    f[3 * at + 2] = -1000.0;
    r.set_interface_forces(f);
    r.solve_static();
    // Springs at x = 0 and 1, centre at 0.5: forces F0 + F1 = P + W, moment about x = 0.5.
    const double w = m * 9.81, pl = 1000.0;
    const double f1 = (w * 0.5 + pl * 0.8), f0 = w + pl - f1;  // moments about x = 0
    const double z0 = -f0 / k, z1 = -f1 / k;
    CHECK(r.coordinates()[2] == Approx(0.5 * (z0 + z1)).epsilon(1e-10));
    // theta_y: u_z = d_z - theta_y (x - 0.5)  ->  theta_y = -(z1 - z0)
    CHECK(r.coordinates()[4] == Approx(-(z1 - z0)).epsilon(1e-10));
    std::vector<double> x(f.size()), v(f.size()), a(f.size());
    r.interface_kinematics(x, v, a);
    const double* ref = &r.interface_mesh().reference_positions[3 * at];
    CHECK(x[3 * at + 2] - ref[2] == Approx(z0 + (z1 - z0) * 0.8).epsilon(1e-10));
  }
}

TEST_CASE("rigid body: save and restore continue bitwise", "[fem][rigid]") {
  demfem::test::TempDir dir("rigid_restore");
  RigidSettings rs;
  rs.springs.push_back({{0.0, 0.1, 0.0}, {1e5, 2e5, 1e6}, {10, 10, 100}});
  rs.springs.push_back({{1.0, 0.0, 0.1}, {1e5, 2e5, 1e6}, {0, 0, 0}});
  FemProblem p = block();
  p.gravity = {0, 0, -9.81};
  RigidSolver a(p, rs), b(p, rs);
  std::vector<double> f(3 * a.interface_mesh().node_count(), 0.0);
  for (int i = 0; i < 20; ++i) {
    f[5] = 100.0 * i;
    a.set_interface_forces(f);
    a.advance(1e-3);
  }
  {
    demfem::io::H5File h5(dir.path / "r.h5", demfem::io::H5File::Mode::create);
    a.save(h5, "fem");
  }
  b.restore(demfem::io::H5File(dir.path / "r.h5", demfem::io::H5File::Mode::read), "fem");
  for (int i = 20; i < 40; ++i) {
    f[5] = 100.0 * i;
    a.set_interface_forces(f);
    b.set_interface_forces(f);
    a.advance(1e-3);
    b.advance(1e-3);
  }
  CHECK(a.coordinates() == b.coordinates());
  CHECK(a.rates() == b.rates());
  // Another body's state is refused.
  FemProblem q = p;
  q.materials[0].density = 2700;
  RigidSolver other(q, rs);
  CHECK_THROWS_WITH(
      other.restore(demfem::io::H5File(dir.path / "r.h5", demfem::io::H5File::Mode::read), "fem"),
      Catch::Contains("another body"));
}

TEST_CASE("rigid body: a reference point far from the body is refused, naming the key and range",
          "[fem][rigid]") {
  // Issue 34, item 15: reference_point = [1e8, 0, 0] m ended in "the reduced mass matrix is
  // not positive definite". The block's smallest radius of gyration is
  // sqrt((0.2^2 + 0.1^2) / 12) = 0.0645 m: the limit is 1e5 of it, 6455 m.
  RigidSettings rs;
  rs.springs.push_back({{0.5, 0.1, 0.0}, {1e6, 1e6, 1e6}, {0, 0, 0}});
  rs.springs.push_back({{0.0, 0.0, 0.0}, {1e6, 1e6, 1e6}, {0, 0, 0}});
  rs.springs.push_back({{1.0, 0.2, 0.1}, {1e6, 1e6, 1e6}, {0, 0, 0}});
  rs.has_reference_point = true;
  rs.reference_point = {1e8, 0.0, 0.0};
  CHECK_THROWS_WITH(RigidSolver(block(), rs),
                    Catch::Contains("fem.rigid.reference_point (1e+08, 0, 0) m lies 1e+08 m from "
                                    "the body's centre of mass (0.5, 0.1, 0.05) m") &&
                        Catch::Contains("condition number of about") &&
                        Catch::Contains("Accepted: within 1e+05 radii of gyration of the centre "
                                        "of mass (6.45e+03 m)"));
  CHECK_THROWS_AS(RigidSolver(block(), rs), FemModelError);
  // Inside the range: accepted.
  rs.reference_point = {1000.0, 0.0, 0.0};
  RigidSolver far(block(), rs);
  rs.has_reference_point = false;
  RigidSolver near(block(), rs);
  CHECK(far.mass() == near.mass());
  CHECK(far.reference_point()[0] == 1000.0);
  // With every rotation fixed the point only names where the translation is measured.
  rs.has_reference_point = true;
  rs.reference_point = {1e8, 0.0, 0.0};
  rs.fixed = {false, false, false, true, true, true};
  CHECK_NOTHROW(RigidSolver(block(), rs));
}
