// Sensors without the engine: mass flow through a plane against a hand count, and the angle
// of repose of synthetic heaps of known slope.

#include <catch2/catch.hpp>

#include <cmath>
#include <numbers>

#include "demfem/dem/sensors/sensors.hpp"
#include "demfem_test/cube_shape.hpp"

using namespace demfem::dem;

namespace {

void push(ParticleState& s, double x, double y, double z, double r, double m) {
  s.px.push_back(x);
  s.py.push_back(y);
  s.pz.push_back(z);
  s.radius.push_back(r);
  s.mass.push_back(m);
}

}  // namespace

TEST_CASE("mass flow counter: free fall through a plane, counted by hand", "[sensor]") {
  // Ten particles of mass 0.1 kg * (i + 1) start at rest at heights z_i = 0.1 + 0.05 i above
  // the plane z = 0 and fall freely: z_i(t) = z0_i - g t^2 / 2. Particle i crosses at
  // t_i = sqrt(2 z0_i / g). Sampling every 10 ms, the mass in each window is the sum of the
  // masses with t_i in (t_prev, t].
  const double g = 9.81;
  const int n = 10;
  std::vector<std::int64_t> ids(n);
  for (int i = 0; i < n; ++i) ids[i] = 100 + i;  // ids need not start at 0
  MassFlowCounter counter({0, 0, 0}, {0, 0, -1}, 0.0);
  double total = 0.0;
  for (int k = 0; k <= 40; ++k) {
    const double t = 0.01 * k, t_prev = 0.01 * (k - 1);
    ParticleState s;
    for (int i = 0; i < n; ++i)
      push(s, 0.01 * i, 0, 0.1 + 0.05 * i - 0.5 * g * t * t, 0.002, 0.1 * (i + 1));
    const double dm = counter.update(s, ids);
    double expected = 0.0;
    for (int i = 0; i < n; ++i) {
      const double ti = std::sqrt(2 * (0.1 + 0.05 * i) / g);
      if (k > 0 && ti > t_prev && ti <= t) expected += 0.1 * (i + 1);
    }
    INFO("t = " << t);
    CHECK(dm == Approx(expected).margin(1e-12));
    total += dm;
  }
  // All ten have crossed by t = 0.4 s (the last at sqrt(2 * 0.55 / 9.81) = 0.335 s).
  CHECK(total == Approx(5.5).epsilon(1e-12));
}

TEST_CASE("mass flow counter: upward crossings subtract, disc limits the area, removal is safe",
          "[sensor]") {
  MassFlowCounter c({0, 0, 1}, {0, 0, -2}, 0.5);
  ParticleState a, b;
  push(a, 0.0, 0, 1.1, 0.01, 2.0);  // id 0: crosses down inside the disc
  push(a, 0.9, 0, 1.1, 0.01, 3.0);  // id 1: crosses down outside the disc
  push(a, 0.1, 0, 0.9, 0.01, 5.0);  // id 2: crosses up inside
  std::vector<std::int64_t> ia{0, 1, 2};
  CHECK(c.update(a, ia) == 0.0);     // first sight: sides only
  push(b, 0.1, 0, 1.2, 0.01, 5.0);   // id 2, now first in the arrays
  push(b, 0.0, 0, 0.95, 0.01, 2.0);  // id 0
  push(b, 0.9, 0, 0.95, 0.01, 3.0);  // id 1
  std::vector<std::int64_t> ib{2, 0, 1};
  CHECK(c.update(b, ib) == Approx(2.0 - 5.0));
  // id 1 removed, id 7 new: nothing crosses.
  ParticleState d;
  push(d, 0.0, 0, 0.9, 0.01, 2.0);
  push(d, 0.0, 0, 2.0, 0.01, 1.0);
  std::vector<std::int64_t> id{0, 7};
  CHECK(c.update(d, id) == 0.0);
}

TEST_CASE("angle of repose of synthetic cones of known slope", "[sensor]") {
  // A cone of spheres of radius r on a hexagonal-ish grid: surface z = H - r_xy tan(theta).
  for (double theta_deg : {15.0, 22.0, 30.0}) {
    const double r = 0.002, H = 0.06;
    const double tan_t = std::tan(theta_deg * std::numbers::pi / 180.0);
    const double R = H / tan_t;
    ParticleState s;
    for (double x = -R; x <= R; x += 2 * r)
      for (double y = -R; y <= R; y += 2 * r) {
        const double rho = std::hypot(x, y);
        const double top = H - rho * tan_t;
        for (double z = r; z + r <= top; z += 2 * r) push(s, x + 0.3, y - 0.2, z, r, 1e-5);
      }
    ReposeOptions o;
    o.centre = {0.3, -0.2};
    const auto res = angle_of_repose(s, o);
    INFO("theta = " << theta_deg << ", fitted bins " << res.fitted_bins);
    // Layer quantisation (2 r = 4 mm steps in z) and the bin width blur the surface; over a
    // flank of >= 60 mm the slope error stays within 1.5 degrees.
    CHECK(res.angle_deg == Approx(theta_deg).margin(1.5));
    CHECK(res.heap_radius == Approx(R).margin(0.3 * R));
  }
  ParticleState tiny;
  push(tiny, 0, 0, 0.002, 0.002, 1e-5);
  CHECK_THROWS_WITH(angle_of_repose(tiny, ReposeOptions{}), Catch::Contains("too small"));
}

TEST_CASE("angle of repose: a polyhedron's top is its highest surface point", "[sensor][poly]") {
  // Reference: geometry. A cube core of half side 0.3 (dilation 0.2) at scale 0.05, turned
  // by 0.6 rad about x: its highest core vertex is 0.3 (sin 0.6 + cos 0.6) above the centre,
  // so its top is z + 0.05 (0.3 (sin 0.6 + cos 0.6) + 0.2); a sphere's stays z + r. The
  // bounding sphere (radius 0.05 (0.3 √3 + 0.2)) would put it higher. Tolerance 1e-12 m.
  DemSystem sys = demfem::test::cube_and_sphere({"m", 1e7, 0.3, 1000.0}, {0, 0, 0.5});
  const std::vector<double> tops = particle_tops(sys);
  REQUIRE(tops.size() == 2);
  CHECK(std::abs(tops[0] - (3.0 + 0.05 * (0.3 * (std::sin(0.6) + std::cos(0.6)) + 0.2))) < 1e-12);
  CHECK(std::abs(tops[1] - 0.51) < 1e-12);
  CHECK(tops[0] < 3.0 + sys.particles().radius[0] - 1e-3);
}
