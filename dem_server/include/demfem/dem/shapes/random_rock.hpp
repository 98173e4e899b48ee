#pragma once
// Random convex rock cores with an exact number of triangles and given elongation and
// flatness.
//
// A closed triangulated convex polyhedron whose V vertices are all extreme has E = 3V - 6
// edges and F = 2V - 4 triangles (Euler), so only even triangle counts >= 4 exist; the thesis
// used 10, 30 and 40 (V = 7, 17, 22).
//
// Method: V directions uniform on the unit sphere, no two closer than half the mean spacing
// sqrt(4 pi / V) (so no sliver faces), stretched by (1, e, e f); the Qhull hull; redrawn until
// every point is a hull vertex and the hull has exactly 2V - 4 triangles (points on an
// ellipsoid are all extreme, so this is rare). Then the hull is moved to its centroid and
// principal axes and stretched along them so that its extents (principal-axes bounding box)
// are exactly L = 1, I = e, S = e f: a stretch along the principal axes keeps the central
// second-moment tensor diagonal, so the axes and the triangulation stay. These are the
// core's ratios; the dilated particle's are closer to 1 (ParticleShape reports them).
//
// Deterministic: the same seed gives the same rock on every platform with IEEE doubles and
// the same libm (the Rng's transforms are our own; sqrt is exact; cos/sin come from libm).

#include <cstdint>

#include "demfem/dem/shapes/convex_polyhedron.hpp"

namespace demfem::dem::shapes {

/// @brief What random_rock generates.
struct RockParams {
  int triangles = 30;       ///< even, >= 4 (the thesis: 10, 30, 40)
  double elongation = 1.0;  ///< I / L of the core, in (0, 1]
  double flatness = 1.0;    ///< S / I of the core, in (0, 1]
};

/// Throws ShapeError naming the parameter and its accepted range.
void validate(const RockParams& params);

/// A core with exactly params.triangles triangles, centroid at the origin, principal axes
/// along x (longest, extent 1), y (extent e) and z (extent e f).
ConvexPolyhedron random_rock(const RockParams& params, std::uint64_t seed);

}  // namespace demfem::dem::shapes
