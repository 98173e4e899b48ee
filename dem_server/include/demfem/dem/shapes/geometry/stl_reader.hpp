#pragma once
// STL geometry for rigid walls and scanned rocks: reading (ASCII and binary) into a welded
// TriangleMesh, writing (for tests and generated geometry), and generated boxes and planes.

#include <array>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include "demfem/dem/shapes/geometry/triangle_mesh.hpp"

namespace demfem::dem {

/// @brief Malformed or unreadable STL; what() names the file and the triangle or line.
class StlError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// @brief Reads an ASCII or binary STL file into a TriangleMesh (name = file stem). Binary is
/// recognised by its size (84 + 50 n bytes for the n triangles its header announces), not by
/// the "solid" prefix, which binary exporters also write. Vertices closer
/// than `weld_tolerance` (m) are merged so neighbouring triangles share vertices;
/// a negative tolerance means 1e-9 times the bounding-box diagonal. Throws StlError for an
/// empty, truncated or inconsistent file, non-finite coordinates, and triangles of zero area
/// (before or after welding).
TriangleMesh read_stl(const std::filesystem::path& file, double weld_tolerance = -1.0);

/// @brief Writes a mesh as ASCII STL ("solid <name>", one facet per triangle, normals by the
/// right-hand rule).
void write_stl_ascii(const std::filesystem::path& file, const TriangleMesh& mesh);
/// @brief Writes a mesh as binary STL.
void write_stl_binary(const std::filesystem::path& file, const TriangleMesh& mesh);

/// @brief The 12 triangles of the box [lo, hi], normals pointing into the box (particles are
/// inside). `open_top` leaves out the two triangles of the face z = hi[2].
TriangleMesh make_box_mesh(const std::array<double, 3>& lo, const std::array<double, 3>& hi,
                           bool open_top);

/// @brief A square of side `size` centred on `point`, normal `normal` (towards the particles),
/// as two triangles.
TriangleMesh make_plane_mesh(const std::array<double, 3>& point,
                             const std::array<double, 3>& normal, double size);

/// @brief Total area of a triangle mesh given as vertex coordinates and triangles, m^2.
double mesh_area(const std::vector<double>& vertices, const std::vector<std::int32_t>& triangles);

}  // namespace demfem::dem
