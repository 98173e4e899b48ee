#pragma once
// The coupled surface as both solvers see it. The FEM side owns it (the exterior surface of
// a volume mesh, or the two offset surfaces of a shell), the coupler hands it to the DEM.
// Node i of this mesh is the same material point in both solvers for the whole run.
//
// Conventions (SI): positions in m, velocities in m/s, accelerations in m/s^2, forces in N.
// Arrays are node-major xyz: entry 3*i+k is component k of node i. Forces are the forces
// that the particles exert ON the structure at each node (barycentric split of each contact
// force onto the triangle's three nodes), in the global frame.

#include <cstddef>
#include <cstdint>
#include <vector>

namespace demfem {

/// @brief Triangulated coupled surface: reference node positions and triangles.
struct InterfaceMesh {
  std::vector<double> reference_positions;  ///< 3 * node_count, m
  std::vector<std::int32_t> triangles;      ///< 3 * triangle_count, node indices, outward normal
                                            ///< by the right-hand rule (normal points into
                                            ///< the region where particles are)
  std::size_t node_count() const { return reference_positions.size() / 3; }
  std::size_t triangle_count() const { return triangles.size() / 3; }
};

/// @brief Node kinematics of the coupled surface at one instant.
struct InterfaceKinematics {
  std::vector<double> positions;      ///< 3n, current positions, m
  std::vector<double> velocities;     ///< 3n, m/s
  std::vector<double> accelerations;  ///< 3n, m/s^2
  void resize(std::size_t nodes) {
    positions.assign(3 * nodes, 0.0);
    velocities.assign(3 * nodes, 0.0);
    accelerations.assign(3 * nodes, 0.0);
  }
};

/// @brief How the DEM reports interface forces over the n^D substeps of a coupling step.
enum class ForceMode : std::uint8_t {
  last_substep = 0,  ///< force of the last substep (Algorithm 3, eq. 3.3)
  average = 1,       ///< mean over the substeps (force averaging, eq. 3.8)
};

}  // namespace demfem
