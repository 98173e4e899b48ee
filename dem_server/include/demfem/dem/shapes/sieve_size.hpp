#pragma once
// Sieve size of a convex body: the side of the smallest square aperture it passes through.
//
// A convex body passes a square hole of side s (moving straight through it, in some
// orientation) when its projection along the direction of motion fits in the square, i.e.
// when there are two orthogonal directions w1, w2 in the sieve plane along which its widths
// are both <= s (the width along w is the width of the projection along w). So
//   sieve size = min over orthonormal pairs (w1, w2) of max(width(w1), width(w2)),
// a minimisation over rotations (3 parameters). For the dilated body K + rB every width is
// the core's plus 2r, so its sieve size is the core's plus 2r exactly.
//
// Known values: a cube of edge a: a; a regular tetrahedron of edge a: a/sqrt(2) (both equal
// the body's minimum width, a lower bound); a box L >= I >= S: at most min(I, (I + S)/sqrt(2))
// (the second: passage along L with the square turned by 45 degrees), so the sieve size of a
// flat particle is below its intermediate dimension I, the usual approximation.
//
// Algorithm. For a fixed direction of passage u the best square is found exactly: project
// the vertices on the plane normal to u, take their 2-D convex hull; between consecutive
// breakpoints (the hull's edge normals modulo 90 degrees) both widths are sinusoids c . e(psi)
// of fixed antipodal pairs, concave where positive, so the minimum over the square's turn psi
// lies at a breakpoint or where the two widths cross: O(m log m) for m hull vertices. The
// remaining minimisation over u (2 parameters, Lipschitz, not smooth, several local minima)
// is searched: 512 directions on a Fibonacci hemisphere plus the face normals and the
// principal axes; a pattern search (16 tangent directions, polled from the last successful
// one; after a failed poll the step halves and the pattern turns by a random angle, so that
// it cannot stall on a fixed kink) from the 8 best down to 1e-3 rad; the best two refined
// down to 1e-9 rad.
//
// Accuracy: exact (round-off) for the cube, the regular tetrahedron and the boxes above. On
// 200 random hulls (4 to 33 vertices) the result is within 4.4e-10 relative of a search with
// 16x the directions and 8x the starts refined to 1e-11 rad (bench/shape_library). Cost:
// ~2-3 ms of CPU per 20-vertex shape, once per unit shape of a ShapeLibrary.
//
// Large cores (scanned rocks, issue 34 item 7). Projecting every vertex for each of the 2 V
// face normals cost O(V^2 log V): 42 s at 10^4 vertices, hours at 10^5. Two exact shortcuts
// (the same doubles as the exhaustive search, tested): from 64 vertices on, a direction
// projects only the silhouette band (the vertices whose faces face both ways, ~sqrt(V) of
// them); and a face normal is skipped when the objective's Lipschitz bound
// (|f(u) - f(u')| <= 2 rho |u - u'|) shows it cannot be among the local searches' starts.
// The normals are evaluated along a space-filling curve (neighbouring bands: short climbs,
// warm caches). Measured (bench/shape_library --large, 2-core VM under a load of 4-6 from other
// builds): 10^4 vertices on an ellipsoid 5 : 3.5 : 2 in 0.9 s (the exhaustive search 26 s),
// 10^5 in 3.0 s (+ 1.0 s for the hull). A sphere is the worst case (its objective is flat: no
// normal is skipped): 1.7 s at 10^4 (exhaustive 24 s), 10 s at 3*10^4, 83 s at 10^5; `progress`
// reports the stages (dem_server prints them for STL hulls of 2000 vertices and more).

#include <cstddef>
#include <functional>
#include <string_view>

#include "demfem/dem/shapes/convex_polyhedron.hpp"

namespace demfem::dem::shapes {

/// @brief The sieve size and the orientation that achieves it.
struct SieveFit {
  double size = 0.0;  ///< m (the core's: add 2 r_d for the dilated body)
  /// Columns: w1, w2 (the square's sides) and the direction of passage w1 x w2.
  Mat3 frame{};
};

/// @brief How hard to search for the global minimum over passage directions.
struct SieveSearch {
  int directions = 512;      ///< candidate passage directions (Fibonacci hemisphere)
  int local_starts = 8;      ///< coarse local searches (to 1e-3 rad) from the best candidates
  int refined = 2;           ///< of which the best are refined further
  double final_step = 1e-9;  ///< rad: the refinement's last step
  /// From this many core vertices on, a passage direction projects only the vertices of the
  /// silhouette band (the same 2-D hull, ~sqrt(V) of the cost); below it every vertex, which
  /// is cheaper on small cores. INT_MAX: always every vertex (the reference in the tests).
  int band_from_vertices = 64;
  /// Skip the face normals that the objective's Lipschitz bound rules out of the local
  /// searches' starts (exact: the same starts). false: evaluate every one (the reference).
  bool skip_hopeless_normals = true;
  /// Progress of a long search (cores of many vertices), if set: the stage ("candidates",
  /// "local searches"), the items done of the stage's total, and the objective evaluations so
  /// far (each projects the core along one direction). Called from the calling thread.
  std::function<void(std::string_view stage, std::size_t done, std::size_t total,
                     std::size_t evaluations)>
      progress;
};

/// The core's sieve size (0 for the point core). Deterministic.
SieveFit sieve_size(const ConvexPolyhedron& core, const SieveSearch& search = {});

}  // namespace demfem::dem::shapes
