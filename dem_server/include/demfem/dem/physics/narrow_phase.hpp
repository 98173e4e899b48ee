#pragma once
// Narrow phase of the dilated convex polyhedra (thesis eq. 2.5): the distance Δ between two
// convex cores, the contact normal, the closest core points and the contact point, shared by
// both backends.
//
//  * Distance: GJK (Gilbert, Johnson & Keerthi 1988) on the Minkowski difference A ⊖ B with the
//    closest point of each simplex found by Ericson's Voronoi-region walks (Real-Time Collision
//    Detection §5.1), started from the centre difference (so that the result depends on the
//    configuration only, not on earlier steps: the bits of a run do not depend on which
//    non-touching pairs the neighbour list held). For polytopes GJK ends exactly: when the new
//    support point is one the simplex has (same vertex pair) the simplex holds the closest
//    features. Stops early when a separating axis proves Δ > margin (no contact).
//  * Cores that intersect (Δ = 0: the overlap is deeper than r_i + r_j) fall back to the
//    separating-axis test over the face normals of both cores and the cross products of their
//    edges (the normals of the faces of A ⊖ B): the smallest overlap along them is the exact
//    penetration depth, its axis the normal; Δ is then minus that depth, so the force keeps its
//    sign and stays finite however deep the overlap.
//  * Contact point: the midpoint between the two dilated surfaces, (p_A + r_A n + p_B − r_B n)/2,
//    placed, when the normal is the normal of a face of A or B (face–face, edge–face and
//    vertex–face contacts), at the centroid of the touching region weighted by the local
//    overlap o(x) = r_A + r_B − g(x) (g the local separation of the two faces along the
//    normal): the face best aligned with the normal (reference) clips the opposite body's face
//    most opposed to it (incident) by its side planes, the result is clipped to o ≥ 0, and
//    ∫ o dA, ∫ x o dA over it give the centroid. For a flat face on a flat face this is the
//    middle of the touching region, and a tilt θ shifts it continuously (by θ a² / (12 δ) on a
//    face of width a at overlap δ), like the pressure centre of an elastic foundation: a single
//    contact point at a face's vertex would make a cube resting on a face rock (measured,
//    docs/dem.md). Edge–edge and vertex–edge contacts keep the midpoint of the closest points.

#include "demfem/dem/physics/shape_table.hpp"

namespace demfem::dem::phys {

/// Contact of two dilated cores A (radius ra) and B (radius rb).
struct ConvexContact {
  bool separated;    ///< proven farther apart than the margin asked for: only `axis` is valid
  double dist;       ///< Δ: distance of the cores; minus the penetration depth when they intersect
  Vec3 n;            ///< unit normal from A towards B
  Vec3 pa, pb;       ///< closest core points (deepest points when the cores intersect)
  Vec3 point;        ///< contact point (see the file comment)
  double weight;     ///< ∫ o dA of the touching region, m³ (0: point contact)
  Vec3 moment;       ///< ∫ x o dA (world), m⁴
  double second[6];  ///< ∫ o u uᵀ dA, u = x − A's centre: xx, yy, zz, xy, xz, yz, m⁵
  Vec3 axis;         ///< a separating direction A → B (for the next step's quick test)
  int ref_side;      ///< 0: the region's reference face is A's, 1: B's, -1: no region
  int ref_face;      ///< the reference face index
};

namespace detail {

struct Simplex {
  int n;
  Vec3 w[4], a[4], b[4];  // A ⊖ B point, its A and B support points
  int ia[4], ib[4];
  double lam[4];
};

// Keeps the vertices k of s whose flag is set, in order.
DEMFEM_HD void simplex_keep(Simplex& s, const bool* keep, const double* lam) {
  int m = 0;
  for (int k = 0; k < s.n; ++k)
    if (keep[k]) {
      s.w[m] = s.w[k], s.a[m] = s.a[k], s.b[m] = s.b[k];
      s.ia[m] = s.ia[k], s.ib[m] = s.ib[k];
      s.lam[m] = lam[k];
      ++m;
    }
  s.n = m;
}

// Closest point of a triangle to the origin, reducing the simplex (3 points) to its feature.
DEMFEM_HD Vec3 simplex_triangle(Simplex& s, const int* idx) {
  const ClosestPoint c =
      closest_point_triangle(Vec3{0, 0, 0}, s.w[idx[0]], s.w[idx[1]], s.w[idx[2]]);
  bool keep[4] = {false, false, false, false};
  double lam[4] = {0, 0, 0, 0};
  const double bw[3] = {c.u, c.v, c.w};
  for (int k = 0; k < 3; ++k)
    if (bw[k] > 0.0) keep[idx[k]] = true, lam[idx[k]] = bw[k];
  if (!keep[idx[0]] && !keep[idx[1]] && !keep[idx[2]]) keep[idx[0]] = true, lam[idx[0]] = 1.0;
  simplex_keep(s, keep, lam);
  return c.point;
}

// Closest point of the simplex to the origin; reduces it to the smallest sub-simplex holding
// that point. Returns false when the origin lies inside a (non-degenerate) tetrahedron.
DEMFEM_HD bool simplex_closest(Simplex& s, Vec3& v) {
  if (s.n == 1) {
    s.lam[0] = 1.0;
    v = s.w[0];
    return true;
  }
  if (s.n == 2) {
    const Vec3 e = s.w[1] - s.w[0];
    const double ee = norm2(e);
    const double t = ee > 0.0 ? -dot(s.w[0], e) / ee : 0.0;
    if (t <= 0.0) {
      bool keep[4] = {true, false, false, false};
      double lam[4] = {1, 0, 0, 0};
      simplex_keep(s, keep, lam);
      v = s.w[0];
    } else if (t >= 1.0) {
      bool keep[4] = {false, true, false, false};
      double lam[4] = {0, 1, 0, 0};
      simplex_keep(s, keep, lam);
      v = s.w[0];
    } else {
      s.lam[0] = 1.0 - t, s.lam[1] = t;
      v = s.w[0] + t * e;
    }
    return true;
  }
  if (s.n == 3) {
    const int idx[3] = {0, 1, 2};
    v = simplex_triangle(s, idx);
    return true;
  }
  // tetrahedron: origin inside when the four sub-volumes have the sign of the whole
  const Vec3 a = s.w[0], b = s.w[1], c = s.w[2], d = s.w[3];
  const double vol = dot(b - a, cross(c - a, d - a));
  const Vec3 o{0, 0, 0};
  const double v0 = dot(b - o, cross(c - o, d - o));  // o replaces a
  const double v1 = dot(o - a, cross(c - a, d - a));  // o replaces b
  const double v2 = dot(b - a, cross(o - a, d - a));  // o replaces c
  const double v3 = dot(b - a, cross(c - a, o - a));  // o replaces d
  const double scale = norm2(b - a) + norm2(c - a) + norm2(d - a);
  const bool solid = vol * vol > 1e-24 * scale * scale * scale;
  if (solid && (vol > 0.0 ? (v0 >= 0.0 && v1 >= 0.0 && v2 >= 0.0 && v3 >= 0.0)
                          : (v0 <= 0.0 && v1 <= 0.0 && v2 <= 0.0 && v3 <= 0.0))) {
    const double inv = 1.0 / vol;
    s.lam[0] = v0 * inv, s.lam[1] = v1 * inv, s.lam[2] = v2 * inv, s.lam[3] = v3 * inv;
    v = Vec3{0, 0, 0};
    return false;
  }
  // otherwise the closest point lies on a face holding the newest point w[3] (the origin
  // lies beyond the previous triangle 0, 1, 2 towards w[3]): the nearest of those three
  const int faces[3][3] = {{0, 1, 3}, {0, 2, 3}, {1, 2, 3}};
  int best = 0;
  double bd = 1e300;
  for (int f = 0; f < 3; ++f) {
    const ClosestPoint cp =
        closest_point_triangle(o, s.w[faces[f][0]], s.w[faces[f][1]], s.w[faces[f][2]]);
    const double dd = norm2(cp.point);
    if (dd < bd) bd = dd, best = f;
  }
  v = simplex_triangle(s, faces[best]);
  return true;
}

// Support of A ⊖ B in direction d: s_A(d) - s_B(-d).
DEMFEM_HD void cso_support(const Core& A, const Core& B, Vec3 d, Vec3& w, Vec3& a, Vec3& b, int& ia,
                           int& ib) {
  a = support(A, d, ia);
  b = support(B, -d, ib);
  w = a - b;
}

}  // namespace detail

/// Result of gjk_distance().
struct GjkResult {
  int status;  ///< 0: separated by more than the margin; 1: distance found; 2: cores intersect
  double dist;
  Vec3 v;       ///< p_A - p_B (status 1), a separating direction B → A (status 0)
  Vec3 pa, pb;  ///< closest points (status 1)
  int n;        ///< final simplex (status 1): its vertex pairs (ia, ib)
  int ia[3], ib[3];
};

namespace detail {

// Closest points of segments p1 q1 and p2 q2 (Ericson §5.1.9, the parallel case clamped).
DEMFEM_HD void closest_segments(Vec3 p1, Vec3 q1, Vec3 p2, Vec3 q2, Vec3& c1, Vec3& c2) {
  const Vec3 d1 = q1 - p1, d2 = q2 - p2, r = p1 - p2;
  const double a = norm2(d1), e = norm2(d2), f = dot(d2, r);
  double sp, t;
  if (!(a > 0.0) && !(e > 0.0)) {
    sp = t = 0.0;
  } else if (!(a > 0.0)) {
    sp = 0.0;
    t = f / e;
    t = t < 0.0 ? 0.0 : (t > 1.0 ? 1.0 : t);
  } else {
    const double c = dot(d1, r);
    if (!(e > 0.0)) {
      t = 0.0;
      sp = -c / a;
      sp = sp < 0.0 ? 0.0 : (sp > 1.0 ? 1.0 : sp);
    } else {
      const double b = dot(d1, d2);
      const double den = a * e - b * b;
      sp = den > 0.0 ? (b * f - c * e) / den : 0.0;
      sp = sp < 0.0 ? 0.0 : (sp > 1.0 ? 1.0 : sp);
      t = (b * sp + f) / e;
      if (t < 0.0) {
        t = 0.0;
        sp = -c / a;
        sp = sp < 0.0 ? 0.0 : (sp > 1.0 ? 1.0 : sp);
      } else if (t > 1.0) {
        t = 1.0;
        sp = (b - c) / a;
        sp = sp < 0.0 ? 0.0 : (sp > 1.0 ? 1.0 : sp);
      }
    }
  }
  c1 = p1 + sp * d1;
  c2 = p2 + t * d2;
}

// Closest point of segment a b to p.
DEMFEM_HD Vec3 closest_on_segment(Vec3 p, Vec3 a, Vec3 b) {
  const Vec3 e = b - a;
  const double ee = norm2(e);
  double t = ee > 0.0 ? dot(p - a, e) / ee : 0.0;
  t = t < 0.0 ? 0.0 : (t > 1.0 ? 1.0 : t);
  return a + t * e;
}

// The closest points recomputed from the closest features alone (A's vertices sa, B's sb,
// ascending), so that they do not depend on the path GJK took: vertex–face, edge–edge,
// vertex–edge and vertex–vertex. Returns false for other (degenerate) feature pairs.
DEMFEM_HD bool canonical_points(const Core& A, const int* sa, int na, const Core& B, const int* sb,
                                int nb, Vec3& pa, Vec3& pb) {
  if (na == 1 && nb == 1) {
    pa = core_vertex(A, sa[0]);
    pb = core_vertex(B, sb[0]);
  } else if (na == 1 && nb == 2) {
    pa = core_vertex(A, sa[0]);
    pb = closest_on_segment(pa, core_vertex(B, sb[0]), core_vertex(B, sb[1]));
  } else if (na == 2 && nb == 1) {
    pb = core_vertex(B, sb[0]);
    pa = closest_on_segment(pb, core_vertex(A, sa[0]), core_vertex(A, sa[1]));
  } else if (na == 1 && nb == 3) {
    pa = core_vertex(A, sa[0]);
    pb = closest_point_triangle(pa, core_vertex(B, sb[0]), core_vertex(B, sb[1]),
                                core_vertex(B, sb[2]))
             .point;
  } else if (na == 3 && nb == 1) {
    pb = core_vertex(B, sb[0]);
    pa = closest_point_triangle(pb, core_vertex(A, sa[0]), core_vertex(A, sa[1]),
                                core_vertex(A, sa[2]))
             .point;
  } else if (na == 2 && nb == 2) {
    closest_segments(core_vertex(A, sa[0]), core_vertex(A, sa[1]), core_vertex(B, sb[0]),
                     core_vertex(B, sb[1]), pa, pb);
  } else {
    return false;
  }
  return true;
}

// The distinct values of v[0..n), ascending.
DEMFEM_HD int sorted_unique(const int* v, int n, int* out) {
  int m = 0;
  for (int k = 0; k < n; ++k) {
    bool dup = false;
    for (int j = 0; j < m; ++j) dup = dup || out[j] == v[k];
    if (!dup) out[m++] = v[k];
  }
  for (int i = 1; i < m; ++i)
    for (int j = i; j > 0 && out[j - 1] > out[j]; --j) {
      const int t = out[j];
      out[j] = out[j - 1];
      out[j - 1] = t;
    }
  return m;
}

}  // namespace detail

/// GJK distance of cores A and B, stopping early when a separating axis shows Δ > margin.
/// Warm start: `seed` (3 vertex pairs ia, ib; -1 unused; may be null), the closest features
/// of an earlier call, seeds the simplex; else `dir` (A → B, may be zero) gives the first
/// direction; else the centre difference. The closest points returned are recomputed from
/// the closest features (detail::canonical_points), so that they do not depend on the start
/// wherever those features are unique.
DEMFEM_HD GjkResult gjk_distance(const Core& A, const Core& B, double margin,
                                 const int* seed = nullptr, Vec3 dir = Vec3{0, 0, 0}) {
  GjkResult r{};
  detail::Simplex s{};
  s.n = 0;
  if (seed != nullptr)
    for (int k = 0; k < 3; ++k) {
      const int ia = seed[2 * k], ib = seed[2 * k + 1];
      if (ia < 0 || ib < 0 || ia >= A.nv || ib >= B.nv) continue;
      bool dup = false;
      for (int j = 0; j < s.n; ++j) dup = dup || (s.ia[j] == ia && s.ib[j] == ib);
      if (dup) continue;
      s.a[s.n] = core_vertex(A, ia), s.b[s.n] = core_vertex(B, ib);
      s.w[s.n] = s.a[s.n] - s.b[s.n], s.ia[s.n] = ia, s.ib[s.n] = ib;
      ++s.n;
    }
  Vec3 v;
  if (s.n > 0) {
    detail::simplex_closest(s, v);  // at most 3 points: never "inside"
  } else {
    Vec3 d = -1.0 * dir;
    if (!(norm2(d) > 0.0)) {
      d = core_vertex(A, 0) - core_vertex(B, 0);
      if (A.kind != Core::kTriangle)
        d = A.x - (B.kind == Core::kTriangle ? (1.0 / 3.0) * (B.t[0] + B.t[1] + B.t[2]) : B.x);
    }
    if (!(norm2(d) > 0.0)) d = Vec3{1, 0, 0};
    detail::cso_support(A, B, -1.0 * d, s.w[0], s.a[0], s.b[0], s.ia[0], s.ib[0]);
    s.n = 1;
    s.lam[0] = 1.0;
    v = s.w[0];
  }
  double vv = norm2(v);
  // scale of the coordinates, for the termination tolerances
  const double tiny = 1e-30;
  for (int iter = 0; iter < 64; ++iter) {
    if (vv <= tiny) break;  // the cores touch or intersect
    Vec3 w, a, b;
    int ia, ib;
    detail::cso_support(A, B, -1.0 * v, w, a, b, ia, ib);
    const double vw = dot(v, w);
    if (vw > 0.0 && vw * vw > margin * margin * vv) {  // Δ ≥ v·w/|v| > margin
      r.status = 0;
      r.v = v;
      r.dist = vw / std::sqrt(vv);
      return r;
    }
    bool seen = false;
    for (int k = 0; k < s.n; ++k) seen = seen || (s.ia[k] == ia && s.ib[k] == ib);
    if (seen || vv - vw <= 1e-14 * vv) break;  // no better support point: converged
    s.w[s.n] = w, s.a[s.n] = a, s.b[s.n] = b, s.ia[s.n] = ia, s.ib[s.n] = ib;
    ++s.n;
    Vec3 nv;
    if (!detail::simplex_closest(s, nv)) {  // origin inside A ⊖ B
      vv = 0.0;
      break;
    }
    const double nvv = norm2(nv);
    if (nvv >= vv) break;  // no progress (rounding): keep the last
    v = nv;
    vv = nvv;
  }
  if (vv <= tiny * 1e2 || s.n == 4) {
    r.status = 2;
    r.dist = 0.0;
    return r;
  }
  Vec3 pa{0, 0, 0}, pb{0, 0, 0};
  int sa[3], sb[3];
  const int na = detail::sorted_unique(s.ia, s.n, sa), nb = detail::sorted_unique(s.ib, s.n, sb);
  if (!detail::canonical_points(A, sa, na, B, sb, nb, pa, pb)) {
    double lsum = 0.0;
    for (int k = 0; k < s.n; ++k) lsum += s.lam[k];
    for (int k = 0; k < s.n; ++k) {
      const double l = s.lam[k] / lsum;
      pa = pa + l * s.a[k];
      pb = pb + l * s.b[k];
    }
  }
  r.n = s.n;
  for (int k = 0; k < 3; ++k) r.ia[k] = k < s.n ? s.ia[k] : -1, r.ib[k] = k < s.n ? s.ib[k] : -1;
  r.status = 1;
  r.pa = pa, r.pb = pb;
  r.v = pa - pb;
  r.dist = std::sqrt(norm2(r.v));
  return r;
}

/// Penetration of two intersecting cores by the separating-axis test over the face normals of
/// both and the cross products of their edges: returns the depth (≥ 0) and the axis n (A → B)
/// along which the overlap max_A n·x − min_B n·x is smallest.
DEMFEM_HD double sat_penetration(const Core& A, const Core& B, Vec3& n) {
  double best = 1e300;
  n = Vec3{0, 0, 1};
  auto test = [&](Vec3 d) {
    const double l2 = norm2(d);
    if (!(l2 > 1e-24)) return;
    const Vec3 u = (1.0 / std::sqrt(l2)) * d;
    int ia, ib;
    const double o = dot(support(A, u, ia), u) - dot(support(B, -1.0 * u, ib), u);
    if (o < best) best = o, n = u;
  };
  const int fa = core_face_count(A), fb = core_face_count(B);
  for (int f = 0; f < fa; ++f) test(core_face_normal(A, f));
  for (int f = 0; f < fb; ++f) test(-1.0 * core_face_normal(B, f));
  const int ea = core_edge_count(A), eb = core_edge_count(B);
  for (int i = 0; i < ea; ++i) {
    Vec3 a0, a1;
    core_edge(A, i, a0, a1);
    for (int j = 0; j < eb; ++j) {
      Vec3 b0, b1;
      core_edge(B, j, b0, b1);
      const Vec3 c = cross(a1 - a0, b1 - b0);
      test(c);
      test(-1.0 * c);
    }
  }
  // cores without faces (points, segments): the perpendiculars from their vertices to the
  // other's edges, and the centre line (point–point)
  if (fa == 0 || fb == 0) {
    const Core& P = fa == 0 ? A : B;
    const Core& Q = fa == 0 ? B : A;
    const double sign = fa == 0 ? 1.0 : -1.0;  // the axis points from A to B
    const int eq = core_edge_count(Q);
    for (int k = 0; k < P.nv; ++k) {
      const Vec3 p = core_vertex(P, k);
      for (int j = 0; j < eq; ++j) {
        Vec3 q0, q1;
        core_edge(Q, j, q0, q1);
        const Vec3 e = q1 - q0;
        const Vec3 perp = cross(e, cross(q0 - p, e));
        test(sign * perp);
      }
    }
    test(B.x - A.x);
  }
  if (best == 1e300) best = 0.0;
  return best;
}

namespace detail {

// Sutherland–Hodgman: keeps the part of polygon p (n vertices) where f(x) = dot(k, x) - c ≥ 0.
DEMFEM_HD int clip_polygon(const Vec3* p, int n, Vec3 k, double c, Vec3* out) {
  int m = 0;
  for (int i = 0; i < n; ++i) {
    const Vec3 a = p[i], b = p[(i + 1) % n];
    const double fa = dot(k, a) - c, fb = dot(k, b) - c;
    if (fa >= 0.0) out[m++] = a;
    if ((fa >= 0.0) != (fb >= 0.0)) {
      const double t = fa / (fa - fb);
      out[m++] = a + t * (b - a);
    }
  }
  return m;
}

}  // namespace detail

/// ∫ o dA, ∫ x o dA and ∫ o u uᵀ dA (u = x − p0) over the touching region of reference face
/// `ref` (polygon r, outward unit normal nr) and incident polygon `inc` (ni vertices), for
/// o(x) = rsum − g(x), g the distance of the incident face above the reference plane (see the
/// file comment). The integrals are taken over the projection on the reference plane (o is
/// linear there: exact fan-triangle formulas). Returns the largest o on the region (−1e300
/// when it is empty).
DEMFEM_HD double touching_region(const Vec3* r, int nr_, Vec3 nr, const Vec3* inc, int ni,
                                 double rsum, Vec3 p0, double& weight, Vec3& moment,
                                 double* second) {
  Vec3 buf0[2 * kMaxFaceVertices + 2], buf1[2 * kMaxFaceVertices + 2];
  weight = 0.0;
  moment = Vec3{0, 0, 0};
  for (int k = 0; k < 6; ++k) second[k] = 0.0;
  int n = ni;
  for (int k = 0; k < ni; ++k) buf0[k] = inc[k];
  Vec3* cur = buf0;
  Vec3* nxt = buf1;
  for (int e = 0; e < nr_ && n > 0; ++e) {
    const Vec3 a = r[e], b = r[(e + 1) % nr_];
    const Vec3 k = cross(nr, b - a);  // inward side normal (loop CCW about nr)
    n = detail::clip_polygon(cur, n, k, dot(k, a), nxt);
    Vec3* t = cur;
    cur = nxt;
    nxt = t;
  }
  if (n == 0) return -1e300;
  // o ≥ 0  ⇔  nr·x ≤ nr·r0 + rsum
  const double plane = dot(nr, r[0]);
  n = detail::clip_polygon(cur, n, -1.0 * nr, -(plane + rsum), nxt);
  if (n < 3) return -1e300;
  double omax = -1e300;
  Vec3 q[2 * kMaxFaceVertices + 2];
  double o[2 * kMaxFaceVertices + 2];
  for (int k = 0; k < n; ++k) {
    const double g = dot(nr, nxt[k]) - plane;
    o[k] = rsum - g;
    q[k] = nxt[k] - g * nr;  // projected onto the reference plane
    omax = o[k] > omax ? o[k] : omax;
  }
  for (int k = 1; k + 1 < n; ++k) {
    const double area = 0.5 * dot(cross(q[k] - q[0], q[k + 1] - q[0]), nr);
    const double os = o[0] + o[k] + o[k + 1];
    weight += area * os * (1.0 / 3.0);
    const Vec3 xs = q[0] + q[k] + q[k + 1];
    const Vec3 xo = o[0] * q[0] + o[k] * q[k] + o[k + 1] * q[k + 1];
    moment = moment + (area / 12.0) * (os * xs + xo);
    // ∫ o u uᵀ over a triangle with linear o (values f_i at corners u_i), from
    // ∫ λ_i λ_j λ_k dA = A (1 + δ_ij + δ_jk + δ_ik + 2 δ_ijk) / 60:
    // A/60 (F X Xᵀ + Y Xᵀ + X Yᵀ + F Σ u_i u_iᵀ + 2 Σ f_i u_i u_iᵀ), F = Σ f_i, X = Σ u_i,
    // Y = Σ f_i u_i
    const Vec3 u0 = q[0] - p0, u1 = q[k] - p0, u2 = q[k + 1] - p0;
    const Vec3 X = u0 + u1 + u2;
    const Vec3 Y = o[0] * u0 + o[k] * u1 + o[k + 1] * u2;
    const double f[3] = {o[0], o[k], o[k + 1]};
    const Vec3 U[3] = {u0, u1, u2};
    const double a60 = area / 60.0;
    double t[6];
    t[0] = os * X.x * X.x + 2 * Y.x * X.x;
    t[1] = os * X.y * X.y + 2 * Y.y * X.y;
    t[2] = os * X.z * X.z + 2 * Y.z * X.z;
    t[3] = os * X.x * X.y + Y.x * X.y + X.x * Y.y;
    t[4] = os * X.x * X.z + Y.x * X.z + X.x * Y.z;
    t[5] = os * X.y * X.z + Y.y * X.z + X.y * Y.z;
    for (int m = 0; m < 3; ++m) {
      const double w2 = os + 2 * f[m];
      const Vec3 v = U[m];
      t[0] += w2 * v.x * v.x, t[1] += w2 * v.y * v.y, t[2] += w2 * v.z * v.z;
      t[3] += w2 * v.x * v.y, t[4] += w2 * v.x * v.z, t[5] += w2 * v.y * v.z;
    }
    for (int m = 0; m < 6; ++m) second[m] += a60 * t[m];
  }
  // the incident loop runs clockwise about nr (its outward normal opposes nr): all fan
  // triangles of the convex polygon have the same sign
  if (weight < 0.0) {
    weight = -weight, moment = -1.0 * moment;
    for (int m = 0; m < 6; ++m) second[m] = -second[m];
  }
  return omax;
}

/// Cosine above which the contact normal counts as the normal of a face (1e-3 rad).
constexpr double kFaceAlign = 1.0 - 5e-7;

/// An incident face tilted against the reference by more than kRegionTilt (15°) is left out of
/// the touching region: its part of the band o > 0 is a cap that reaches less than
/// δ / tan 15° ≈ 4 δ from its deepest vertex, so leaving it out moves the contact point by a
/// few overlaps at most (and spares clipping the faces around every vertex contact: they
/// were most of the narrow phase's time). Nearly parallel faces, whose band can span the
/// face, are always in.
constexpr double kRegionCos = 0.96592582628906828675;  // cos 15°

/// Largest vertex count of a core whose touching region is computed (larger hulls, e.g. of a
/// finely scanned rock: point contacts).
constexpr int kMaxRegionVertices = 128;

/// The touching region of the contact (A, B) with normal n (A → B): fills weight, moment and
/// second and returns the side of the reference face (0: A, 1: B) or -1 (a point contact).
/// The reference is the face of A or B whose normal is n (to kFaceAlign; A's when both are),
/// or with ref_b B's face towards A whatever the alignment (a wall triangle); the incident
/// region is summed over every face of the other body that faces the reference: their bands
/// o ≥ 0 partition the overlap of its lower envelope, so the region changes continuously
/// with the pose (no choice of one incident face).
/// When the reference face's normal is the contact normal (to kFaceAlign), `canon` is set and
/// dist_c, n_c, mid_c give the distance (the incident body's lowest vertex above the reference
/// plane), the normal (A → B) and the position along it of the midpoint between the dilated
/// surfaces, computed from the faces alone: they do not depend on the path GJK took (a face
/// resting on a face has non-unique closest points).
DEMFEM_HD int contact_region(const Core& A, const Core& B, Vec3 n, double rsum, Vec3 p0, bool ref_b,
                             double& weight, Vec3& moment, double* second, int& ref_face,
                             bool& canon, double& dist_c, Vec3& n_c, double& mid_c, double ra,
                             double rb) {
  canon = false;
  weight = 0.0;
  moment = Vec3{0, 0, 0};
  for (int k = 0; k < 6; ++k) second[k] = 0.0;
  ref_face = -1;
  if (A.kind == Core::kPoint || B.kind == Core::kPoint) return -1;
  double aa, ab;
  const int fa = core_best_face(A, n, aa);
  const int fb = core_best_face(B, -1.0 * n, ab);
  if (fa < 0 || fb < 0) return -1;
  const bool a_ref = !ref_b && aa >= kFaceAlign && aa >= ab;
  const bool b_ref = ref_b || (!a_ref && ab >= kFaceAlign);
  if (!a_ref && !b_ref) return -1;
  const bool aligned = a_ref || ab >= kFaceAlign;
  const Core& R = a_ref ? A : B;
  const Core& I = a_ref ? B : A;
  const int rf = a_ref ? fa : fb;
  if (I.nv > kMaxRegionVertices) return -1;
  const Vec3 nrm = core_face_normal(R, rf);
  const int nfi = core_face_count(I);
  const double* fn =
      I.kind == Core::kTriangle ? nullptr : I.table->fnormal + 3 * I.table->fbase[I.shape];
  Vec3 nb = nrm;  // the reference normal in I's frame (triangle: world)
  // n_g·nb of the incident faces, once for both loops below (from the columns: SIMD lanes)
  double fdot[kMaxSoa];
  const bool fcols = I.kind != Core::kTriangle && I.table->fsoa != nullptr && nfi <= kMaxSoa;
  if (I.kind != Core::kTriangle) {
    // most face-aligned contacts of rocks are a vertex on a face, with no incident face
    // within kRegionTilt: no region, found before any vertex is placed
    nb = to_body(I.r, nrm);
    bool facing = false;
    if (fcols) {
      column_dots(I.table->fsoa + I.table->fsoa_base[I.shape], soa_padded(nfi), nb, fdot);
      int nfacing = 0;
      for (int g = 0; g < nfi; ++g) nfacing += fdot[g] < -kRegionCos ? 1 : 0;
      facing = nfacing > 0;
    } else {
      for (int g = 0; g < nfi && !facing; ++g)
        facing = fn[3 * g] * nb.x + fn[3 * g + 1] * nb.y + fn[3 * g + 2] * nb.z < -kRegionCos;
    }
    if (!facing) return -1;
  }
  Vec3 rp[kMaxFaceVertices];
  const int nr = core_face_polygon(R, rf, rp);
  if (nr < 3) return -1;
  const double plane = dot(nrm, rp[0]);
  // heights of the incident body's vertices above the reference plane, from the body frame
  // (one rotation, not one per vertex); world positions only for the faces in the band
  double hv[kMaxRegionVertices];
  double h0 = -plane;
  if (I.kind == Core::kTriangle) {
    for (int k = 0; k < 3; ++k) hv[k] = dot(nrm, I.t[k]) - plane;
  } else {
    h0 = dot(nrm, I.x) - plane;
    if (I.table->vsoa != nullptr) {
      column_dots(I.table->vsoa + I.table->vsoa_base[I.shape], soa_padded(I.nv), nb, hv);
      for (int k = 0; k < I.nv; ++k) hv[k] = h0 + I.s * hv[k];
    } else {
      for (int k = 0; k < I.nv; ++k) {
        const double* p = I.v + 3 * k;
        hv[k] = h0 + I.s * (nb.x * p[0] + nb.y * p[1] + nb.z * p[2]);
      }
    }
  }
  for (int g = 0; g < nfi; ++g) {
    Vec3 ip[kMaxFaceVertices];
    int ni;
    double hmin = 1e300;
    if (I.kind == Core::kTriangle) {
      if (!(dot(core_face_normal(I, g), nrm) < -kRegionCos)) continue;
      ni = core_face_polygon(I, g, ip);
      for (int k = 0; k < 3; ++k) hmin = hv[k] < hmin ? hv[k] : hmin;
      if (hmin >= rsum) continue;
    } else {
      // faces the reference within kRegionTilt only (see there)
      const double fg =
          fcols ? fdot[g] : fn[3 * g] * nb.x + fn[3 * g + 1] * nb.y + fn[3 * g + 2] * nb.z;
      if (!(fg < -kRegionCos)) continue;
      const int gi = I.table->fbase[I.shape] + g;
      ni = I.table->flen[gi];
      if (ni > kMaxFaceVertices) continue;
      const std::int32_t* lp = I.table->fvert + I.table->floop[gi];
      for (int k = 0; k < ni; ++k) hmin = hv[lp[k]] < hmin ? hv[lp[k]] : hmin;
      if (hmin >= rsum) continue;  // the whole face is above the band
      for (int k = 0; k < ni; ++k) ip[k] = core_vertex(I, lp[k]);
    }
    double w;
    Vec3 m;
    double s2[6];
    touching_region(rp, nr, nrm, ip, ni, rsum, p0, w, m, s2);
    if (!(w > 0.0)) continue;
    weight += w;
    moment = moment + m;
    for (int k = 0; k < 6; ++k) second[k] += s2[k];
  }
  if (!(weight > 0.0)) return -1;
  ref_face = rf;
  if (aligned) {
    double hmin = 1e300;
    const int nvi = I.kind == Core::kTriangle ? 3 : I.nv;
    for (int k = 0; k < nvi; ++k) hmin = hv[k] < hmin ? hv[k] : hmin;
    canon = true;
    dist_c = hmin;
    n_c = a_ref ? nrm : -1.0 * nrm;
    mid_c = a_ref ? plane + 0.5 * (ra + hmin - rb) : -plane + 0.5 * (ra - hmin - rb);
  }
  return a_ref ? 0 : 1;
}

/// Contact of the dilated cores A (dilation ra) and B (rb): distance, normal, closest points and
/// contact point, or `separated` when Δ > ra + rb + margin is proven (margin ≥ 0). `axis`
/// (unit, A → B, or zero) is tried first: when it separates the cores by more than the
/// margin, nothing else is computed.
DEMFEM_HD ConvexContact convex_contact(const Core& A, double ra, const Core& B, double rb,
                                       double margin, Vec3 axis, bool ref_b = false,
                                       int* feat = nullptr) {
  ConvexContact c{};
  c.ref_side = -1;
  c.ref_face = -1;
  const double rsum = ra + rb;
  const double limit = rsum + margin;
  // The cached axis is tried on pairs that did not touch last time only: for a touching pair
  // (closest features cached) it is the contact normal and separates nothing, and GJK proves
  // a separation (status 0, or a distance beyond the limit) as well.
  const bool touched = feat != nullptr && feat[0] >= 0;
  // GJK's start when the axis test fails: the support pair it found, the first point GJK's
  // cold start from `axis` would find (the same bits, two support calls fewer); against a
  // triangle (a wall, whose axis is its normal), A's support vertex paired with all three
  // triangle vertices: the vertex-face simplex that GJK reached from cold in 5-7 iterations
  int start[6] = {-1, -1, -1, -1, -1, -1};
  if (!touched && norm2(axis) > 0.0) {
    int ia, ib;
    const double gap = dot(support(B, -1.0 * axis, ib), axis) - dot(support(A, axis, ia), axis);
    if (gap > limit) {
      c.separated = true;
      c.axis = axis;
      c.dist = gap;
      if (feat != nullptr)
        for (int k = 0; k < 6; ++k) feat[k] = -1;
      return c;
    }
    start[0] = ia, start[1] = ib;
    if (B.kind == Core::kTriangle)
      for (int k = 0; k < 3; ++k) start[2 * k] = ia, start[2 * k + 1] = k;
  }
  const GjkResult g = gjk_distance(A, B, limit, touched ? feat : start, axis);
  if (feat != nullptr)
    for (int k = 0; k < 3; ++k) {
      feat[2 * k] = g.status == 1 ? g.ia[k] : -1;
      feat[2 * k + 1] = g.status == 1 ? g.ib[k] : -1;
    }
  if (g.status == 0) {
    c.separated = true;
    c.axis = (-1.0 / std::sqrt(norm2(g.v))) * g.v;
    c.dist = g.dist;
    return c;
  }
  c.separated = false;
  if (g.status == 1) {
    c.dist = g.dist;
    c.n = (-1.0 / g.dist) * g.v;
    c.pa = g.pa, c.pb = g.pb;
  } else {
    Vec3 n;
    const double depth = sat_penetration(A, B, n);
    c.dist = -depth;
    c.n = n;
    int ia, ib;
    c.pa = support(A, n, ia);
    c.pb = support(B, -1.0 * n, ib);
  }
  c.axis = c.n;
  const Vec3 mid = 0.5 * (c.pa + ra * c.n + c.pb - rb * c.n);
  c.point = mid;
  if (rsum - c.dist > 0.0) {
    bool canon;
    double dist_c, mid_c;
    Vec3 n_c;
    c.ref_side = contact_region(A, B, c.n, rsum, A.x, ref_b, c.weight, c.moment, c.second,
                                c.ref_face, canon, dist_c, n_c, mid_c, ra, rb);
    if (c.ref_side >= 0) {
      const Vec3 cen = (1.0 / c.weight) * c.moment;
      // the faces' distance replaces GJK's only where they agree (the normal is the face's
      // up to rounding, not just within kFaceAlign: a nearly parallel edge is not a face)
      if (canon && g.status == 1 && std::abs(dist_c - c.dist) <= 1e-9 * (rsum + std::abs(c.dist))) {
        c.dist = dist_c;
        c.n = n_c;
        c.axis = n_c;
        c.point = cen + (mid_c - dot(n_c, cen)) * n_c;
      } else {
        c.point = cen + dot(c.n, mid - cen) * c.n;
      }
    }
  }
  return c;
}

}  // namespace demfem::dem::phys
