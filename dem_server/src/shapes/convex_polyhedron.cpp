#include "demfem/dem/shapes/convex_polyhedron.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

#include "qhull_hull.hpp"
#include "shape_util.hpp"

namespace demfem::dem::shapes {

using detail::format_number;
using detail::format_point;

double norm(const Vec3& a) {
  return std::sqrt(dot(a, a));
}

namespace {

// Relative tolerances, as fractions of the shape's extent (bounding-box diagonal). Qhull's
// own round-off bound for merging is ~1e-15 of the coordinates; 1e-9 leaves six orders of
// magnitude for triangulated merged facets and transformed copies, and is far below any
// geometric feature a DEM contact resolves.
constexpr double kFlatTolerance = 1e-9;
// A triangle whose area is below this fraction of its longest edge squared has no usable
// normal (the STL reader's test).
constexpr double kSliverTolerance = 1e-12;

double extent_of(std::span<const Vec3> points) {
  Vec3 lo = points[0], hi = points[0];
  for (const Vec3& p : points)
    for (std::size_t k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], p[k]);
      hi[k] = std::max(hi[k], p[k]);
    }
  return norm(hi - lo);
}

std::string vertex_label(std::int32_t i, const Vec3& p) {
  return "vertex " + std::to_string(i) + " " + format_point(p);
}

/// Directed edge -> triangle, as a sorted vector (deterministic, no hashing).
struct DirectedEdge {
  std::int32_t from, to, triangle;
  bool operator<(const DirectedEdge& o) const { return from != o.from ? from < o.from : to < o.to; }
};

}  // namespace

ConvexPolyhedron::ConvexPolyhedron() : vertices_{Vec3{0.0, 0.0, 0.0}}, fan_offsets_{0, 0} {}

ConvexPolyhedron ConvexPolyhedron::point(const Vec3& p) {
  for (double x : p)
    if (!std::isfinite(x)) throw ShapeError("point core: non-finite coordinate " + format_point(p));
  ConvexPolyhedron c;
  c.vertices_[0] = p;
  return c;
}

ConvexPolyhedron ConvexPolyhedron::hull(std::span<const Vec3> points, std::string_view source) {
  const std::string src(source);
  if (points.size() < 4) {
    throw ShapeError(src + ": a convex hull of non-zero volume needs at least 4 points, got " +
                     std::to_string(points.size()));
  }
  for (std::size_t i = 0; i < points.size(); ++i)
    for (double x : points[i])
      if (!std::isfinite(x)) {
        throw ShapeError(src + ": point " + std::to_string(i) + " has a non-finite coordinate " +
                         format_point(points[i]));
      }
  const double extent = extent_of(points);
  if (!(extent > 0)) {
    throw ShapeError(src + ": all " + std::to_string(points.size()) + " points coincide at " +
                     format_point(points[0]) + ": the hull has zero volume");
  }
  // Dimension check before Qhull, for a message in the user's terms: the thickness of the
  // point set across its principal directions (the eigenvectors of its covariance).
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const Vec3& p : points) mean += detail::to_eigen(p);
  mean /= double(points.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const Vec3& p : points) {
    const Eigen::Vector3d d = detail::to_eigen(p) - mean;
    cov += d * d.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  auto thickness = [&](int k) {
    const Eigen::Vector3d n = eig.eigenvectors().col(k);
    double lo = INFINITY, hi = -INFINITY;
    for (const Vec3& p : points) {
      const double s = n.dot(detail::to_eigen(p));
      lo = std::min(lo, s);
      hi = std::max(hi, s);
    }
    return hi - lo;
  };
  const double tol = kFlatTolerance * extent;
  if (thickness(1) <= tol) {
    throw ShapeError(src + ": all " + std::to_string(points.size()) +
                     " points are collinear (within " + format_number(tol) + " of the line along " +
                     format_point(detail::vec_from_eigen(eig.eigenvectors().col(2))) +
                     "): the hull has zero volume");
  }
  if (const double t = thickness(0); t <= tol) {
    throw ShapeError(src + ": all " + std::to_string(points.size()) +
                     " points are coplanar (they span " + format_number(t) +
                     " across the plane with normal " +
                     format_point(detail::vec_from_eigen(eig.eigenvectors().col(0))) + ", extent " +
                     format_number(extent) + "): the hull has zero volume");
  }
  detail::RawHull raw = detail::qhull_triangulated(points, source);
  return checked(std::move(raw.vertices), std::move(raw.triangles), source, ConvexCheck::climb);
}

ConvexPolyhedron ConvexPolyhedron::from_triangles(std::vector<Vec3> vertices,
                                                  std::vector<Triangle> triangles,
                                                  std::string_view source) {
  return checked(std::move(vertices), std::move(triangles), source, ConvexCheck::every_vertex);
}

ConvexPolyhedron ConvexPolyhedron::checked(std::vector<Vec3> vertices,
                                           std::vector<Triangle> triangles, std::string_view source,
                                           ConvexCheck check) {
  const std::string src(source);
  if (vertices.size() < 4 || triangles.size() < 4) {
    throw ShapeError(src + ": a closed polyhedron needs at least 4 vertices and 4 triangles, got " +
                     std::to_string(vertices.size()) + " and " + std::to_string(triangles.size()));
  }
  for (std::size_t i = 0; i < vertices.size(); ++i)
    for (double x : vertices[i])
      if (!std::isfinite(x)) {
        throw ShapeError(src + ": " + vertex_label(std::int32_t(i), vertices[i]) +
                         " has a non-finite coordinate");
      }
  ConvexPolyhedron c;
  c.vertices_ = std::move(vertices);
  c.triangles_ = std::move(triangles);
  c.build_topology(source);
  c.check_convex(source, check);
  return c;
}

void ConvexPolyhedron::build_topology(std::string_view source) {
  const std::string src(source);
  const auto nv = static_cast<std::int32_t>(vertices_.size());
  const std::size_t nt = triangles_.size();
  normals_.resize(nt);
  std::vector<std::int32_t> degree(vertices_.size(), 0);
  std::vector<DirectedEdge> directed;
  directed.reserve(3 * nt);
  for (std::size_t t = 0; t < nt; ++t) {
    const Triangle& tri = triangles_[t];
    for (std::int32_t i : tri)
      if (i < 0 || i >= nv) {
        throw ShapeError(src + ": triangle " + std::to_string(t) + " refers to vertex " +
                         std::to_string(i) + " of " + std::to_string(nv));
      }
    if (tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2]) {
      throw ShapeError(src + ": triangle " + std::to_string(t) + " repeats a vertex");
    }
    const Vec3& a = vertices_[std::size_t(tri[0])];
    const Vec3& b = vertices_[std::size_t(tri[1])];
    const Vec3& cc = vertices_[std::size_t(tri[2])];
    const Vec3 n = cross(b - a, cc - a);
    const double longest = std::max({norm(b - a), norm(cc - b), norm(a - cc)});
    const double len = norm(n);
    if (!(len > kSliverTolerance * longest * longest)) {
      throw ShapeError(src + ": triangle " + std::to_string(t) + " " + format_point(a) + " " +
                       format_point(b) + " " + format_point(cc) + " has zero area");
    }
    normals_[t] = (1.0 / len) * n;
    for (int k = 0; k < 3; ++k) {
      ++degree[std::size_t(tri[std::size_t(k)])];
      directed.push_back({tri[std::size_t(k)], tri[std::size_t((k + 1) % 3)], std::int32_t(t)});
    }
  }
  std::sort(directed.begin(), directed.end());
  for (std::size_t i = 1; i < directed.size(); ++i) {
    if (directed[i].from == directed[i - 1].from && directed[i].to == directed[i - 1].to) {
      throw ShapeError(
          src + ": the edge from " +
          vertex_label(directed[i].from, vertices_[std::size_t(directed[i].from)]) + " to " +
          vertex_label(directed[i].to, vertices_[std::size_t(directed[i].to)]) +
          " runs the same way in triangles " + std::to_string(directed[i - 1].triangle) + " and " +
          std::to_string(directed[i].triangle) +
          ": the triangles are inconsistently oriented or the surface is not a "
          "manifold");
    }
  }
  auto find = [&](std::int32_t from, std::int32_t to) -> std::int32_t {
    const DirectedEdge key{from, to, 0};
    const auto it = std::lower_bound(directed.begin(), directed.end(), key);
    return (it != directed.end() && it->from == from && it->to == to) ? it->triangle : -1;
  };
  edges_.clear();
  for (const DirectedEdge& e : directed) {
    const std::int32_t back = find(e.to, e.from);
    if (back < 0) {
      throw ShapeError(src + ": the edge between " +
                       vertex_label(e.from, vertices_[std::size_t(e.from)]) + " and " +
                       vertex_label(e.to, vertices_[std::size_t(e.to)]) + " belongs to triangle " +
                       std::to_string(e.triangle) +
                       " only (or both its triangles run it the same way): the surface is not "
                       "closed and consistently oriented");
    }
    if (e.from < e.to) {
      const Vec3& n1 = normals_[std::size_t(e.triangle)];
      const Vec3& n2 = normals_[std::size_t(back)];
      edges_.push_back(
          {e.from, e.to, e.triangle, back, std::atan2(norm(cross(n1, n2)), dot(n1, n2))});
    }
  }
  for (std::int32_t v = 0; v < nv; ++v)
    if (degree[std::size_t(v)] == 0) {
      throw ShapeError(src + ": " + vertex_label(v, vertices_[std::size_t(v)]) +
                       " is in no triangle");
    }
  // Fans: around v, triangle (v, p, q) is followed by the triangle that holds v -> q.
  fan_offsets_.assign(vertices_.size() + 1, 0);
  for (std::size_t v = 0; v < vertices_.size(); ++v)
    fan_offsets_[v + 1] = fan_offsets_[v] + degree[v];
  fan_neighbours_.assign(std::size_t(fan_offsets_.back()), -1);
  fan_triangles_.assign(std::size_t(fan_offsets_.back()), -1);
  std::vector<std::int32_t> first_triangle(vertices_.size(), -1);
  for (std::size_t t = 0; t < nt; ++t)
    for (std::int32_t i : triangles_[t])
      if (first_triangle[std::size_t(i)] < 0) first_triangle[std::size_t(i)] = std::int32_t(t);
  for (std::int32_t v = 0; v < nv; ++v) {
    const std::int32_t begin = fan_offsets_[std::size_t(v)];
    const std::int32_t count = degree[std::size_t(v)];
    std::int32_t t = first_triangle[std::size_t(v)];
    for (std::int32_t k = 0; k < count; ++k) {
      const Triangle& tri = triangles_[std::size_t(t)];
      const auto pos = std::size_t(std::find(tri.begin(), tri.end(), v) - tri.begin());
      const std::int32_t p = tri[(pos + 1) % 3], q = tri[(pos + 2) % 3];
      fan_neighbours_[std::size_t(begin + k)] = p;
      fan_triangles_[std::size_t(begin + k)] = t;
      t = find(v, q);
      if (k + 1 < count && t == first_triangle[std::size_t(v)]) {
        throw ShapeError(src + ": " + vertex_label(v, vertices_[std::size_t(v)]) +
                         " joins more than one fan of triangles: the surface is not a manifold");
      }
    }
    if (t != first_triangle[std::size_t(v)]) {
      throw ShapeError(src + ": the triangles around " +
                       vertex_label(v, vertices_[std::size_t(v)]) +
                       " do not close into one fan: the surface is not a manifold");
    }
  }
  const auto euler =
      std::int64_t(vertices_.size()) - std::int64_t(edges_.size()) + std::int64_t(nt);
  if (euler != 2) {
    throw ShapeError(src + ": V - E + F = " + std::to_string(vertices_.size()) + " - " +
                     std::to_string(edges_.size()) + " + " + std::to_string(nt) + " = " +
                     std::to_string(euler) +
                     ", a convex polyhedron has 2 (the surface has handles or several parts)");
  }
}

void ConvexPolyhedron::check_convex(std::string_view source, ConvexCheck check) const {
  const std::string src(source);
  const double extent = extent_of(vertices_);
  const double tol = kFlatTolerance * extent;
  // Signed volume (divergence theorem): positive for outward triangles.
  double six_volume = 0.0;
  const Vec3& o = vertices_[0];
  for (const Triangle& t : triangles_) {
    six_volume += dot(vertices_[std::size_t(t[0])] - o,
                      cross(vertices_[std::size_t(t[1])] - o, vertices_[std::size_t(t[2])] - o));
  }
  const double volume = six_volume / 6.0;
  if (!(volume > kFlatTolerance * extent * extent * extent)) {
    throw ShapeError(
        src + ": the polyhedron has " +
        (volume < 0 ? "negative volume " + format_number(volume) + " (its triangles face inwards)"
                    : "zero volume (" + format_number(volume) + " for extent " +
                          format_number(extent) + ")"));
  }
  if (check == ConvexCheck::climb) {
    // Steepest ascent along each normal from the triangle's first vertex (on a convex body
    // already the highest: one look at its neighbours). No vertex above any plane: done; one
    // found: the full scan below names the first offending pair as for any input.
    bool above = false;
    for (std::size_t t = 0; t < triangles_.size() && !above; ++t) {
      const Vec3& a = vertices_[std::size_t(triangles_[t][0])];
      std::int32_t v = triangles_[t][0];
      double h = 0.0;
      for (bool moved = true; moved;) {
        moved = false;
        for (const std::int32_t w : neighbours(std::size_t(v))) {
          const double hw = dot(normals_[t], vertices_[std::size_t(w)] - a);
          if (hw > h) {
            h = hw;
            v = w;
            moved = true;
          }
        }
      }
      above = h > tol;
    }
    if (!above) return;
  }
  for (std::size_t t = 0; t < triangles_.size(); ++t) {
    const Vec3& a = vertices_[std::size_t(triangles_[t][0])];
    for (std::size_t v = 0; v < vertices_.size(); ++v) {
      const double h = dot(normals_[t], vertices_[v] - a);
      if (h > tol) {
        throw ShapeError(src + ": not convex: " + vertex_label(std::int32_t(v), vertices_[v]) +
                         " lies " + format_number(h) + " above the plane of triangle " +
                         std::to_string(t) + " (tolerance " + format_number(tol) + ")");
      }
    }
  }
}

std::span<const std::int32_t> ConvexPolyhedron::neighbours(std::size_t v) const {
  const auto b = std::size_t(fan_offsets_[v]), e = std::size_t(fan_offsets_[v + 1]);
  return {fan_neighbours_.data() + b, e - b};
}

std::span<const std::int32_t> ConvexPolyhedron::vertex_triangles(std::size_t v) const {
  const auto b = std::size_t(fan_offsets_[v]), e = std::size_t(fan_offsets_[v + 1]);
  return {fan_triangles_.data() + b, e - b};
}

std::int32_t ConvexPolyhedron::support_index(const Vec3& d) const {
  std::int32_t best = 0;
  double best_h = dot(vertices_[0], d);
  for (std::size_t i = 1; i < vertices_.size(); ++i) {
    const double h = dot(vertices_[i], d);
    if (h > best_h) {
      best_h = h;
      best = std::int32_t(i);
    }
  }
  return best;
}

double ConvexPolyhedron::width(const Vec3& d) const {
  double lo = dot(vertices_[0], d), hi = lo;
  for (const Vec3& v : vertices_) {
    const double h = dot(v, d);
    lo = std::min(lo, h);
    hi = std::max(hi, h);
  }
  return hi - lo;
}

double ConvexPolyhedron::radius_about(const Vec3& centre) const {
  double r = 0.0;
  for (const Vec3& v : vertices_) r = std::max(r, norm(v - centre));
  return r;
}

ConvexPolyhedron ConvexPolyhedron::transformed(const Mat3& a, const Vec3& t) const {
  const double det = detail::to_eigen(a).determinant();
  if (!(det > 0) || !std::isfinite(det)) {
    throw ShapeError("ConvexPolyhedron::transformed: the linear map has determinant " +
                     format_number(det) + "; it must be > 0 (no reflection, no collapse)");
  }
  std::vector<Vec3> v(vertices_.size());
  for (std::size_t i = 0; i < v.size(); ++i) {
    const Vec3& x = vertices_[i];
    for (std::size_t r = 0; r < 3; ++r) v[i][r] = dot(a[r], x) + t[r];
  }
  if (is_point()) return point(v[0]);
  return checked(std::move(v), triangles_, "transformed polyhedron", ConvexCheck::climb);
}

ConvexPolyhedron ConvexPolyhedron::scaled(double s) const {
  if (!(s > 0) || !std::isfinite(s)) {
    throw ShapeError("ConvexPolyhedron::scaled: factor " + format_number(s) + " must be > 0");
  }
  return transformed(Mat3{Vec3{s, 0, 0}, Vec3{0, s, 0}, Vec3{0, 0, s}}, {0, 0, 0});
}

ConvexPolyhedron ConvexPolyhedron::translated(const Vec3& t) const {
  return transformed(Mat3{Vec3{1, 0, 0}, Vec3{0, 1, 0}, Vec3{0, 0, 1}}, t);
}

namespace {
void require_positive(std::string_view what, std::initializer_list<double> values) {
  for (double x : values)
    if (!(x > 0) || !std::isfinite(x)) {
      throw ShapeError(std::string(what) + ": dimensions must be finite and > 0, got " +
                       format_number(x));
    }
}
}  // namespace

ConvexPolyhedron make_box(double a, double b, double c) {
  require_positive("box", {a, b, c});
  std::vector<Vec3> p;
  for (int i = 0; i < 8; ++i) {
    p.push_back({(i & 1 ? 0.5 : -0.5) * a, (i & 2 ? 0.5 : -0.5) * b, (i & 4 ? 0.5 : -0.5) * c});
  }
  return ConvexPolyhedron::hull(
      p, "box " + format_number(a) + " x " + format_number(b) + " x " + format_number(c));
}

ConvexPolyhedron make_regular_tetrahedron(double a) {
  require_positive("regular tetrahedron", {a});
  // (1,1,1), (1,-1,-1), (-1,1,-1), (-1,-1,1): edge 2 sqrt(2).
  const double s = a / (2.0 * std::sqrt(2.0));
  const std::vector<Vec3> p{{s, s, s}, {s, -s, -s}, {-s, s, -s}, {-s, -s, s}};
  return ConvexPolyhedron::hull(p, "regular tetrahedron of edge " + format_number(a));
}

ConvexPolyhedron make_octahedron(double r) {
  require_positive("octahedron", {r});
  const std::vector<Vec3> p{{r, 0, 0}, {-r, 0, 0}, {0, r, 0}, {0, -r, 0}, {0, 0, r}, {0, 0, -r}};
  return ConvexPolyhedron::hull(p, "octahedron of radius " + format_number(r));
}

ConvexPolyhedron make_triangular_prism(double a, double h) {
  require_positive("triangular prism", {a, h});
  const double rc = a / std::sqrt(3.0);  // circumradius of the equilateral triangle
  std::vector<Vec3> p;
  for (int k = 0; k < 3; ++k) {
    const double phi = 2.0 * std::numbers::pi * k / 3.0;
    for (double z : {-0.5 * h, 0.5 * h}) p.push_back({rc * std::cos(phi), rc * std::sin(phi), z});
  }
  return ConvexPolyhedron::hull(
      p, "triangular prism of edge " + format_number(a) + " and height " + format_number(h));
}

}  // namespace demfem::dem::shapes
