#pragma once
// Mass properties of a closed triangle mesh of uniform density (a rigid mesh body: pressure
// cell, rigid sleeper, plate), for RigidBodySpec. Any closed mesh, convex or not, with its
// triangles consistently oriented (outwards or inwards: the sign of the volume tells).

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace demfem::dem::shapes {

struct MeshBodyProperties {
  double volume = 0.0;                            ///< m³
  double mass = 0.0;                              ///< kg
  std::array<double, 3> centre{};                 ///< centre of mass, m
  std::array<double, 3> moments{};                ///< principal moments about the centre, kg m²
  std::array<double, 4> orientation{1, 0, 0, 0};  ///< principal frame to world (w, x, y, z)
};

/// Exact by tetrahedra from a point near the mesh (divergence theorem). Throws
/// std::invalid_argument naming `name` when the mesh is not closed (an edge not shared by
/// exactly two triangles), inconsistently oriented or of zero volume, or density <= 0.
MeshBodyProperties closed_mesh_properties(const std::vector<double>& vertices,
                                          const std::vector<std::int32_t>& triangles,
                                          double density, const std::string& name);

}  // namespace demfem::dem::shapes
