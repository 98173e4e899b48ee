#pragma once
// Local topology of the element types: faces as local node lists (Abaqus face numbering),
// ordered so that the right-hand rule gives the outward normal for an element with positive
// Jacobian. Shared by the solver (pressure, exterior surface) and the mesher.

#include <array>
#include <span>

#include "demfem/fem/fem_problem.hpp"

namespace demfem::fem {

/// @brief Number of faces of an element type (shell: 0 = bottom/SNEG, 1 = top/SPOS).
constexpr int face_count(ElementType t) {
  return t == ElementType::hex8 ? 6 : (t == ElementType::tet4 ? 4 : 2);
}

/// @brief Node count of a face (3 for tet faces, 4 otherwise).
constexpr int face_node_count(ElementType t) {
  return t == ElementType::tet4 ? 3 : 4;
}

/// @brief Local node indices of a face, outward orientation (right-hand rule).
/// hex8: S1 zeta=-1, S2 zeta=+1, S3 eta=-1, S4 xi=+1, S5 eta=+1, S6 xi=-1.
/// tet4: S1 (1,2,3), S2 (1,4,2), S3 (2,4,3), S4 (3,4,1), reordered outward.
/// quad4 shell: 0 = bottom (normal -n), 1 = top (normal +n, n by the node order 1-2-3-4).
constexpr std::array<int, 4> face_local_nodes(ElementType t, int face) {
  constexpr std::array<std::array<int, 4>, 6> hex{
      {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4}, {1, 2, 6, 5}, {2, 3, 7, 6}, {0, 4, 7, 3}}};
  constexpr std::array<std::array<int, 4>, 4> tet{
      {{0, 2, 1, -1}, {0, 1, 3, -1}, {1, 2, 3, -1}, {2, 0, 3, -1}}};
  constexpr std::array<std::array<int, 4>, 2> quad{{{0, 3, 2, 1}, {0, 1, 2, 3}}};
  if (t == ElementType::hex8) return hex[static_cast<std::size_t>(face)];
  if (t == ElementType::tet4) return tet[static_cast<std::size_t>(face)];
  return quad[static_cast<std::size_t>(face)];
}

}  // namespace demfem::fem
