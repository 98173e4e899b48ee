#pragma once
// Structured meshes for tests, benchmarks and simple scenes: boxes of hexahedra or
// tetrahedra and flat rectangular plates of shell quads, with named node sets and surfaces.

#include <array>

#include "demfem/fem/fem_problem.hpp"

namespace demfem::fem {

/// @brief Box [lo, hi] split into counts[0] x counts[1] x counts[2] hex8 elements.
/// Node sets and surfaces "xmin", "xmax", "ymin", "ymax", "zmin", "zmax" (the six faces);
/// node set and element set "all". All elements use section 0. Throws std::invalid_argument
/// for counts < 1 or hi <= lo.
Mesh box_mesh_hex(std::array<double, 3> lo, std::array<double, 3> hi, std::array<int, 3> counts);

/// @brief As box_mesh_hex but each hex is split into 6 tet4 (Kuhn split along the main
/// diagonal, identical in every cell so the mesh is conforming); same sets and surfaces.
Mesh box_mesh_tet(std::array<double, 3> lo, std::array<double, 3> hi, std::array<int, 3> counts);

/// @brief Flat plate in the plane z = origin[2] from origin to origin + (size_x, size_y, 0),
/// counts[0] x counts[1] quad4 shell elements, normal +z. Edge node sets "xmin", "xmax",
/// "ymin", "ymax"; node set and element set "all"; surfaces "top" (+z side) and "bottom".
Mesh plate_mesh_quad(std::array<double, 3> origin, double size_x, double size_y,
                     std::array<int, 2> counts);

}  // namespace demfem::fem
