// The packing sensor's measure (packing.hpp) against hand-computed values: a simple cubic
// lattice of slightly overlapping spheres (solid fraction 4/3 pi r^3 / s^3, six contacts
// inside) and a dilated cube tilted by 45 degrees (top = z + s (a sqrt 2 + r_d)).

#include <catch2/catch.hpp>

#include <cmath>
#include <numbers>

#include "demfem/dem/dem_system.hpp"
#include "demfem/dem/sensors/packing.hpp"

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
}  // namespace

TEST_CASE("packing in a box: simple cubic lattice of spheres", "[sensor][packing]") {
  const double r = 0.01, s = 0.0198;  // 0.2 mm overlap with each of six neighbours
  DemSystem d(no_gravity());
  std::vector<ParticleInit> ps;
  for (int i = 0; i < 5; ++i)
    for (int j = 0; j < 5; ++j)
      for (int k = 0; k < 5; ++k) {
        ParticleInit p;
        p.position = {s * i, s * j, s * k};
        p.radius = r;
        ps.push_back(p);
      }
  d.add_particles(ps);
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
