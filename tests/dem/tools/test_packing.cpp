// The packing sensor's measure (packing.hpp) against hand-computed values: a simple cubic
// lattice of slightly overlapping spheres (solid fraction 4/3 pi r^3 / s^3, six contacts
// inside) and a dilated cube tilted by 45 degrees (top = z + s (a sqrt 2 + r_d)).

#include <catch2/catch.hpp>

#include <cmath>
#include <numbers>
#include <vector>

#include "demfem/dem/dem_system.hpp"
#include "demfem/dem/sensors/packing.hpp"
#include "demfem/dem/sensors/sensors.hpp"

using namespace demfem::dem;

namespace {
DemSettings no_gravity() {
  DemSettings s;
  s.dt = 1e-6;
  s.gravity = {0, 0, 0};
  s.materials = {{"grain", 1e7, 0.3, 2000.0}};
  s.pairs.assign(1, MaterialPair{0.5, 0.5, 0.0});
  s.threads = 1;
  return s;
}

// 5 x 5 x 5 spheres of radius r on a simple cubic lattice of spacing s from the origin.
std::vector<ParticleInit> cubic_lattice(double r, double s) {
  std::vector<ParticleInit> ps;
  for (int i = 0; i < 5; ++i)
    for (int j = 0; j < 5; ++j)
      for (int k = 0; k < 5; ++k) {
        ParticleInit p;
        p.position = {s * i, s * j, s * k};
        p.radius = r;
        ps.push_back(p);
      }
  return ps;
}
}  // namespace

TEST_CASE("packing in a box: simple cubic lattice of spheres", "[sensor][packing]") {
  const double r = 0.01, s = 0.0198;  // 0.2 mm overlap with each of six neighbours
  DemSystem d(no_gravity());
  d.add_particles(cubic_lattice(r, s));
  d.advance(1);  // the contact forces of one step
  // The inner 3 x 3 x 3 centres, in a box of 3 lattice cells around them.
  const std::array<double, 3> lo{0.5 * s, 0.5 * s, 0.5 * s}, hi{3.5 * s, 3.5 * s, 3.5 * s};
  const auto res = packing_in_box(d, lo, hi);
  CHECK(res.particles == 27);
  CHECK(res.solid_fraction ==
        Approx(4.0 / 3.0 * std::numbers::pi * r * r * r / (s * s * s)).epsilon(1e-12));
  CHECK(res.coordination == Approx(6.0).epsilon(1e-12));
  CHECK(res.top == Approx(3 * s + r).epsilon(1e-9));  // moved by at most 1e-12 m in one step
  // the whole lattice: corners 3, edges 4, faces 5, inside 6 contacts
  const auto all = packing_in_box(d, {-1, -1, -1}, {1, 1, 1});
  CHECK(all.particles == 125);
  CHECK(all.coordination == Approx((8 * 3 + 36 * 4 + 54 * 5 + 27 * 6) / 125.0).epsilon(1e-12));
  // an empty box
  const auto none = packing_in_box(d, {2, 2, 2}, {3, 3, 3});
  CHECK(none.particles == 0);
  CHECK(none.solid_fraction == 0.0);
  CHECK(std::isnan(none.top));
  CHECK_THROWS_AS(packing_in_box(d, {0, 0, 0}, {1, 0, 1}), std::invalid_argument);
}

TEST_CASE("packing in a box: top and volume of a tilted, scaled dilated cube",
          "[sensor][packing]") {
  const double a = 0.01, rd = 0.002, sc = 2.0;
  PolyhedronShape cube;
  cube.name = "cube";
  for (int c = 0; c < 8; ++c)
    cube.vertices.insert(cube.vertices.end(), {c & 1 ? a : -a, c & 2 ? a : -a, c & 4 ? a : -a});
  // outward counter-clockwise faces of the cube's 8 corners (bit 0 x, bit 1 y, bit 2 z)
  cube.triangles = {0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6, 0, 1, 5, 0, 5, 4,
                    2, 6, 7, 2, 7, 3, 0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5};
  cube.dilation = rd;
  const double e = 2 * a;
  cube.volume = e * e * e + 6 * e * e * rd + 3 * std::numbers::pi * e * rd * rd +
                4.0 / 3.0 * std::numbers::pi * rd * rd * rd;
  const double i0 = cube.volume * (e + 2 * rd) * (e + 2 * rd) / 6.0;  // a cube's m(2h)^2/6
  cube.inertia = {i0, i0, i0};
  DemSystem d(no_gravity());
  const auto id = d.add_shape(cube);
  ParticleInit p;
  p.position = {0.1, 0.2, 0.3};
  p.shape = ParticleShape::polyhedron;
  p.shape_id = id;
  p.scale = sc;
  const double h = std::sin(std::numbers::pi / 8);  // 45 degrees about x
  p.orientation = {std::cos(std::numbers::pi / 8), h, 0, 0};
  d.add_particles(std::span<const ParticleInit>(&p, 1));
  const auto res = packing_in_box(d, {0, 0, 0}, {1, 1, 1});
  CHECK(res.particles == 1);
  CHECK(res.top == Approx(0.3 + sc * (a * std::sqrt(2.0) + rd)).epsilon(1e-12));
  CHECK(res.solid_fraction == Approx(cube.volume * sc * sc * sc).epsilon(1e-12));
  CHECK(res.coordination == 0.0);
}

TEST_CASE("force distribution: hand-made samples and an exponential's quantiles",
          "[sensor][packing][contacts]") {
  // {1, 1, 1, 5}: <f> = 2, one force above 4; above <f> only x = 2.5: beta = 1 / 1.5
  const std::vector<double> four{1.0, 1.0, 1.0, 5.0};
  const auto d = force_distribution(four);
  CHECK(d.contacts == 4);
  CHECK(d.mean == 2.0);
  CHECK(d.above_two_mean == 0.25);
  CHECK(d.tail_decay == Approx(1.0 / 1.5).epsilon(1e-15));
  // equal forces: no tail to fit
  const std::vector<double> equal(10, 3.0);
  const auto e = force_distribution(equal);
  CHECK(e.mean == 3.0);
  CHECK(e.above_two_mean == 0.0);
  CHECK(std::isnan(e.tail_decay));
  const auto none = force_distribution({});
  CHECK(none.contacts == 0);
  CHECK(std::isnan(none.mean));
  CHECK(std::isnan(none.above_two_mean));
  // the midpoint quantiles of an exponential of mean 3 N (the distribution of random packings'
  // large forces): <f> = 3 N, P(f > 2 <f>) = e^-2, and the tail above the mean is the same
  // exponential (memoryless), beta = 1; quantile discretisation of 1e5 samples errs < 1e-3
  const int n = 100000;
  std::vector<double> q(n);
  for (int k = 0; k < n; ++k) q[std::size_t(k)] = -3.0 * std::log(1.0 - (k + 0.5) / n);
  const auto x = force_distribution(q);
  CHECK(x.mean == Approx(3.0).epsilon(1e-3));
  CHECK(x.above_two_mean == Approx(std::exp(-2.0)).epsilon(1e-3));
  CHECK(x.tail_decay == Approx(1.0).epsilon(1e-3));
}

TEST_CASE("contact statistics in a box: simple cubic lattice, every contact Hertz's force",
          "[sensor][packing][contacts]") {
  const double r = 0.01, s = 0.0198;  // 0.2 mm overlap with each of six neighbours
  DemSystem d(no_gravity());
  d.add_particles(cubic_lattice(r, s));
  d.advance(1);  // at rest: the forces of the overlaps alone (no dashpot, no spring yet)
  // Hertz: F = 4/3 E* sqrt(R* delta) delta, E* = E / (2 (1 - nu^2)), R* = r / 2
  const double e_star = 1e7 / (2.0 * (1.0 - 0.3 * 0.3)), delta = 2 * r - s;
  const double f0 = 4.0 / 3.0 * e_star * std::sqrt(0.5 * r * delta) * delta;
  // box 0.75 s .. 3.25 s: centres 1, 2, 3 s (27 particles); contact midpoints at 1.5 and
  // 2.5 s along their axis and 1, 2, 3 s across it: 2 x 9 per axis, 54
  const std::array<double, 3> lo{0.75 * s, 0.75 * s, 0.75 * s}, hi{3.25 * s, 3.25 * s, 3.25 * s};
  const auto c = contact_statistics_in_box(d, lo, hi);
  CHECK(c.rattlers == 0);
  CHECK(c.coordination_no_rattlers == Approx(6.0).epsilon(1e-12));
  CHECK(c.force.contacts == 54);
  CHECK(c.force.mean == Approx(f0).epsilon(1e-9));
  CHECK(c.force.above_two_mean == 0.0);
  // Love-Weber: the 18 vertical contacts, each f0 over a branch s, in (2.5 s)^3
  CHECK(c.stress_zz == Approx(18.0 * f0 * s / std::pow(2.5 * s, 3)).epsilon(1e-9));
  CHECK_THROWS_AS(contact_statistics_in_box(d, {0, 0, 0}, {1, 1, 0}), std::invalid_argument);
}

TEST_CASE("contact statistics: rattlers are particles with fewer than two contacts",
          "[sensor][packing][contacts]") {
  const double r = 0.01, s = 0.0198;
  DemSystem d(no_gravity());
  std::vector<ParticleInit> ps(5);
  ps[0].position = {0.0, 0.0, 0.0};  // a touching triangle 0, 1, 2 ...
  ps[1].position = {s, 0.0, 0.0};
  ps[2].position = {0.5 * s, s * std::sqrt(3.0) / 2, 0.0};
  ps[3].position = {-s, 0.0, 0.0};   // ... 3 touches 0 only ...
  ps[4].position = {0.0, 0.0, 0.1};  // ... 4 touches none
  for (auto& p : ps) p.radius = r;
  d.add_particles(ps);
  d.advance(1);
  const auto c = contact_statistics_in_box(d, {-0.1, -0.1, -0.1}, {0.1, 0.1, 0.2});
  CHECK(c.rattlers == 2);                    // 3 (one contact) and 4 (none)
  CHECK(c.coordination_no_rattlers == 2.0);  // the triangle, 0's contact with 3 left out
  CHECK(c.force.contacts == 4);              // every contact, rattlers' included
  const auto p = packing_in_box(d, {-0.1, -0.1, -0.1}, {0.1, 0.1, 0.2});
  CHECK(p.coordination == Approx((2 + 2 + 3 + 1 + 0) / 5.0).epsilon(1e-15));
}

TEST_CASE("contact statistics: a contact across a periodic seam counts where its midpoint is",
          "[sensor][packing][contacts]") {
  const double r = 0.01, s = 0.0198, L = 0.1;
  DemSettings set = no_gravity();
  set.periodic.on[0] = true;
  set.periodic.lo = {0.0, 0.0, 0.0};
  set.periodic.hi = {L, 0.0, 0.0};
  DemSystem d(set);
  std::vector<ParticleInit> ps(2);
  ps[0].position = {0.0049, 0.05, 0.05};  // touching through x = 0: branch 0.0198 m
  ps[1].position = {L - (s - 0.0049), 0.05, 0.05};
  for (auto& p : ps) p.radius = r;
  d.add_particles(ps);
  d.advance(1);
  // the midpoint lies at x = -0.005, i.e. 0.095 m: in a box at the seam's far side only
  const auto seam = contact_statistics_in_box(d, {0.09, 0.0, 0.0}, {0.1, 0.1, 0.1});
  CHECK(seam.force.contacts == 1);
  CHECK(seam.stress_zz == 0.0);  // a horizontal contact has no vertical stress
  CHECK(contact_statistics_in_box(d, {0.02, 0.0, 0.0}, {0.08, 0.1, 0.1}).force.contacts == 0);
}

TEST_CASE("packing sensor with contacts = true: the contact statistics follow the packing",
          "[sensor][packing][contacts]") {
  const double r = 0.01, s = 0.0198;
  DemSystem d(no_gravity());
  std::vector<ParticleInit> ps(3);
  for (int k = 0; k < 3; ++k)
    ps[std::size_t(k)].position = {0.0, 0.0, s * k}, ps[std::size_t(k)].radius = r;
  d.add_particles(ps);
  d.advance(1);
  SensorSpec spec;
  spec.kind = SensorSpec::Kind::packing;
  spec.name = "bed";
  spec.interval = 1.0;
  spec.box_lo = {-0.1, -0.1, -0.1};
  spec.box_hi = {0.1, 0.1, 0.1};
  SensorSpec plain = spec;
  spec.contacts = true;
  SensorSet sensors({spec, plain}, {}, d);
  const std::vector<std::int64_t> ids{0, 1, 2};
  sensors.sample(d, ids);
  const auto& v = sensors.last(0);
  REQUIRE(v.size() == 11);  // particles, solid_fraction, coordination, top + 7
  CHECK(sensors.last(1).size() == 4);
  const auto c = contact_statistics_in_box(d, spec.box_lo, spec.box_hi);
  CHECK(v[4] == 2.0);  // the column's ends have one contact each
  CHECK(v[5] == 0.0);  // the middle one's contacts are with rattlers
  CHECK(v[6] == 2.0);
  CHECK(v[7] == c.force.mean);
  CHECK(v[10] == c.stress_zz);
  CHECK(c.stress_zz > 0.0);  // the two vertical contacts are compressed
}
