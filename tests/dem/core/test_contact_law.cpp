// Contact law against independent references: the Hertz formula, the restitution
// coefficient of head-on impacts, energy conservation of elastic collisions, the rolling /
// sliding theory of a sphere on an incline, rolling resistance.

#include <catch2/catch.hpp>
#include <cmath>
#include <numbers>

#include "dem_test_util.hpp"
#include "demfem/dem/dem_system.hpp"

using namespace demfem::dem;
using namespace demfem::dem::test;

namespace {
constexpr double kE = 1e8, kNu = 0.3, kRho = 2500.0;
double e_star() {
  return kE / (2.0 * (1.0 - kNu * kNu));
}  // two equal materials (eq. 2.7)
}  // namespace

TEST_CASE("Normal force equals the Hertz formula", "[dem][contact]") {
  // Two spheres of radii 2 and 3 mm overlapping by delta, at rest: F = 4/3 E* sqrt(R) d^1.5.
  // Reference: eq. 2.6-2.8; tolerance 1e-12 relative (round-off only).
  for (double delta : {1e-6, 1e-5, 5e-5}) {
    DemSystem sys(two_material_settings(kE, kNu, kRho, 0.5, 0.3, 1e-7));
    const double r1 = 0.002, r2 = 0.003;
    const std::vector<ParticleInit> p = {sphere({0, 0, 0}, r1),
                                         sphere({r1 + r2 - delta, 0, 0}, r2)};
    sys.add_particles(p);
    sys.advance(1);
    const auto& st = sys.particles();
    // after one step of 1e-7 s the overlap changed by < 1e-16 m (v ~ F dt / m); use the
    // current overlap for the reference
    const double d = r1 + r2 - (st.px[1] - st.px[0]);
    const double reff = r1 * r2 / (r1 + r2);
    const double f_ref = 4.0 / 3.0 * e_star() * std::sqrt(reff) * std::pow(d, 1.5);
    // the force is evaluated with the half-step velocity: its damping part is below 1e-9 F
    CHECK(std::abs(st.fx[0] + f_ref) <= 1e-9 * f_ref);
    CHECK(std::abs(st.fx[1] - f_ref) <= 1e-9 * f_ref);
    CHECK(st.fy[0] == 0.0);
    CHECK(sys.max_overlap() == Approx(d).epsilon(1e-12));
  }
}

TEST_CASE("Head-on impacts recover the restitution coefficient", "[dem][contact]") {
  // Reference: the input e. Tolerance 1 % (the requirement); dt = t_contact / ~190.
  for (double e : {0.2, 0.4, 0.9}) {
    SECTION("sphere-sphere e=" + std::to_string(e)) {
      DemSystem sys(two_material_settings(kE, kNu, kRho, e, 0.0, 1e-6));
      const double r = 0.002, v = 0.5;
      const std::vector<ParticleInit> p = {sphere({-r - 1e-5, 0, 0}, r, {v, 0, 0}),
                                           sphere({r + 1e-5, 0, 0}, r, {-v, 0, 0})};
      sys.add_particles(p);
      sys.advance(600);  // 40 us approach + ~190 us contact
      const auto& st = sys.particles();
      CHECK(sys.max_overlap() == 0.0);  // separated again
      const double e_meas = (st.vx[1] - st.vx[0]) / (2 * v);
      CHECK(e_meas == Approx(e).epsilon(0.01));
    }
    SECTION("sphere-wall e=" + std::to_string(e)) {
      DemSystem sys(two_material_settings(kE, kNu, kRho, e, 0.0, 1e-6));
      sys.add_wall(plane_mesh(0.02, 2));
      const double r = 0.002, v = 0.5;
      const std::vector<ParticleInit> p = {sphere({0.001, 0.0013, r + 1e-5}, r, {0, 0, -v})};
      sys.add_particles(p);
      sys.advance(600);
      const auto& st = sys.particles();
      CHECK(sys.max_overlap() == 0.0);
      CHECK(st.vz[0] / v == Approx(e).epsilon(0.01));
    }
  }
}

TEST_CASE("Elastic frictionless collisions conserve energy", "[dem][contact]") {
  // Three spheres between two walls 20 mm apart, e = 1, mu = 0, no gravity: > 100 bounces
  // (wall and sphere-sphere), dt = t_contact / ~1900 (the error of one collision comes from
  // the step in which the contact opens or closes, where the Hertz force is not smooth: about
  // 2e-6 per bounce at t_contact / 190, 2e-8 at t_contact / 1900, of random sign).
  // Reference: the initial kinetic energy; tolerance 1e-6 relative,
  // measured when no contact is active (velocity Verlet is symplectic: the energy error of a
  // collision does not accumulate).
  DemSystem sys(two_material_settings(kE, kNu, kRho, 1.0, 0.0, 1e-7));
  WallMesh lo = plane_mesh(0.03, 1, std::numbers::pi / 2);  // plane x = 0 (normal along x)
  WallMesh hi = lo;
  for (std::size_t k = 0; k < hi.vertices.size(); k += 3) hi.vertices[k] += 0.02;
  sys.add_wall(lo);
  sys.add_wall(hi);
  const double r = 0.002;
  const std::vector<ParticleInit> p = {sphere({0.004, 0, 0}, r, {1.3, 0, 0}),
                                       sphere({0.010, 0, 0}, r, {-0.7, 0, 0}),
                                       sphere({0.016, 0, 0}, r, {2.1, 0, 0})};
  sys.add_particles(p);
  const double e0 = sys.kinetic_energy();
  // count bounces by sign changes of the velocities
  int bounces = 0;
  std::vector<double> last = {1.3, -0.7, 2.1};
  std::int64_t steps = 0;
  double e_end = 0.0;
  while (bounces < 110 || sys.max_overlap() > 0.0) {
    sys.advance(500);
    steps += 500;
    const auto& st = sys.particles();
    for (int i = 0; i < 3; ++i) {
      if ((st.vx[i] > 0) != (last[i] > 0)) ++bounces;
      last[i] = st.vx[i];
    }
    REQUIRE(steps < 20000000);
    if (sys.max_overlap() == 0.0) e_end = sys.kinetic_energy();
  }
  INFO("bounces " << bounces << " steps " << steps);
  CHECK(std::abs(e_end - e0) <= 1e-6 * e0);
}

namespace {
// Sphere on a plane tilted by theta: returns (acceleration along the slope, angular
// acceleration) from the velocities between t = 0.02 s and 0.08 s.
std::pair<double, double> incline(double theta, double mu, double rolling = 0.0, double v0 = 0.0) {
  auto s = two_material_settings(kE, kNu, kRho, 0.4, mu, 2e-6, rolling);
  s.gravity = {0, 0, -9.81};
  DemSystem sys(s);
  sys.add_wall(plane_mesh(0.12, 6, theta));
  const double r = 0.002;
  const double c = std::cos(theta), sn = std::sin(theta);
  // start on the plane (normal (sin, 0, cos)) near the upper end, overlap ~ equilibrium
  const double x0 = -0.05;
  const std::array<double, 3> on{c * x0, 0.0013, -sn * x0};
  const double h = r - 1e-7;
  const std::vector<ParticleInit> p = {
      sphere({on[0] + sn * h, on[1], on[2] + c * h}, r, {v0 * c, 0, -v0 * sn}, {0, v0 / r, 0})};
  sys.add_particles(p);
  sys.advance(10000);
  const auto& st = sys.particles();
  const double v1 = st.vx[0] * c - st.vz[0] * sn, w1 = st.wy[0];
  sys.advance(30000);
  const double v2 = st.vx[0] * c - st.vz[0] * sn, w2 = st.wy[0];
  return {(v2 - v1) / 0.06, (w2 - w1) / 0.06};
}
}  // namespace

TEST_CASE("Sphere on an inclined triangle-mesh plane rolls or slides", "[dem][contact][wall]") {
  // Reference (rigid-body theory of a sphere on an incline): for mu >= (2/7) tan(theta) it
  // rolls without slip, a = (5/7) g sin(theta); for mu < (2/7) tan(theta) it slides while
  // spinning up, a = g (sin(theta) - mu cos(theta)) and angular acceleration
  // 5 mu g cos(theta) / (2 r). A free sphere never sticks on an incline, so sticking below
  // atan(mu) is not tested. The plane has 72 triangles: the sphere crosses edges and
  // vertices on its way. Tolerance 1 %.
  const double g = 9.81, r = 0.002;
  SECTION("rolling: theta = 20 deg, mu = 0.5") {
    const double th = 20 * std::numbers::pi / 180;
    const auto [a, alpha] = incline(th, 0.5);
    CHECK(a == Approx(5.0 / 7.0 * g * std::sin(th)).epsilon(0.01));
    CHECK(alpha == Approx(5.0 / 7.0 * g * std::sin(th) / r).epsilon(0.01));
  }
  SECTION("sliding: theta = 30 deg, mu = 0.1") {
    const double th = 30 * std::numbers::pi / 180;
    const auto [a, alpha] = incline(th, 0.1);
    CHECK(a == Approx(g * (std::sin(th) - 0.1 * std::cos(th))).epsilon(0.01));
    CHECK(alpha == Approx(5 * 0.1 * g * std::cos(th) / (2 * r)).epsilon(0.01));
  }
  SECTION("frictionless: theta = 15 deg") {
    const double th = 15 * std::numbers::pi / 180;
    const auto [a, alpha] = incline(th, 0.0);
    CHECK(a == Approx(g * std::sin(th)).epsilon(0.01));
    CHECK(alpha == 0.0);
  }
}

TEST_CASE("Rolling resistance decelerates a rolling sphere", "[dem][contact][wall]") {
  // Constant directional torque M = mu_r r F_n on a sphere rolling on a horizontal plane:
  // (I / r^2 + m) a = -M / r, so a = -(5/7) mu_r g. Tolerance 2 % (the contact settles in
  // the first steps).
  const double mur = 0.05, g = 9.81;
  const auto [a, alpha] = incline(0.0, 0.5, mur, 0.5);
  (void)alpha;
  CHECK(a == Approx(-5.0 / 7.0 * mur * g).epsilon(0.02));
}
