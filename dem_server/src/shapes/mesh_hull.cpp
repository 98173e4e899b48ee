#include "demfem/dem/shapes/mesh_hull.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include "demfem/dem/shapes/geometry/stl_reader.hpp"
#include "demfem/dem/shapes/mass_properties.hpp"
#include "shape_util.hpp"

namespace demfem::dem::shapes {

using detail::format_number;
using detail::format_point;

MeshHull hull_of_closed_mesh(std::span<const double> vertices,
                             std::span<const std::int32_t> triangles, std::string_view source) {
  const std::string src(source);
  if (vertices.size() % 3 != 0 || triangles.size() % 3 != 0) {
    throw ShapeError(src + ": vertex and triangle arrays must hold 3 entries per item");
  }
  const std::size_t nv = vertices.size() / 3, nt = triangles.size() / 3;
  if (nt < 4) {
    throw ShapeError(src + ": " + std::to_string(nt) +
                     " triangles cannot close a volume (at least 4 are needed)");
  }
  auto point = [&](std::int32_t i) {
    return Vec3{vertices[3 * std::size_t(i)], vertices[3 * std::size_t(i) + 1],
                vertices[3 * std::size_t(i) + 2]};
  };
  // Undirected edges with their use count and orientation balance (+1 for a -> b, a < b).
  struct EdgeUse {
    std::int32_t a, b;
    int direction;
    bool operator<(const EdgeUse& o) const { return a != o.a ? a < o.a : b < o.b; }
  };
  std::vector<EdgeUse> uses;
  uses.reserve(3 * nt);
  for (std::size_t t = 0; t < nt; ++t)
    for (std::size_t c = 0; c < 3; ++c) {
      const std::int32_t p = triangles[3 * t + c], q = triangles[3 * t + (c + 1) % 3];
      if (p < 0 || q < 0 || std::size_t(p) >= nv || std::size_t(q) >= nv) {
        throw ShapeError(src + ": triangle " + std::to_string(t + 1) + " refers to vertex " +
                         std::to_string(std::max(p, q)) + " of " + std::to_string(nv));
      }
      uses.push_back({std::min(p, q), std::max(p, q), p < q ? 1 : -1});
    }
  std::sort(uses.begin(), uses.end());
  bool oriented = true;
  for (std::size_t i = 0; i < uses.size();) {
    std::size_t j = i;
    int balance = 0;
    while (j < uses.size() && uses[j].a == uses[i].a && uses[j].b == uses[i].b)
      balance += uses[j++].direction;
    const std::size_t count = j - i;
    if (count != 2) {
      throw ShapeError(src + ": the mesh is not closed: the edge " +
                       format_point(point(uses[i].a)) + " - " + format_point(point(uses[i].b)) +
                       " belongs to " + std::to_string(count) +
                       " triangle(s); every edge of a closed surface belongs to exactly 2 "
                       "(after welding vertices closer than 1e-9 of the model size)");
    }
    if (balance != 0) oriented = false;
    i = j;
  }
  std::vector<Vec3> pts(nv);
  for (std::size_t i = 0; i < nv; ++i) pts[i] = point(std::int32_t(i));
  MeshHull out{ConvexPolyhedron::hull(pts, source), 0.0, 0.0, {}};
  out.hull_volume = core_mass_properties(out.core).volume;
  if (!oriented) {
    out.warning = src +
                  ": the triangles are not consistently oriented, so the mesh volume "
                  "is unknown; the particle is the convex hull of its vertices";
    return out;
  }
  double six_v = 0.0;
  const Vec3 o = pts[0];
  for (std::size_t t = 0; t < nt; ++t) {
    six_v += dot(point(triangles[3 * t]) - o,
                 cross(point(triangles[3 * t + 1]) - o, point(triangles[3 * t + 2]) - o));
  }
  out.mesh_volume = std::abs(six_v) / 6.0;
  const double ratio = out.hull_volume / out.mesh_volume;
  if (ratio > 1.0 + 1e-6) {
    out.warning = src + ": the mesh is not convex: its convex hull (the particle) has " +
                  format_number(ratio) + " times its volume (" + format_number(out.hull_volume) +
                  " vs " + format_number(out.mesh_volume) + " m^3)";
  }
  return out;
}

MeshHull hull_of_stl(const std::filesystem::path& file) {
  const TriangleMesh mesh = read_stl(file);
  return hull_of_closed_mesh(mesh.vertices, mesh.triangles, file.string());
}

}  // namespace demfem::dem::shapes
