// Hulls of closed STL meshes (scanned rocks): closedness, the hull/mesh volume warning for
// concave meshes, orientation, and the errors naming the file and an open edge.

#include <catch2/catch.hpp>

#include <cmath>

#include "demfem/dem/shapes/geometry/stl_reader.hpp"
#include "demfem/dem/shapes/shapes.hpp"
#include "demfem_test/error_of.hpp"
#include "demfem_test/temp_dir.hpp"

using namespace demfem::dem;
using namespace demfem::dem::shapes;
using demfem::test::error_of;
using demfem::test::TempDir;

namespace {

/// The cube [0, a]^3 with its top face split into four triangles around a centre vertex
/// pushed down by h (a dent): closed, outward, not convex; volume a^3 - a^2 h / 3.
TriangleMesh dented_cube(double a, double h) {
  TriangleMesh m = make_box_mesh({0, 0, 0}, {a, a, a}, true);  // inward normals, no top
  for (std::size_t t = 0; t < m.triangles.size(); t += 3)
    std::swap(m.triangles[t + 1], m.triangles[t + 2]);
  // Top corners: vertices 4..7 of make_box_mesh (z = a): 4 (0,0), 5 (a,0), 6 (0,a), 7 (a,a).
  m.vertices.insert(m.vertices.end(), {0.5 * a, 0.5 * a, a - h});
  const std::int32_t c = 8;
  for (const auto& [p, q] : {std::pair{4, 5}, {5, 7}, {7, 6}, {6, 4}})
    m.triangles.insert(m.triangles.end(), {p, q, c});
  return m;
}

}  // namespace

TEST_CASE("a closed convex STL gives its own hull without a warning", "[shapes][stl]") {
  TempDir dir;
  // make_box_mesh orients the triangles inwards (a wall): the volume is taken unsigned.
  write_stl_binary(dir / "box.stl", make_box_mesh({0, 0, 0}, {0.03, 0.02, 0.01}, false));
  const MeshHull h = hull_of_stl(dir / "box.stl");
  CHECK(h.core.vertices().size() == 8);
  CHECK(h.core.triangles().size() == 12);
  // float32 coordinates in binary STL: 1e-7 relative.
  CHECK(h.hull_volume == Approx(0.03 * 0.02 * 0.01).epsilon(1e-6));
  CHECK(h.mesh_volume == Approx(h.hull_volume).epsilon(1e-12));
  CHECK(h.warning.empty());
}

TEST_CASE("a concave STL gives its hull and a warning with the volume ratio", "[shapes][stl]") {
  TempDir dir;
  const double a = 1.0, hd = 0.6;
  write_stl_ascii(dir / "dented.stl", dented_cube(a, hd));
  const MeshHull h = hull_of_stl(dir / "dented.stl");
  CHECK(h.core.vertices().size() == 8);  // the dent's vertex is inside the hull
  CHECK(h.mesh_volume == Approx(a * a * a - a * a * hd / 3).epsilon(1e-12));
  CHECK(h.hull_volume == Approx(a * a * a).epsilon(1e-12));
  // ratio 1 / 0.8 = 1.25
  CHECK_THAT(h.warning, Catch::Contains("dented.stl") && Catch::Contains("not convex") &&
                            Catch::Contains("1.25 times its volume"));
}

TEST_CASE("an open STL is refused naming the file and an open edge", "[shapes][stl]") {
  TempDir dir;
  write_stl_ascii(dir / "open.stl", make_box_mesh({0, 0, 0}, {1, 1, 1}, true));
  CHECK_THAT(error_of<ShapeError>([&] { (void)hull_of_stl(dir / "open.stl"); }),
             Catch::Contains((dir / "open.stl").string()) && Catch::Contains("not closed") &&
                 Catch::Contains("belongs to 1 triangle(s)"));
}

TEST_CASE("non-manifold and inconsistently oriented meshes", "[shapes][stl]") {
  // Two boxes sharing an edge (welded): that edge is in 4 triangles.
  const TriangleMesh a = make_box_mesh({0, 0, 0}, {1, 1, 1}, false);
  const TriangleMesh b = make_box_mesh({1, 1, 0}, {2, 2, 1}, false);
  std::vector<double> v = a.vertices;
  std::vector<std::int32_t> t = a.triangles;
  auto id_of = [&](std::size_t i) {  // b's vertex i in v, added when new
    for (std::size_t j = 0; j < v.size() / 3; ++j)
      if (v[3 * j] == b.vertices[3 * i] && v[3 * j + 1] == b.vertices[3 * i + 1] &&
          v[3 * j + 2] == b.vertices[3 * i + 2])
        return std::int32_t(j);
    v.insert(v.end(), {b.vertices[3 * i], b.vertices[3 * i + 1], b.vertices[3 * i + 2]});
    return std::int32_t(v.size() / 3 - 1);
  };
  for (std::int32_t x : b.triangles) t.push_back(id_of(std::size_t(x)));
  CHECK_THAT(error_of<ShapeError>([&] { (void)hull_of_closed_mesh(v, t, "two boxes"); }),
             Catch::Contains("two boxes: the mesh is not closed") &&
                 Catch::Contains("belongs to 4 triangle(s)"));

  // One triangle flipped: closed, but the volume is unknown; the hull is still the box.
  TriangleMesh c = make_box_mesh({0, 0, 0}, {1, 2, 3}, false);
  std::swap(c.triangles[1], c.triangles[2]);
  const MeshHull h = hull_of_closed_mesh(c.vertices, c.triangles, "flipped");
  CHECK(h.hull_volume == Approx(6.0).epsilon(1e-14));
  CHECK(h.mesh_volume == 0.0);
  CHECK_THAT(h.warning, Catch::Contains("not consistently oriented"));
}

TEST_CASE("a flat closed mesh is a degenerate shape", "[shapes][stl]") {
  // A flat square pillow: top split along 0-3, bottom along 1-2; closed, zero volume.
  const std::vector<double> v{0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0};
  const std::vector<std::int32_t> t{0, 1, 3, 0, 3, 2, 0, 2, 1, 1, 2, 3};
  CHECK_THAT(error_of<ShapeError>([&] { (void)hull_of_closed_mesh(v, t, "flat.stl"); }),
             Catch::Contains("flat.stl") && Catch::Contains("coplanar"));
}
