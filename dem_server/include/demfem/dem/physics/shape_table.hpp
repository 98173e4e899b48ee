#pragma once
// The shape table of the dilated convex polyhedra (thesis §2.1.1, eq. 2.4: a convex core ⊕ a
// sphere of radius r_d), as plain arrays that both backends read (host or device pointers),
// and the convex cores the narrow phase (physics/narrow_phase.hpp) works on.
//
// A shape is stored at scale 1 in its body frame: the principal frame of the dilated body,
// origin at its centre of mass. A particle refers to a shape by index and carries a scale s:
// its core is x + s R(q) v for the shape's vertices v, its dilation radius s r_d. The faces
// are the planar polygons of the hull (coplanar triangles merged, loops counter-clockwise seen
// from outside), with unit outward normals; the edges are the polygon sides (no diagonals of
// merged faces). Built on the host by dem_server/src/core/shape_table.cpp.
//
// A convex core (struct Core) is one of: a posed polyhedron (a table shape; one vertex is a
// point core, the sphere limit), a sphere's centre (point core) or a wall triangle (three
// vertices in world coordinates, one two-sided face).

#include <cstdint>

#include "demfem/dem/physics/geometry.hpp"
#include "demfem/dem/physics/rigid_body.hpp"

namespace demfem::dem::phys {

/// Largest vertex count of a face polygon that the contact region handles (longer faces give a
/// point contact; hulls of rocks have triangles, simple solids quadrilaterals).
constexpr int kMaxFaceVertices = 16;

/// Read-only view of the shape table.
struct ShapeTableView {
  const std::int32_t* vbase;  ///< per shape: first vertex (index into vert / 3)
  const std::int32_t* nv;     ///< per shape: vertex count
  const double* vert;         ///< 3 per vertex, body frame, scale 1, m
  const std::int32_t* fbase;  ///< per shape: first face
  const std::int32_t* nf;     ///< per shape: face count (0 for cores without volume)
  const double* fnormal;      ///< 3 per face: unit outward normal, body frame
  const std::int32_t* floop;  ///< per face: first entry in fvert
  const std::int32_t* flen;   ///< per face: vertex count of the polygon
  const std::int32_t* fvert;  ///< local vertex indices of the face loops (CCW from outside)
  const std::int32_t* ebase;  ///< per shape: first edge
  const std::int32_t* ne;     ///< per shape: edge count
  const std::int32_t* edge;   ///< 2 local vertex indices per edge
  const double* dilation;     ///< per shape: r_d at scale 1, m
  const double* bound;        ///< per shape: bounding radius of the dilated body at scale 1, m
  /// The vertices and face normals again as columns (x of all, then y, then z; each column
  /// padded to a multiple of kSoaPad), so that the loops over them run in SIMD lanes; null:
  /// the loops read vert and fnormal (the device table). Offsets per shape in vsoa_base,
  /// fsoa_base.
  const double* vsoa = nullptr;
  const std::int32_t* vsoa_base = nullptr;
  const double* fsoa = nullptr;
  const std::int32_t* fsoa_base = nullptr;
};

/// Padding of the columns of ShapeTableView::vsoa and fsoa (8 doubles: one AVX-512 vector).
constexpr int kSoaPad = 8;
/// Largest count of vertices or faces read from the columns (larger shapes: the rows).
constexpr int kMaxSoa = 128;

/// d·x for the n entries of columns X, Y, Z (n padded to kSoaPad) into h: written as
/// x d.x + y d.y + z d.z, the rounding of the row loops'.
DEMFEM_HD void column_dots(const double* X, int n, Vec3 d, double* h) {
  const double* Y = X + n;
  const double* Z = Y + n;
  for (int k = 0; k < n; ++k) h[k] = X[k] * d.x + Y[k] * d.y + Z[k] * d.z;
}

DEMFEM_HD int soa_padded(int n) {
  return (n + kSoaPad - 1) / kSoaPad * kSoaPad;
}

/// The index the scan `best = 0; for k ≥ 1: if (h[k] > h[best]) best = k` finds in h[0..n)
/// (n ≥ 1: the first of the largest), as the largest value, a reduction that runs in SIMD
/// lanes, and then the first index holding it; the scalar scan compares and branches once per
/// entry (most of the support and best-face loops' instructions). The same index wherever h
/// is free of NaN (a NaN direction gives some index, as the scan does).
DEMFEM_HD int first_max_index(const double* h, int n) {
  double m = h[0];
#if defined(_OPENMP) && !defined(__CUDA_ARCH__)
#pragma omp simd reduction(max : m)
#endif
  for (int k = 1; k < n; ++k) m = h[k] > m ? h[k] : m;
  for (int k = 0; k < n; ++k)
    if (h[k] == m) return k;
  int best = 0;
  for (int k = 1; k < n; ++k)
    if (h[k] > h[best]) best = k;
  return best;
}

/// A convex core in world coordinates.
struct Core {
  enum Kind : int { kPoint = 0, kPolyhedron = 1, kTriangle = 2 };
  int kind;
  int nv;
  Vec3 x;           ///< position (point, polyhedron)
  Rot r;            ///< orientation (polyhedron)
  double s;         ///< scale (polyhedron)
  const double* v;  ///< body-frame vertices (polyhedron)
  int shape;        ///< table index (polyhedron)
  const ShapeTableView* table;
  Vec3 t[3];  ///< world vertices (triangle)
};

DEMFEM_HD Core point_core(Vec3 x) {
  Core c{};
  c.kind = Core::kPoint;
  c.nv = 1;
  c.x = x;
  return c;
}

DEMFEM_HD Core triangle_core(Vec3 a, Vec3 b, Vec3 c) {
  Core k{};
  k.kind = Core::kTriangle;
  k.nv = 3;
  k.t[0] = a, k.t[1] = b, k.t[2] = c;
  return k;
}

/// Core of a particle with shape `shape` (table index), position x, rotation matrix rot (9
/// values, row-major: rotation(q) of its orientation q), scale s.
DEMFEM_HD Core polyhedron_core(const ShapeTableView& tab, int shape, Vec3 x, const double* rot,
                               double s) {
  Core c{};
  c.kind = Core::kPolyhedron;
  c.table = &tab;
  c.shape = shape;
  c.nv = tab.nv[shape];
  c.v = tab.vert + 3 * tab.vbase[shape];
  c.x = x;
  for (int k = 0; k < 9; ++k) c.r.m[k] = rot[k];
  c.s = s;
  return c;
}

/// The same from the orientation quaternion q.
DEMFEM_HD Core polyhedron_core(const ShapeTableView& tab, int shape, Vec3 x, double qw, double qx,
                               double qy, double qz, double s) {
  const Rot r = rotation(qw, qx, qy, qz);
  return polyhedron_core(tab, shape, x, r.m, s);
}

/// World position of vertex k of a core.
DEMFEM_HD Vec3 core_vertex(const Core& c, int k) {
  if (c.kind == Core::kTriangle) return c.t[k];
  if (c.kind == Core::kPoint) return c.x;
  const double* p = c.v + 3 * k;
  return c.x + c.s * to_world(c.r, Vec3{p[0], p[1], p[2]});
}

/// Support point of a core in world direction d (a vertex maximising d·x; the lowest index
/// among equals, so that the result depends on d only); `idx` receives the vertex index.
DEMFEM_HD Vec3 support(const Core& c, Vec3 d, int& idx) {
  if (c.kind == Core::kPoint) {
    idx = 0;
    return c.x;
  }
  if (c.kind == Core::kTriangle) {
    const double d0 = dot(c.t[0], d), d1 = dot(c.t[1], d), d2 = dot(c.t[2], d);
    idx = d1 > d0 ? (d2 > d1 ? 2 : 1) : (d2 > d0 ? 2 : 0);
    return c.t[idx];
  }
  const Vec3 db = to_body(c.r, d);
  if (c.table->vsoa != nullptr && c.nv <= kMaxSoa) {
    double h[kMaxSoa];
    column_dots(c.table->vsoa + c.table->vsoa_base[c.shape], soa_padded(c.nv), db, h);
    idx = first_max_index(h, c.nv);
    return core_vertex(c, idx);
  }
  const double* p = c.v;
  int best = 0;
  double bv = p[0] * db.x + p[1] * db.y + p[2] * db.z;
  for (int k = 1; k < c.nv; ++k) {
    const double h = p[3 * k] * db.x + p[3 * k + 1] * db.y + p[3 * k + 2] * db.z;
    if (h > bv) bv = h, best = k;
  }
  idx = best;
  return core_vertex(c, best);
}

/// Number of faces a core offers to the contact region: a polyhedron its polygons, a triangle
/// its two sides (0: front, normal (b - a) × (c - a); 1: back), a point none.
DEMFEM_HD int core_face_count(const Core& c) {
  if (c.kind == Core::kTriangle) return 2;
  if (c.kind == Core::kPoint) return 0;
  return c.table->nf[c.shape];
}

/// Unit outward normal of face f of a core, world frame.
DEMFEM_HD Vec3 core_face_normal(const Core& c, int f) {
  if (c.kind == Core::kTriangle) {
    const Vec3 nn = cross(c.t[1] - c.t[0], c.t[2] - c.t[0]);
    const double l = std::sqrt(norm2(nn));
    return (f == 0 ? 1.0 / l : -1.0 / l) * nn;
  }
  const double* n = c.table->fnormal + 3 * (c.table->fbase[c.shape] + f);
  return to_world(c.r, Vec3{n[0], n[1], n[2]});
}

/// Vertices of face f of a core (world, counter-clockwise seen from outside); returns the
/// count (0 when the face has more than kMaxFaceVertices).
DEMFEM_HD int core_face_polygon(const Core& c, int f, Vec3* out) {
  if (c.kind == Core::kTriangle) {
    out[0] = c.t[0];
    out[1] = f == 0 ? c.t[1] : c.t[2];
    out[2] = f == 0 ? c.t[2] : c.t[1];
    return 3;
  }
  const int g = c.table->fbase[c.shape] + f;
  const int len = c.table->flen[g];
  if (len > kMaxFaceVertices) return 0;
  const std::int32_t* lp = c.table->fvert + c.table->floop[g];
  for (int k = 0; k < len; ++k) out[k] = core_vertex(c, lp[k]);
  return len;
}

/// The face of a core whose outward normal is best aligned with d (unit): returns its index
/// (-1 without faces) and its alignment n_f·d in `align`.
DEMFEM_HD int core_best_face(const Core& c, Vec3 d, double& align) {
  const int nf = core_face_count(c);
  int best = -1;
  align = -2.0;
  if (c.kind == Core::kTriangle) {
    const Vec3 n0 = core_face_normal(c, 0);
    const double a = dot(n0, d);
    best = a >= 0.0 ? 0 : 1;
    align = a >= 0.0 ? a : -a;
    return best;
  }
  if (nf == 0) return -1;
  const Vec3 db = to_body(c.r, d);  // compare in the body frame: one rotation, not nf
  if (c.table->fsoa != nullptr && nf <= kMaxSoa) {
    double a[kMaxSoa];
    column_dots(c.table->fsoa + c.table->fsoa_base[c.shape], soa_padded(nf), db, a);
    best = first_max_index(a, nf);
    if (!(a[best] > align)) return -1;  // NaN: the scan from -2 finds none
    align = a[best];
    return best;
  }
  const double* fn = c.table->fnormal + 3 * c.table->fbase[c.shape];
  for (int f = 0; f < nf; ++f) {
    const double a = fn[3 * f] * db.x + fn[3 * f + 1] * db.y + fn[3 * f + 2] * db.z;
    if (a > align) align = a, best = f;
  }
  return best;
}

/// Edge count of a core and the two world end points of edge e.
DEMFEM_HD int core_edge_count(const Core& c) {
  if (c.kind == Core::kTriangle) return 3;
  if (c.kind == Core::kPoint) return 0;
  return c.table->ne[c.shape];
}

/// The end vertices of edge e of core c: from vertex a to vertex b (local indices).
DEMFEM_HD void core_edge_vertices(const Core& c, int e, int& a, int& b) {
  if (c.kind == Core::kTriangle) {
    a = e, b = (e + 1) % 3;
    return;
  }
  const std::int32_t* ev = c.table->edge + 2 * (c.table->ebase[c.shape] + e);
  a = ev[0], b = ev[1];
}

DEMFEM_HD void core_edge(const Core& c, int e, Vec3& a, Vec3& b) {
  int ia, ib;
  core_edge_vertices(c, e, ia, ib);
  a = core_vertex(c, ia);
  b = core_vertex(c, ib);
}

}  // namespace demfem::dem::phys
