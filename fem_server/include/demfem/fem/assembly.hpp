#pragma once
// Assembly of the FEM system from a FemProblem: DOF numbering, global stiffness and mass,
// load vectors, constraint reduction and the coupled interface surface. FemSolver is built
// on these; tests (eigenfrequencies) and benchmarks use them directly.

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Dense>

#include "demfem/fem/fem_problem.hpp"
#include "demfem/fem/sparse_solver.hpp"
#include "demfem/interface/interface_mesh.hpp"

namespace demfem::io {
class H5File;
}

namespace demfem::fem {

/// @brief DOF numbering: 3 DOF per node, 6 for nodes of shell elements (u, then theta).
/// Constraints are applied by elimination: `reduced` maps a global DOF to its row in the
/// reduced (free) system, or -1 where fixed.
struct DofMap {
  std::vector<std::int32_t> node_offset;  ///< first global DOF of each node
  std::vector<std::uint8_t> node_dofs;    ///< 3 or 6
  std::int32_t total = 0;
  std::vector<std::int32_t> reduced;  ///< global -> reduced index, -1 = fixed
  std::vector<std::int32_t> free;     ///< reduced -> global
};

/// @brief Checks indices, materials, sections, loads; throws std::invalid_argument naming the
/// offending item and the accepted range.
void validate_problem(const FemProblem& problem);

DofMap make_dof_map(const FemProblem& problem);

/// @brief Global (unreduced) stiffness. Element matrices are computed in parallel and
/// summed in element order, so the result is bitwise independent of the thread count.
SparseMatrix assemble_stiffness(const FemProblem& problem, const DofMap& dofs);
/// @brief Global mass, consistent or lumped as problem.mass says.
SparseMatrix assemble_mass(const FemProblem& problem, const DofMap& dofs);
/// @brief Rows and columns of the free DOFs only.
SparseMatrix reduce_matrix(const SparseMatrix& full, const DofMap& dofs);

/// @brief Consistent nodal forces (global DOFs) of a pressure load at amplitude 1.
Eigen::VectorXd pressure_load_vector(const FemProblem& problem, const DofMap& dofs,
                                     const PressureLoad& load);
/// @brief Nodal forces of a nodal load at amplitude 1.
Eigen::VectorXd nodal_load_vector(const FemProblem& problem, const DofMap& dofs,
                                  const NodalLoad& load);
/// @brief Self weight M g (exact consistent body force: rows of M sum to the integral of N).
Eigen::VectorXd gravity_load_vector(const FemProblem& problem, const DofMap& dofs,
                                    const SparseMatrix& mass);

/// @brief The external loads of a problem over all DOFs: `constant` (self weight and the loads
/// without an amplitude, summed in the order pressures, nodal loads) and one vector per load
/// with an amplitude, at amplitude 1 (the load is amplitude(t) times the vector).
struct LoadVectors {
  Eigen::VectorXd constant;
  std::vector<std::pair<Eigen::VectorXd, TimeFunction>> timed;
};
LoadVectors load_vectors(const FemProblem& problem, const DofMap& dofs,
                         const SparseMatrix& full_mass);

/// @brief Unit nodal directors of shell nodes (average of the adjacent element normals),
/// zero for nodes of no shell element; and the mean thickness of their elements.
void shell_nodal_directors(const FemProblem& problem, std::vector<Eigen::Vector3d>& directors,
                           std::vector<double>& thickness);

/// @brief The coupled surface and how its nodes follow the mesh: interface node i is
/// mesh node `mesh_node[i]` offset by `offset[i]` (zero for volume meshes, +-t/2 director
/// for the top / bottom copies of shell nodes).
struct InterfaceMap {
  InterfaceMesh mesh;
  std::vector<std::int32_t> mesh_node;
  std::vector<Eigen::Vector3d> offset;
};
InterfaceMap build_interface(const FemProblem& problem);

/// @brief B (free DOFs x 3 interface nodes): the nodal loads of unit interface forces, i.e.
/// F = B f for interface forces f; a force on a shell's offset surface also gives the moment
/// (offset x force) on the mid-surface node. Its transpose maps free-DOF displacements to the
/// interface node displacements (x = x_mid + u + theta x offset), by virtual work.
SparseMatrix interface_load_matrix(const DofMap& dofs, const InterfaceMap& iface);

/// @brief Checks interface forces handed to a solver (`who`, for the message): 3 values per
/// interface node (`expected` in all), all finite. Throws std::invalid_argument.
void check_interface_forces(std::span<const double> forces, std::size_t expected, const char* who);

/// @brief Checks that the state in `group` of a checkpoint was saved from a model with these
/// DOFs (attributes dof_count and free_dof_count); throws std::runtime_error naming `who`, the
/// file and group, and both counts otherwise.
void check_saved_dof_count(const io::H5File& file, const std::string& group, const DofMap& dofs,
                           const char* who);

}  // namespace demfem::fem
