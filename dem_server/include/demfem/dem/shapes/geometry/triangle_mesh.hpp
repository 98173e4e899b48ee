#pragma once
// A triangle surface as the geometry base hands it on: what an STL file holds, a generated
// box or plane, the input of a hull. What the engine adds to make it a wall (material, motion,
// rigid body) lives with the engine (WallMesh, dem_system.hpp), which builds on this.

#include <cstdint>
#include <string>
#include <vector>

namespace demfem::dem {

/// @brief Vertices and triangles of a surface, node-major as the engine's walls hold them.
struct TriangleMesh {
  std::string name;
  std::vector<double> vertices;         ///< 3 per vertex, m
  std::vector<std::int32_t> triangles;  ///< 3 vertex indices per triangle
};

}  // namespace demfem::dem
