// STL reading: ASCII and binary round trips, welding, and every malformed-file kind.

#include <catch2/catch.hpp>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>

#include "demfem/dem/shapes/geometry/stl_reader.hpp"
#include "demfem_test/error_of.hpp"
#include "demfem_test/temp_dir.hpp"

using namespace demfem::dem;
using demfem::test::TempDir;

namespace {

void write_text(const std::filesystem::path& p, const std::string& text) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out << text;
}

std::string read_bytes(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

std::string message_of(const std::filesystem::path& p) {
  return demfem::test::error_of<StlError>([&] { read_stl(p); });
}

/// A box has 8 corners and 12 triangles; an edge is shared by exactly two triangles.
void check_closed_box(const TriangleMesh& m) {
  REQUIRE(m.vertices.size() == 3 * 8);
  REQUIRE(m.triangles.size() == 3 * 12);
  std::map<std::pair<int, int>, int> edges;
  for (std::size_t t = 0; t < 12; ++t)
    for (int c = 0; c < 3; ++c) {
      int a = m.triangles[3 * t + c], b = m.triangles[3 * t + (c + 1) % 3];
      edges[{std::min(a, b), std::max(a, b)}]++;
    }
  for (const auto& [e, n] : edges) CHECK(n == 2);
}

const char* kTriangle =
    "solid t\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vertex 1 0 0\n"
    "   vertex 0 1 0\n  endloop\n endfacet\nendsolid t\n";

}  // namespace

TEST_CASE("ASCII and binary STL round trip a box with welded vertices", "[stl]") {
  TempDir dir;
  const TriangleMesh box = make_box_mesh({0, 0, 0}, {0.5, 0.25, 0.125}, false);
  write_stl_ascii(dir / "box_ascii.stl", box);
  write_stl_binary(dir / "box_binary.stl", box);
  for (const char* name : {"box_ascii.stl", "box_binary.stl"}) {
    INFO(name);
    const TriangleMesh m = read_stl(dir / name);
    check_closed_box(m);
    CHECK(m.name == std::filesystem::path(name).stem().string());
    // Values representable in float come back exactly from both formats.
    CHECK(mesh_area(m.vertices, m.triangles) ==
          Approx(2 * (0.5 * 0.25 + 0.5 * 0.125 + 0.25 * 0.125)).epsilon(1e-12));
    // Same triangles in the same order with the same coordinates.
    for (std::size_t i = 0; i < box.triangles.size(); ++i) {
      for (int k = 0; k < 3; ++k) {
        CHECK(m.vertices[3 * m.triangles[i] + k] == box.vertices[3 * box.triangles[i] + k]);
      }
    }
  }
  // The binary file's header starts with "solid": detection is by size, not by prefix.
  CHECK(read_bytes(dir / "box_binary.stl").rfind("solid", 0) == 0);
}

TEST_CASE("STL welding merges vertices within the tolerance only", "[stl]") {
  TempDir dir;
  // Two triangles sharing an edge whose copies differ by 1e-7 m.
  write_text(dir / "two.stl",
             "solid two\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\n"
             "endloop\nendfacet\nfacet normal 0 0 1\nouter loop\nvertex 1.0000001 0 0\n"
             "vertex 1 1 0\nvertex 0 1.0000001 0\nendloop\nendfacet\nendsolid two\n");
  CHECK(read_stl(dir / "two.stl", 1e-6).vertices.size() == 3 * 4);
  CHECK(read_stl(dir / "two.stl", 1e-9).vertices.size() == 3 * 6);
  // The default tolerance (1e-9 of the 1.41 m diagonal) keeps them apart.
  CHECK(read_stl(dir / "two.stl").vertices.size() == 3 * 6);
}

TEST_CASE("STL reader accepts the plane and open box generators' output", "[stl]") {
  TempDir dir;
  const TriangleMesh plane = make_plane_mesh({1, 2, 3}, {0, 0, 2}, 2.0);
  REQUIRE(plane.triangles.size() == 6);
  CHECK(mesh_area(plane.vertices, plane.triangles) == Approx(4.0).epsilon(1e-12));
  // Normal by the right-hand rule points along +z as asked.
  const auto& v = plane.vertices;
  const double ax = v[3] - v[0], ay = v[4] - v[1], bx = v[6] - v[0], by = v[7] - v[1];
  CHECK(ax * by - ay * bx > 0);
  const TriangleMesh open = make_box_mesh({0, 0, 0}, {1, 1, 1}, true);
  CHECK(open.triangles.size() == 3 * 10);
  write_stl_binary(dir / "open.stl", open);
  CHECK(read_stl(dir / "open.stl").triangles.size() == 3 * 10);
}

TEST_CASE("malformed STL files give errors naming file and triangle or line", "[stl]") {
  TempDir dir;
  SECTION("missing file") {
    CHECK_THAT(message_of(dir / "nope.stl"), Catch::Contains("nope.stl: cannot open"));
  }
  SECTION("not a regular file") {
    // Issue 19: /dev/zero as an STL grew to 4 GB and aborted with bad_alloc.
    CHECK_THAT(message_of("/dev/zero"),
               Catch::Contains("/dev/zero: is a character device, not a regular file; expected "
                               "an STL file"));
    CHECK_THAT(message_of(dir.path), Catch::Contains("is a directory, not a regular file"));
  }
  SECTION("empty file") {
    write_text(dir / "empty.stl", "");
    CHECK_THAT(message_of(dir / "empty.stl"), Catch::Contains("empty.stl: is empty"));
  }
  SECTION("ASCII solid without triangles") {
    write_text(dir / "none.stl", "solid none\nendsolid none\n");
    CHECK_THAT(message_of(dir / "none.stl"), Catch::Contains("none.stl: has no triangles"));
  }
  SECTION("truncated ASCII") {
    std::string t = kTriangle;
    write_text(dir / "cut.stl", t.substr(0, t.find("endloop")));  // 7 lines, the last "  "
    CHECK_THAT(message_of(dir / "cut.stl"), Catch::Contains("cut.stl:7: ends inside a solid"));
  }
  SECTION("ASCII facet with two vertices") {
    std::string t = kTriangle;
    t.erase(t.find("   vertex 0 1 0\n"), 16);
    write_text(dir / "two_v.stl", t);
    CHECK_THAT(message_of(dir / "two_v.stl"),
               Catch::Contains("two_v.stl:6: facet 1 has 2 vertices, expected 3"));
  }
  SECTION("ASCII facet with four vertices") {
    std::string t = kTriangle;
    t.insert(t.find("  endloop"), "   vertex 1 1 0\n");
    write_text(dir / "four.stl", t);
    CHECK_THAT(message_of(dir / "four.stl"),
               Catch::Contains("four.stl:7: facet 1 has more than 3"));
  }
  SECTION("ASCII NaN and inf coordinates") {
    for (const char* bad : {"nan", "inf", "-inf"}) {
      // Built by concatenation (std::string::replace here trips a GCC 12 -Wrestrict false
      // positive).
      const std::string tri = kTriangle;
      const auto at = tri.find("vertex 1 0 0") + 7;
      write_text(dir / "nan.stl", tri.substr(0, at) + bad + tri.substr(at + 1));
      CHECK_THAT(message_of(dir / "nan.stl"),
                 Catch::Contains("nan.stl:5: triangle 1 has a non-finite vertex coordinate"));
    }
  }
  SECTION("ASCII garbage number") {
    std::string t = kTriangle;
    t.replace(t.find("vertex 1 0 0") + 7, 1, "1x");
    write_text(dir / "word.stl", t);
    CHECK_THAT(message_of(dir / "word.stl"), Catch::Contains("word.stl:5: '1x' is not a number"));
  }
  SECTION("zero-area triangle (collinear)") {
    TriangleMesh m = make_box_mesh({0, 0, 0}, {1, 1, 1}, false);
    // Triangle 3 (index 2) made collinear: its third corner moved onto its first edge.
    const int a = m.triangles[6], b = m.triangles[7];
    m.vertices.insert(m.vertices.end(), {0.5 * (m.vertices[3 * a] + m.vertices[3 * b]),
                                         0.5 * (m.vertices[3 * a + 1] + m.vertices[3 * b + 1]),
                                         0.5 * (m.vertices[3 * a + 2] + m.vertices[3 * b + 2])});
    m.triangles[8] = 8;
    write_stl_binary(dir / "flat.stl", m);
    CHECK_THAT(message_of(dir / "flat.stl"), Catch::Contains("flat.stl: triangle 3 has zero area"));
    write_stl_ascii(dir / "flat_a.stl", m);
    CHECK_THAT(message_of(dir / "flat_a.stl"), Catch::Contains("triangle 3 has zero area"));
  }
  SECTION("triangle that collapses when welded") {
    write_text(dir / "tiny.stl",
               "solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n"
               "vertex 0 1 0\nendloop\nendfacet\nfacet normal 0 0 1\nouter loop\nvertex 1 0 0\n"
               "vertex 1.001 0 0\nvertex 1 0.001 0\nendloop\nendfacet\nendsolid s\n");
    try {
      read_stl(dir / "tiny.stl", 0.01);
      FAIL("no error");
    } catch (const StlError& e) {
      CHECK_THAT(e.what(), Catch::Contains("tiny.stl:9: triangle 2 has zero area after welding"));
    }
  }
  SECTION("binary: truncated, wrong count, NaN") {
    const TriangleMesh box = make_box_mesh({0, 0, 0}, {1, 1, 1}, false);
    write_stl_binary(dir / "b.stl", box);
    const std::string bytes = read_bytes(dir / "b.stl");
    REQUIRE(bytes.size() == 84 + 50 * 12);
    write_text(dir / "trunc.stl", bytes.substr(0, bytes.size() - 30));
    CHECK_THAT(message_of(dir / "trunc.stl"),
               Catch::Contains("trunc.stl: binary STL header announces 12 triangles") &&
                   Catch::Contains("684 bytes, but the file has 654 bytes"));
    std::string wrong = bytes;
    const std::uint32_t n = 13;
    std::memcpy(wrong.data() + 80, &n, 4);
    write_text(dir / "count.stl", wrong);
    CHECK_THAT(message_of(dir / "count.stl"), Catch::Contains("announces 13 triangles"));
    std::string nan = bytes;
    const float q = std::numeric_limits<float>::quiet_NaN();
    std::memcpy(nan.data() + 84 + 50 * 4 + 12 + 4, &q, 4);  // triangle 5, first vertex, y
    write_text(dir / "nanb.stl", nan);
    CHECK_THAT(message_of(dir / "nanb.stl"),
               Catch::Contains("nanb.stl: triangle 5 has a non-finite vertex coordinate"));
    write_text(dir / "short.stl", bytes.substr(0, 40));
    CHECK_THAT(message_of(dir / "short.stl"), Catch::Contains("shorter than its 84-byte header"));
  }
}
