#pragma once
// Sphere–triangle geometry shared by both backends: the closest point of a triangle to a
// point, with the feature (face, edge or vertex) it lies on, so that a contact at an edge or
// a vertex shared by several triangles is counted once (see the wall kernels).

#include "demfem/dem/physics/hd.hpp"

namespace demfem::dem::phys {

/// Feature of a triangle on which the closest point lies.
enum Feature : int {
  kFace = 0,
  kEdgeAB = 1,
  kEdgeBC = 2,
  kEdgeCA = 3,
  kVertexA = 4,
  kVertexB = 5,
  kVertexC = 6
};

struct ClosestPoint {
  Vec3 point;
  double u, v, w;  ///< barycentric weights of point on a, b, c
  int feature;
};

/// Closest point of triangle abc to p (Voronoi-region walk, Ericson, Real-Time Collision
/// Detection §5.1.5); degenerate triangles fall back to the edges.
DEMFEM_HD ClosestPoint closest_point_triangle(Vec3 p, Vec3 a, Vec3 b, Vec3 c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = dot(ab, ap), d2 = dot(ac, ap);
  if (d1 <= 0.0 && d2 <= 0.0) return {a, 1, 0, 0, kVertexA};
  const Vec3 bp = p - b;
  const double d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0.0 && d4 <= d3) return {b, 0, 1, 0, kVertexB};
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
    const double t = d1 / (d1 - d3);
    return {a + t * ab, 1 - t, t, 0, kEdgeAB};
  }
  const Vec3 cp = p - c;
  const double d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0.0 && d5 <= d6) return {c, 0, 0, 1, kVertexC};
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
    const double t = d2 / (d2 - d6);
    return {a + t * ac, 1 - t, 0, t, kEdgeCA};
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
    const double t = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return {b + t * (c - b), 0, 1 - t, t, kEdgeBC};
  }
  const double denom = va + vb + vc;
  if (!(denom > 0.0)) return {a, 1, 0, 0, kVertexA};  // degenerate: zero area
  const double v = vb / denom, w = vc / denom;
  return {a + v * ab + w * ac, 1 - v - w, v, w, kFace};
}

}  // namespace demfem::dem::phys
