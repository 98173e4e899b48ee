#pragma once
// Exact mass properties of a convex polyhedron and of its dilation by a sphere (the Minkowski
// sum K + r B). All per unit density: multiply volume by rho for the mass and the inertia
// tensor by rho for kg m^2.
//
// The dilated body is the disjoint union (up to boundaries) of
//   the core K,
//   a slab T x [0, r] on each triangle T along its outward normal,
//   a cylinder wedge of radius r and angle theta_e on each edge e, theta_e = the exterior
//     dihedral angle (the angle between the two face normals),
//   a sphere sector on each vertex v over its normal cone, of solid angle Omega_v (the angular
//     defect 2 pi - sum of the face angles at v; sum over vertices = 4 pi).
// Each piece's volume, first and second moments have closed forms (the sector's by the
// boundary integral of the spherical polygon of face normals), so the result is exact to
// round-off; no numerical integration. Summing the volumes gives Steiner's formula
//   V(r) = V + A r + (1/2) sum_e L_e theta_e r^2 + (4/3) pi r^3.

#include "demfem/dem/shapes/convex_polyhedron.hpp"

namespace demfem::dem::shapes {

/// @brief Volume, centroid and inertia tensor about the centroid, per unit density.
struct MassProperties {
  double volume = 0.0;  ///< m^3
  Vec3 centroid{};      ///< m, in the polyhedron's frame
  Mat3 inertia{};       ///< m^5, about the centroid, axes of the polyhedron's frame
};

/// @brief The coefficients of Steiner's formula for a convex polyhedron.
struct SteinerCoefficients {
  double volume = 0.0;     ///< V, m^3
  double area = 0.0;       ///< A, m^2
  double edge_term = 0.0;  ///< M = (1/2) sum_e L_e theta_e, m
  /// V + A r + M r^2 + (4/3) pi r^3.
  double dilated_volume(double r) const;
};

/// @brief Principal moments (ascending) and axes (the columns of `axes`, right-handed: a
/// rotation from the principal frame to the polyhedron's frame). Each of the first two
/// axes has its largest-magnitude component positive; the third is their cross product.
struct PrincipalFrame {
  Vec3 moments{};
  Mat3 axes{};
};

/// Exact, by decomposition into tetrahedra from an interior reference point. The point core
/// has volume 0, centroid = the point, zero inertia.
MassProperties core_mass_properties(const ConvexPolyhedron& core);
/// Exact (see above). r >= 0; r = 0 gives the core's.
MassProperties dilated_mass_properties(const ConvexPolyhedron& core, double r);
SteinerCoefficients steiner_coefficients(const ConvexPolyhedron& core);
/// Solid angle of the normal cone at each vertex (sum 4 pi; the point core: {4 pi}).
std::vector<double> vertex_solid_angles(const ConvexPolyhedron& core);
/// Eigen-decomposition of a symmetric tensor (Eigen's SelfAdjointEigenSolver).
PrincipalFrame principal_frame(const Mat3& inertia);

}  // namespace demfem::dem::shapes
