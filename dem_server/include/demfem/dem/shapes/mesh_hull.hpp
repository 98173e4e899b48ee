#pragma once
// The convex core of a scanned rock: the convex hull of a closed triangle mesh (an STL).
//
// The mesh must be closed: after welding (read_stl merges vertices closer than 1e-9 of the
// bounding-box diagonal) every edge belongs to exactly two triangles. An open or
// non-manifold mesh is refused, naming the source and an offending edge. The mesh need not
// be convex: its hull is taken, and when the hull is larger than the mesh by more than
// 1e-6 (relative volume) the result carries a warning with the ratio, since the particle
// then differs from the scan (a concave rock becomes its convex hull).

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>

#include "demfem/dem/shapes/convex_polyhedron.hpp"

namespace demfem::dem::shapes {

/// @brief A hull and how it compares with the mesh it came from.
struct MeshHull {
  ConvexPolyhedron core;
  double mesh_volume = 0.0;  ///< m^3, |signed volume| (0 when the orientation is inconsistent)
  double hull_volume = 0.0;  ///< m^3
  /// Empty, or why the particle differs from the mesh (concave mesh: the hull/mesh volume
  /// ratio; inconsistently oriented triangles: the ratio is unknown).
  std::string warning;
};

/// `vertices`: 3 per vertex (m); `triangles`: 3 vertex indices per triangle (a WallMesh's
/// arrays). Throws ShapeError naming `source` for an open or non-manifold mesh, and for the
/// degenerate hulls of ConvexPolyhedron::hull.
MeshHull hull_of_closed_mesh(std::span<const double> vertices,
                             std::span<const std::int32_t> triangles, std::string_view source);

/// read_stl(file) (geometry/stl_reader.hpp) then hull_of_closed_mesh. StlError for an
/// unreadable file.
MeshHull hull_of_stl(const std::filesystem::path& file);

}  // namespace demfem::dem::shapes
