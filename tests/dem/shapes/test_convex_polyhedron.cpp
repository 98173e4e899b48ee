// Convex cores: Qhull hulls, triangulation invariants, validation of given triangulations,
// the simple solids, and the errors for degenerate input.

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <random>

#include "demfem/dem/shapes/convex_polyhedron.hpp"
#include "demfem_test/error_of.hpp"
#include "shape_test_util.hpp"

using namespace demfem::dem::shapes;
using demfem::test::error_of;

namespace {

/// Invariants every valid core must have: outward unit normals consistent with the vertex
/// order, each edge in two triangles, Euler 2, every vertex on or below every face plane.
void check_invariants(const ConvexPolyhedron& k) {
  const auto& v = k.vertices();
  const auto& t = k.triangles();
  REQUIRE(k.normals().size() == t.size());
  REQUIRE(std::int64_t(v.size()) - std::int64_t(k.edges().size()) + std::int64_t(t.size()) == 2);
  Vec3 c{0, 0, 0};
  for (const Vec3& p : v) c = c + (1.0 / double(v.size())) * p;
  std::map<std::pair<int, int>, int> directed;
  for (std::size_t f = 0; f < t.size(); ++f) {
    const Vec3 n = cross(v[t[f][1]] - v[t[f][0]], v[t[f][2]] - v[t[f][0]]);
    CHECK(dot(n, k.normals()[f]) > 0);
    CHECK(std::abs(norm(k.normals()[f]) - 1.0) < 1e-15);
    // outward: the vertex mean lies below every face
    CHECK(dot(k.normals()[f], c - v[t[f][0]]) < 0);
    for (const Vec3& p : v) CHECK(dot(k.normals()[f], p - v[t[f][0]]) <= 1e-12);
    for (int e = 0; e < 3; ++e) directed[{t[f][e], t[f][(e + 1) % 3]}]++;
  }
  for (const auto& [e, n] : directed) {
    CHECK(n == 1);
    CHECK(directed.count({e.second, e.first}) == 1);
  }
  // Fans: triangle k of vertex i's fan holds neighbours k and k+1.
  for (std::size_t i = 0; i < v.size(); ++i) {
    const auto nb = k.neighbours(i);
    const auto fan = k.vertex_triangles(i);
    REQUIRE(nb.size() == fan.size());
    REQUIRE(nb.size() >= 3);
    for (std::size_t j = 0; j < fan.size(); ++j) {
      const Triangle& tri = t[std::size_t(fan[j])];
      int found = 0;
      for (int q : tri) found += (q == int(i)) + (q == nb[j]) + (q == nb[(j + 1) % nb.size()]);
      CHECK(found == 3);
    }
  }
}

}  // namespace

TEST_CASE("the hull of a cube's corners is 8 vertices and 12 outward triangles", "[shapes]") {
  const ConvexPolyhedron cube = make_cube(2.0);
  CHECK(cube.vertices().size() == 8);
  CHECK(cube.triangles().size() == 12);
  CHECK(cube.edges().size() == 18);
  check_invariants(cube);
  // 6 edges inside the square faces (flat), 12 cube edges at a right angle.
  int flat = 0, right = 0;
  for (const Edge& e : cube.edges()) {
    flat += e.angle < 1e-15;
    right += std::abs(e.angle - std::numbers::pi / 2) < 1e-15;
  }
  CHECK(flat == 6);
  CHECK(right == 12);
  for (const Vec3& n : cube.normals()) {
    // each normal is a coordinate axis
    const double m = std::max({std::abs(n[0]), std::abs(n[1]), std::abs(n[2])});
    CHECK(m == Approx(1.0).margin(1e-15));
  }
  CHECK(cube.width({1, 0, 0}) == Approx(2.0).epsilon(1e-15));
  CHECK(cube.support({1, 1, 1}) == Vec3{1, 1, 1});
}

TEST_CASE("points on faces, edges and inside a cube are not hull vertices", "[shapes]") {
  std::vector<Vec3> p;
  for (int i = 0; i < 8; ++i)
    p.push_back({double(i & 1), double((i >> 1) & 1), double((i >> 2) & 1)});
  for (double s : {0.25, 0.5, 0.75}) {
    p.push_back({s, 0, 0});      // on an edge
    p.push_back({s, 1, 1});      // on an edge
    p.push_back({s, 0.3, 1});    // on a face
    p.push_back({0.4, s, 0.6});  // inside
  }
  const ConvexPolyhedron k = ConvexPolyhedron::hull(p, "cube with extra points");
  CHECK(k.vertices().size() == 8);
  CHECK(k.triangles().size() == 12);
  check_invariants(k);
}

TEST_CASE("the hull of random points contains them all and uses only input points", "[shapes]") {
  std::mt19937_64 gen(5);
  const std::vector<Vec3> p = test::random_points(gen, 500, {1.0, 0.5, 0.25});
  const ConvexPolyhedron k = ConvexPolyhedron::hull(p, "random points");
  check_invariants(k);
  // Triangulated hull with every vertex extreme: 2V - 4 triangles.
  CHECK(k.triangles().size() == 2 * k.vertices().size() - 4);
  for (const Vec3& x : p)
    for (std::size_t f = 0; f < k.triangles().size(); ++f)
      CHECK(dot(k.normals()[f], x - k.vertices()[std::size_t(k.triangles()[f][0])]) <= 1e-12);
  for (const Vec3& v : k.vertices()) CHECK(std::find(p.begin(), p.end(), v) != p.end());
}

TEST_CASE("the simple solids have their vertex and triangle counts", "[shapes]") {
  const auto tet = make_regular_tetrahedron(1.0);
  CHECK(tet.vertices().size() == 4);
  CHECK(tet.triangles().size() == 4);
  for (const Edge& e : tet.edges())
    CHECK(norm(tet.vertices()[std::size_t(e.a)] - tet.vertices()[std::size_t(e.b)]) ==
          Approx(1.0).epsilon(1e-15));
  check_invariants(tet);
  const auto oct = make_octahedron(1.0);
  CHECK(oct.vertices().size() == 6);
  CHECK(oct.triangles().size() == 8);
  check_invariants(oct);
  const auto prism = make_triangular_prism(1.0, 2.0);
  CHECK(prism.vertices().size() == 6);
  CHECK(prism.triangles().size() == 8);
  CHECK(prism.width({0, 0, 1}) == Approx(2.0).epsilon(1e-15));
  check_invariants(prism);
  const auto box = make_box(1.0, 2.0, 3.0);
  CHECK(box.width({0, 1, 0}) == Approx(2.0).epsilon(1e-15));
  check_invariants(box);
}

TEST_CASE("the point core has one vertex and no faces", "[shapes]") {
  const ConvexPolyhedron p = ConvexPolyhedron::point({1, 2, 3});
  CHECK(p.is_point());
  CHECK(p.vertices().size() == 1);
  CHECK(p.triangles().empty());
  CHECK(p.edges().empty());
  CHECK(p.neighbours(0).empty());
  CHECK(p.support({0, 0, 1}) == Vec3{1, 2, 3});
  CHECK(p.width({1, 0, 0}) == 0.0);
  CHECK(ConvexPolyhedron().is_point());
  CHECK(p.translated({-1, -2, -3}).vertices()[0] == Vec3{0, 0, 0});
}

TEST_CASE("transforms keep the triangulation and refuse reflections", "[shapes]") {
  const auto box = make_box(1.0, 2.0, 3.0);
  const double c = std::cos(0.3), s = std::sin(0.3);
  const Mat3 rot{Vec3{c, -s, 0}, Vec3{s, c, 0}, Vec3{0, 0, 1}};
  const auto moved = box.transformed(rot, {1, 2, 3});
  CHECK(moved.triangles() == box.triangles());
  check_invariants(moved);
  CHECK(box.scaled(2.0).width({0, 0, 1}) == Approx(6.0).epsilon(1e-15));
  const Mat3 mirror{Vec3{-1, 0, 0}, Vec3{0, 1, 0}, Vec3{0, 0, 1}};
  CHECK_THAT(error_of<ShapeError>([&] {
               (void)box.transformed(mirror, {0, 0, 0});
             }),
             Catch::Contains("determinant -1"));
  CHECK_THAT(error_of<ShapeError>([&] { (void)box.scaled(0.0); }), Catch::Contains("must be > 0"));
}

TEST_CASE("degenerate point sets are refused naming the input", "[shapes]") {
  const std::vector<Vec3> flat{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}, {0.5, 0.2, 0}};
  CHECK_THAT(
      error_of<ShapeError>([&] { (void)ConvexPolyhedron::hull(flat, "rock.stl"); }),
      Catch::Contains("rock.stl") && Catch::Contains("coplanar") && Catch::Contains("zero volume"));
  // Coplanar up to round-off: a tilted plane.
  std::vector<Vec3> tilted;
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) tilted.push_back({0.1 * i, 0.1 * j, 0.3 * 0.1 * i + 0.7 * 0.1 * j});
  CHECK_THAT(error_of<ShapeError>([&] { (void)ConvexPolyhedron::hull(tilted, "tilted"); }),
             Catch::Contains("coplanar"));
  const std::vector<Vec3> line{{0, 0, 0}, {1, 1, 1}, {2, 2, 2}, {3, 3, 3}};
  CHECK_THAT(error_of<ShapeError>([&] { (void)ConvexPolyhedron::hull(line, "line"); }),
             Catch::Contains("line: all 4 points are collinear"));
  const std::vector<Vec3> same(5, Vec3{1, 1, 1});
  CHECK_THAT(error_of<ShapeError>([&] { (void)ConvexPolyhedron::hull(same, "same"); }),
             Catch::Contains("coincide"));
  const std::vector<Vec3> three{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  CHECK_THAT(error_of<ShapeError>([&] { (void)ConvexPolyhedron::hull(three, "three"); }),
             Catch::Contains("at least 4 points, got 3"));
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::vector<Vec3> bad{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, nan}};
  CHECK_THAT(error_of<ShapeError>([&] { (void)ConvexPolyhedron::hull(bad, "bad"); }),
             Catch::Contains("point 3 has a non-finite coordinate"));
  CHECK_THAT(error_of<ShapeError>([] { (void)make_box(1.0, 0.0, 1.0); }), Catch::Contains("box"));
}

TEST_CASE("given triangulations are checked: closed, oriented, convex", "[shapes]") {
  const auto cube = make_cube(1.0);
  auto v = cube.vertices();
  auto t = cube.triangles();
  CHECK_NOTHROW(ConvexPolyhedron::from_triangles(v, t, "copy"));

  auto open = t;
  open.pop_back();
  CHECK_THAT(error_of<ShapeError>([&] { (void)ConvexPolyhedron::from_triangles(v, open, "open"); }),
             Catch::Contains("open: the edge between vertex") && Catch::Contains("not closed"));

  auto flipped = t;
  std::swap(flipped[3][1], flipped[3][2]);
  CHECK_THAT(
      error_of<ShapeError>([&] { (void)ConvexPolyhedron::from_triangles(v, flipped, "flipped"); }),
      Catch::Contains("inconsistently oriented"));

  auto inside_out = t;
  for (Triangle& tri : inside_out) std::swap(tri[1], tri[2]);
  CHECK_THAT(
      error_of<ShapeError>([&] { (void)ConvexPolyhedron::from_triangles(v, inside_out, "inv"); }),
      Catch::Contains("negative volume"));

  auto dented = v;
  dented[0] = 0.8 * dented[0];  // a corner pushed towards the centre
  CHECK_THAT(
      error_of<ShapeError>([&] { (void)ConvexPolyhedron::from_triangles(dented, t, "dented"); }),
      Catch::Contains("not convex"));

  auto extra = v;
  extra.push_back({0, 0, 0});
  CHECK_THAT(
      error_of<ShapeError>([&] { (void)ConvexPolyhedron::from_triangles(extra, t, "extra"); }),
      Catch::Contains("vertex 8 (0, 0, 0) is in no triangle"));

  auto sliver = v;
  sliver[std::size_t(t[0][2])] = sliver[std::size_t(t[0][0])];
  CHECK_THAT(
      error_of<ShapeError>([&] { (void)ConvexPolyhedron::from_triangles(sliver, t, "sliver"); }),
      Catch::Contains("zero area"));

  // Two tetrahedra sharing nothing: closed, oriented, but V - E + F = 4.
  const auto tet = make_regular_tetrahedron(1.0);
  std::vector<Vec3> two = tet.vertices();
  for (const Vec3& p : tet.vertices()) two.push_back(p + Vec3{5, 0, 0});
  std::vector<Triangle> tt = tet.triangles();
  for (Triangle tri : tet.triangles()) tt.push_back({tri[0] + 4, tri[1] + 4, tri[2] + 4});
  CHECK_THAT(error_of<ShapeError>([&] { (void)ConvexPolyhedron::from_triangles(two, tt, "two"); }),
             Catch::Contains("V - E + F = 8 - 12 + 8 = 4"));
}
