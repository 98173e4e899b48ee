#pragma once
// The one place that talks to Qhull (reentrant libqhull_r).

#include <span>
#include <string_view>
#include <vector>

#include "demfem/dem/shapes/convex_polyhedron.hpp"

namespace demfem::dem::shapes::detail {

struct RawHull {
  std::vector<Vec3> vertices;             ///< the hull's vertices, in input order
  std::vector<Triangle> triangles;        ///< outward, counter-clockwise seen from outside
  std::vector<std::int32_t> input_index;  ///< input point of each vertex
};

/// Triangulated convex hull ("qhull Qt"). Throws ShapeError naming `source` with Qhull's
/// first message line when Qhull fails.
RawHull qhull_triangulated(std::span<const Vec3> points, std::string_view source);

}  // namespace demfem::dem::shapes::detail
