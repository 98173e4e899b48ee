#pragma once
// The convex core of a dilated polyhedron: vertices in the body frame and closed, outward,
// consistently oriented triangles. Every instance is validated on construction (closed,
// convex, non-degenerate), so consumers (mass properties, the narrow phase, output) never
// re-check. The single-point core (1 vertex, 0 triangles) is a valid instance: dilated, it
// is a sphere.

#include <array>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace demfem::dem::shapes {

using Vec3 = std::array<double, 3>;
/// Row-major 3x3 matrix: m[row][col].
using Mat3 = std::array<Vec3, 3>;
/// Vertex indices, counter-clockwise seen from outside (right-hand rule gives the outward
/// normal).
using Triangle = std::array<std::int32_t, 3>;

/// @brief Bad shape input (coplanar or collinear points, zero volume, open or non-convex
/// mesh, inconsistent parameters). what() names the input (file, generator and seed, or the
/// caller's label) and the reason.
class ShapeError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// @brief An edge of the triangulation: a < b; `left` is the triangle that holds the directed
/// edge a -> b, `right` the one that holds b -> a; `angle` is the exterior dihedral angle
/// (between the two outward normals, rad): 0 up to round-off for an edge inside a facet that
/// Qhull merged from coplanar ones and then triangulated.
struct Edge {
  std::int32_t a, b;
  std::int32_t left, right;
  double angle;
};

/// @brief A convex polyhedron (or a single point), validated.
class ConvexPolyhedron {
 public:
  /// The point core at the origin.
  ConvexPolyhedron();

  /// A single point (1 vertex, no triangles, no edges): the core of a sphere.
  static ConvexPolyhedron point(const Vec3& p = {0.0, 0.0, 0.0});

  /// The convex hull of `points`, computed by Qhull (options "Qt": coplanar facets are
  /// merged within Qhull's round-off bound, then triangulated). Points that are not extreme
  /// are dropped. Throws ShapeError naming `source` for fewer than 4 points, non-finite
  /// coordinates, coincident, collinear or coplanar points (all within 1e-9 of the point
  /// set's extent of a line or plane), or a hull of zero volume.
  static ConvexPolyhedron hull(std::span<const Vec3> points, std::string_view source);

  /// A given triangulation, checked: every vertex used, no zero-area triangle, every edge in
  /// exactly two triangles with opposite directions (closed and consistently oriented),
  /// each vertex a single fan (manifold), V - E + F = 2, outward orientation (positive
  /// volume) and convexity (no vertex above any triangle's plane by more than 1e-9 of the
  /// size). Throws ShapeError naming `source` and the offending triangle, edge or vertex.
  static ConvexPolyhedron from_triangles(std::vector<Vec3> vertices,
                                         std::vector<Triangle> triangles, std::string_view source);

  bool is_point() const { return triangles_.empty(); }
  const std::vector<Vec3>& vertices() const { return vertices_; }
  const std::vector<Triangle>& triangles() const { return triangles_; }
  /// Unit outward normal of each triangle.
  const std::vector<Vec3>& normals() const { return normals_; }
  /// Each edge once, sorted by (a, b).
  const std::vector<Edge>& edges() const { return edges_; }
  /// The vertices adjacent to vertex v, counter-clockwise around v seen from outside.
  std::span<const std::int32_t> neighbours(std::size_t v) const;
  /// The triangles around vertex v, in the same order: triangle k of the fan holds
  /// neighbours k and k+1 (cyclically).
  std::span<const std::int32_t> vertex_triangles(std::size_t v) const;

  /// The vertex farthest along d (the lowest index among ties); a linear scan.
  std::int32_t support_index(const Vec3& d) const;
  Vec3 support(const Vec3& d) const { return vertices_[std::size_t(support_index(d))]; }
  /// max_v (v . d) - min_v (v . d): the width along the unit direction d.
  double width(const Vec3& d) const;
  /// The largest distance of a vertex from `centre`.
  double radius_about(const Vec3& centre) const;

  /// x -> a x + t. `a` must have a positive determinant (a rotation, a scaling, a shear):
  /// then the image is convex with the same triangulation and orientation. Re-validated.
  ConvexPolyhedron transformed(const Mat3& a, const Vec3& t) const;
  /// x -> s x (s > 0).
  ConvexPolyhedron scaled(double s) const;
  /// x -> x + t.
  ConvexPolyhedron translated(const Vec3& t) const;

 private:
  /// How from_triangles checks convexity: every vertex against every triangle's plane
  /// (O(V F), any input), or each plane against the vertex its normal climbs to on the vertex
  /// graph (O(F sqrt V) on a fine mesh; exact where the triangulation is already known to be
  /// convex: Qhull's hull, a positive linear image of a checked polyhedron).
  enum class ConvexCheck { every_vertex, climb };
  static ConvexPolyhedron checked(std::vector<Vec3> vertices, std::vector<Triangle> triangles,
                                  std::string_view source, ConvexCheck check);
  void build_topology(std::string_view source);
  void check_convex(std::string_view source, ConvexCheck check) const;

  std::vector<Vec3> vertices_;
  std::vector<Triangle> triangles_;
  std::vector<Vec3> normals_;
  std::vector<Edge> edges_;
  std::vector<std::int32_t> fan_offsets_;  // size V + 1 (CSR)
  std::vector<std::int32_t> fan_neighbours_;
  std::vector<std::int32_t> fan_triangles_;
};

/// @name Simple solids (validated), for tests and as reference shapes.
/// @{
/// The box [-a/2, a/2] x [-b/2, b/2] x [-c/2, c/2] (12 triangles).
ConvexPolyhedron make_box(double a, double b, double c);
/// A cube of edge a centred at the origin.
inline ConvexPolyhedron make_cube(double a) {
  return make_box(a, a, a);
}
/// A regular tetrahedron of edge a, centroid at the origin (4 triangles): the vertices
/// (±1, ±1, ±1) with an even number of minus signs, scaled.
ConvexPolyhedron make_regular_tetrahedron(double a);
/// A regular octahedron with vertices at distance r on the axes (8 triangles).
ConvexPolyhedron make_octahedron(double r);
/// A right prism over the equilateral triangle of edge a (in the xy plane, centroid on the
/// z axis), height h along z, centred at the origin (8 triangles).
ConvexPolyhedron make_triangular_prism(double a, double h);
/// @}

/// @name Small vector helpers shared by the shape files.
/// @{
inline Vec3 operator+(const Vec3& a, const Vec3& b) {
  return {a[0] + b[0], a[1] + b[1], a[2] + b[2]};
}
inline Vec3 operator-(const Vec3& a, const Vec3& b) {
  return {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
}
inline Vec3 operator*(double s, const Vec3& a) {
  return {s * a[0], s * a[1], s * a[2]};
}
inline double dot(const Vec3& a, const Vec3& b) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
inline Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
double norm(const Vec3& a);
/// @}

}  // namespace demfem::dem::shapes
