#pragma once
// The smooth contact law of dilated polyhedra (`poly_law = "smooth"`, docs/polyhedra.md,
// "Energy"): eq. 2.20's Hertz energy U_H(δ_s) of an overlap δ_s that is a smooth maximum over
// the overlaps of the two cores' feature pairs, with the force and torques its exact gradient.
// Shared by both backends.
//
// Why. The overlap of eq. 2.5, δ = r_i + r_j − Δ, is not differentiable where two closest
// features tie (an edge turning parallel to a face, a face parallel to a face): the force
// jumps from one end of the edge to the other, and a symplectic integrator loses energy at
// each such crossing in proportion to Δt (measured: docs/polyhedra.md). Each feature pair's
// own overlap is smooth; their maximum is not. So the law takes
//
//   δ_s^p = Σ_a P_a + Σ_b Q'_b + Σ_(e,f) χ_ef S(M_ef, P_e0 + P_e1 + Q'_f0 + Q'_f1),
//   Q'_b = S(Q_b, Σ_a V_ab),
//
// p = 4 (kSmoothPower), with
//
//   * P_a = δ(a, B)^p: vertex a of A against the whole core B (the distance of a point to a
//     convex set is C¹: its closest point is unique);
//   * Q_b = δ(b, A)^p: vertex b of B against core A, less the vertex–vertex overlaps
//     V_ab = δ(a, b)^p, which P_a already holds (a vertex on a vertex counts once);
//   * M_ef = δ(e, f)^p: edge e of A against edge f of B (segment distance), less its end
//     vertices' terms (as they count: B's after their own subtraction): it counts only where the
//     edges cross inside both (an edge–edge contact), not where its closest point is an end (a
//     vertex contact, already counted), nor near parallel edges (where the segment distance has a
//     kink: there the ends' terms carry it; χ_ef fades the term out between 2° and 0.5° from
//     parallel, kParallelHi);
//   * S(M, E) = M u²(3 − 2u), u = (M − E)/M clipped to [0, 1]: a C¹ "M less E, not below 0".
//
// δ_s equals δ wherever one feature pair is closest and the others are clear of it (a vertex
// on a face, two crossing edges, a vertex on an edge); where k features tie it is k^{1/p} δ
// (an edge pressed flat on a face: 1.19 δ; a face on a face by its four corners: 1.41 δ, and
// δ_s grows k^{1/p} times as fast as δ, so the force is k^{5/8} times eq. 2.20's at δ, 2.38
// for four corners: a stiffer contact, as a flat punch is stiffer than a sphere); the subtraction S
// lets it fall at most 2.5 % below δ where an edge's crossing nears an end, and the fade of nearly
// parallel edges a few per cent (kParallelHi).
// The energy is C¹ in the poses of both bodies, so velocity Verlet and NO_SQUISH conserve it
// to second order. Each term's gradient is a force along its own closest-point line, so linear
// and angular momentum are conserved exactly. Only the elastic force comes from δ_s: the
// dashpot, the tangential spring and the Coulomb limit act at one contact point with the
// stiffness of the smooth law (poly_contact.hpp, dilated_law).
//
// A point core (a sphere) has unique closest points: the law is then eq. 2.20 on Δ itself
// (the single term P or Q), the sphere limit unchanged. Cores that touch or intersect (an
// overlap deeper than r_i + r_j) fall back to the pressure-centre law.

#include "demfem/dem/physics/narrow_phase.hpp"

namespace demfem::dem::phys {

/// Exponent p of the smooth maximum: a tie of k features is k^{1/p} times deeper. The smaller
/// p, the wider the ties are smoothed (over |δ_1 − δ_2| ≲ δ / p) and the better the integrator
/// resolves them, the stiffer a tie. Measured (bench/poly_energy, docs/polyhedra.md): p = 4
/// holds the gas of rocks to the drift of spheres at 0.1 Δt_R, p = 8 does not.
constexpr int kSmoothPower = 4;
/// Most vertices of one body within the contact band (more: the pressure-centre law).
constexpr int kMaxSmoothBand = 24;
/// The least δ_s / δ of a wall contact under the smooth law (more shallow: the pressure-centre
/// law). Between two bodies every feature has its terms and δ_s ≥ 0.975 δ (test "the overlap
/// against eq. 2.5"); against a wall only the rock's vertices have (smooth_wall_sum), so where
/// a convex wall edge or corner is the deepest point in a rock's face (a ridge, a box's outer
/// edge, a bent flexible mesh) δ_s falls short of δ, to nothing where no vertex is near.
constexpr double kSmoothWallFloor = 0.975;

DEMFEM_HD double smooth_pow(double x) {  // x^p
  const double x2 = x * x;
  return x2 * x2;
}
DEMFEM_HD double smooth_dpow(double x) {  // p x^{p−1}
  return 4.0 * x * x * x;
}

/// Σ of the terms and its gradient in the poses: ∂Σ/∂x_A (= −∂Σ/∂x_B), ∂Σ/∂θ_A, ∂Σ/∂θ_B (small
/// rotations about the centres), and the positive weights of the terms' contact points.
struct SmoothSum {
  double sum;
  Vec3 g, ta, tb;
  double wsum;
  Vec3 wpt;
};

DEMFEM_HD SmoothSum smooth_sum_zero() {
  return SmoothSum{0.0, Vec3{0, 0, 0}, Vec3{0, 0, 0}, Vec3{0, 0, 0}, 0.0, Vec3{0, 0, 0}};
}

/// The overlap of one feature pair with closest core points pa (on A) and pb (on B):
/// δ = rsum − |pb − pa|, n = (pb − pa) / |pb − pa|.
struct FeatureOverlap {
  double delta;
  Vec3 n, pa, pb;
};

DEMFEM_HD FeatureOverlap feature_overlap(Vec3 pa, Vec3 pb, double rsum) {
  FeatureOverlap o;
  const Vec3 d = pb - pa;
  const double l = std::sqrt(norm2(d));
  o.delta = rsum - l;
  o.n = l > 0.0 ? (1.0 / l) * d : Vec3{0, 0, 0};
  o.pa = pa;
  o.pb = pb;
  return o;
}

/// Adds coef · ∂δ/∂(poses) of one feature overlap to s (δ grows when A moves along n or
/// turns its point pa along n). The contact point of the term (the midpoint between the
/// dilated surfaces) joins the weighted point when coef > 0.
DEMFEM_HD void smooth_add_gradient(SmoothSum& s, const FeatureOverlap& o, double coef, Vec3 xa,
                                   Vec3 xb, double ra, double rb) {
  s.g = s.g + coef * o.n;
  s.ta = s.ta + coef * cross(o.pa - xa, o.n);
  s.tb = s.tb - coef * cross(o.pb - xb, o.n);
  if (coef > 0.0) {
    s.wsum += coef;
    s.wpt = s.wpt + coef * (0.5 * (o.pa + ra * o.n + o.pb - rb * o.n));
  }
}

/// S(M, E) of the file comment with ∂S/∂M and ∂S/∂E.
struct SmoothClip {
  double s, dm, de;
};

DEMFEM_HD SmoothClip smooth_clip(double m, double e) {
  SmoothClip c{0.0, 0.0, 0.0};
  if (!(m > 0.0)) return c;
  const double u = (m - e) / m;
  if (!(u > 0.0)) return c;
  c.s = m * u * u * (3.0 - 2.0 * u);
  c.dm = u * (6.0 - 9.0 * u + 4.0 * u * u);
  c.de = -6.0 * u * (1.0 - u);
  return c;
}

/// Edges closer to parallel than kParallelHi (2°) count less, none below kParallelLo (0.5°):
/// where two edges are nearly parallel their crossing point runs along them fast as they turn,
/// and their segment distance bends sharply (it has a kink at parallel); the overlap there is
/// carried by the ends' vertex terms, short of it by at most (s sin θ)² / (2 (r_i + r_j)) at a
/// crossing s from the nearest end (6 % of a 0.1 r_d overlap for s = 5 mm at 2°, r_d = 2 mm).
/// χ is a smoothstep in x = sin²θ, so its derivative is a couple (exact, conservative).
constexpr double kParallelLo = 7.6152421804e-05;  // sin² 0.5°
constexpr double kParallelHi = 1.2179748700e-03;  // sin² 2°

struct ParallelFade {
  double chi, dchi;  ///< χ(x) and dχ/dx
};

DEMFEM_HD ParallelFade parallel_fade(double x) {
  const double w = kParallelHi - kParallelLo;
  const double t = (x - kParallelLo) / w;
  if (!(t > 0.0)) return ParallelFade{0.0, 0.0};
  if (t >= 1.0) return ParallelFade{1.0, 0.0};
  return ParallelFade{t * t * (3.0 - 2.0 * t), 6.0 * t * (1.0 - t) / w};
}

/// The vertices of core c with d·x > hmin (world positions and indices), at most cap; returns
/// the count, or -1 when there are more.
DEMFEM_HD int band_vertices(const Core& c, Vec3 d, double hmin, int* idx, Vec3* pos, int cap) {
  int n = 0;
  if (c.kind != Core::kPolyhedron) {
    for (int k = 0; k < c.nv; ++k) {
      const Vec3 x = core_vertex(c, k);
      if (!(dot(d, x) > hmin)) continue;
      if (n == cap) return -1;
      idx[n] = k, pos[n] = x, ++n;
    }
    return n;
  }
  const Vec3 db = to_body(c.r, d);
  const double h0 = dot(d, c.x);
  for (int k = 0; k < c.nv; ++k) {
    const double* v = c.v + 3 * k;
    const double h = h0 + c.s * (v[0] * db.x + v[1] * db.y + v[2] * db.z);
    if (!(h > hmin)) continue;
    if (n == cap) return -1;
    idx[n] = k, pos[n] = core_vertex(c, k), ++n;
  }
  return n;
}

/// The closest point q of core c to point p when |p − q| < limit: returns 1, 0 when proven
/// farther than limit, 2 when p lies in the core.
DEMFEM_HD int point_core_closest(Vec3 p, const Core& c, double limit, Vec3& q) {
  if (c.kind == Core::kPoint) {
    q = c.x;
    return norm2(p - q) < limit * limit ? 1 : 0;
  }
  if (c.kind == Core::kTriangle) {
    q = closest_point_triangle(p, c.t[0], c.t[1], c.t[2]).point;
    const double d2 = norm2(p - q);
    return d2 < limit * limit ? (d2 > 0.0 ? 1 : 2) : 0;
  }
  const GjkResult g = gjk_distance(point_core(p), c, limit);
  if (g.status != 1) return g.status;
  q = g.pb;
  return g.dist < limit ? 1 : 0;
}

/// The slot of vertex k in a band list, -1 when not in it.
DEMFEM_HD int band_slot(const int* idx, int n, int k) {
  for (int s = 0; s < n; ++s)
    if (idx[s] == k) return s;
  return -1;
}

/// Most edges of one body with an end in the contact band (more: the pressure-centre law).
constexpr int kMaxSmoothEdges = 64;

/// An edge of a core with an end in the band: its ends' band slots (-1: not in the band) and
/// world positions, and the box [lo, hi] of its part inside the band.
struct BandEdge {
  int s0, s1;
  Vec3 p0, p1;
  Vec3 lo, hi;
};

/// The edges of core c with an end among its band vertices (indices idx, positions pos, n of
/// them), at most cap; returns the count, or -1 when there are more. The band is d·x > hmin
/// (band_vertices); each edge's box bounds its part in the band, where any point of it within
/// reach of the other body lies (smooth_pair_sum).
DEMFEM_HD int band_edges(const Core& c, const int* idx, const Vec3* pos, int n, Vec3 d, double hmin,
                         BandEdge* out, int cap) {
  int m = 0;
  const int ne = core_edge_count(c);
  for (int e = 0; e < ne; ++e) {
    int a, b;
    core_edge_vertices(c, e, a, b);
    const int s0 = band_slot(idx, n, a), s1 = band_slot(idx, n, b);
    if (s0 < 0 && s1 < 0) continue;
    if (m == cap) return -1;
    BandEdge& be = out[m++];
    be.s0 = s0, be.s1 = s1;
    be.p0 = s0 >= 0 ? pos[s0] : core_vertex(c, a);
    be.p1 = s1 >= 0 ? pos[s1] : core_vertex(c, b);
    // the end outside the band moved to where the edge leaves it (h = hmin)
    Vec3 c0 = be.p0, c1 = be.p1;
    const double h0 = dot(d, c0), h1 = dot(d, c1);
    if (s0 < 0 && h1 > h0) c0 = c1 + ((h1 - hmin) / (h1 - h0)) * (c0 - c1);
    if (s1 < 0 && h0 > h1) c1 = c0 + ((h0 - hmin) / (h0 - h1)) * (c1 - c0);
    be.lo = Vec3{c0.x < c1.x ? c0.x : c1.x, c0.y < c1.y ? c0.y : c1.y, c0.z < c1.z ? c0.z : c1.z};
    be.hi = Vec3{c0.x > c1.x ? c0.x : c1.x, c0.y > c1.y ? c0.y : c1.y, c0.z > c1.z ? c0.z : c1.z};
  }
  return m;
}

/// Whether the boxes of two band edges come closer than `reach` along every axis (a pair
/// farther apart along one axis is farther than reach).
DEMFEM_HD bool band_boxes_near(const BandEdge& a, const BandEdge& b, double reach) {
  return a.lo.x < b.hi.x + reach && b.lo.x < a.hi.x + reach && a.lo.y < b.hi.y + reach &&
         b.lo.y < a.hi.y + reach && a.lo.z < b.hi.z + reach && b.lo.z < a.hi.z + reach;
}

/// Adds coef · ∂Q'_b/∂(poses) to s: Q'_b = S(Q_b, Σ_a V_ab) of B's vertex b (overlap fb with
/// core A; S's derivatives dm, de; A's band vertices va[0..na)), the term itself (coef 1) or
/// an edge term's end (coef its ∂/∂E).
DEMFEM_HD void smooth_add_q_gradient(SmoothSum& s, const FeatureOverlap& fb, double dm, double de,
                                     const Vec3* va, int na, double coef, double rsum, Vec3 xa,
                                     Vec3 xb, double ra, double rb) {
  smooth_add_gradient(s, fb, coef * dm * smooth_dpow(fb.delta), xa, xb, ra, rb);
  for (int j = 0; j < na; ++j) {
    const FeatureOverlap v = feature_overlap(va[j], fb.pb, rsum);
    if (v.delta > 0.0) smooth_add_gradient(s, v, coef * de * smooth_dpow(v.delta), xa, xb, ra, rb);
  }
}

/// The terms of the pair (A, B) (dilations ra, rb) into s, given a closest pair (pa, pb) of the
/// cores at positive distance (GJK's). Returns false when the law does not apply (the cores
/// touch, or a band holds more than kMaxSmoothBand vertices or kMaxSmoothEdges edges): the
/// caller takes the pressure-centre law. xa, xb: the centres the torques are taken about.
DEMFEM_HD bool smooth_pair_sum(const Core& A, double ra, const Core& B, double rb, Vec3 pa, Vec3 pb,
                               Vec3 xa, Vec3 xb, SmoothSum& s) {
  s = smooth_sum_zero();
  const double rsum = ra + rb;
  const FeatureOverlap o0 = feature_overlap(pa, pb, rsum);
  if (!(rsum - o0.delta > 0.0)) return false;
  const Vec3 n0 = o0.n;
  // A point x of A within rsum of B has n0·(pa − x) < δ0 (B lies beyond the plane n0·y =
  // n0·pb); so do B's. The band is widened by a rounding margin: a vertex in it by mistake
  // only adds a term of zero.
  const double tol = 1e-9 * (rsum + std::sqrt(norm2(pa)) + std::sqrt(norm2(pb)));
  int ia[kMaxSmoothBand], ib[kMaxSmoothBand];
  Vec3 va[kMaxSmoothBand], vb[kMaxSmoothBand];
  const double hmin_a = dot(n0, pa) - o0.delta - tol, hmin_b = -dot(n0, pb) - o0.delta - tol;
  const int na = band_vertices(A, n0, hmin_a, ia, va, kMaxSmoothBand);
  const int nb = band_vertices(B, -1.0 * n0, hmin_b, ib, vb, kMaxSmoothBand);
  if (na < 0 || nb < 0) return false;
  // P_a: A's vertices against B
  FeatureOverlap fa[kMaxSmoothBand], fb[kMaxSmoothBand];
  // P: A's terms; Q: B's terms after the vertex–vertex subtraction, with its ∂/∂Q, ∂/∂ΣV
  double P[kMaxSmoothBand], Q[kMaxSmoothBand], Qdm[kMaxSmoothBand], Qde[kMaxSmoothBand];
  for (int k = 0; k < na; ++k) {
    Vec3 q;
    const int st = point_core_closest(va[k], B, rsum, q);
    if (st == 2) return false;
    P[k] = 0.0;
    fa[k].delta = 0.0;
    if (st == 0) continue;
    fa[k] = feature_overlap(va[k], q, rsum);
    if (!(fa[k].delta > 0.0)) continue;
    P[k] = smooth_pow(fa[k].delta);
    s.sum += P[k];
    smooth_add_gradient(s, fa[k], smooth_dpow(fa[k].delta), xa, xb, ra, rb);
  }
  // Q_b: B's vertices against A, less the vertex–vertex overlaps
  for (int k = 0; k < nb; ++k) {
    Vec3 q;
    const int st = point_core_closest(vb[k], A, rsum, q);
    if (st == 2) return false;
    Q[k] = Qdm[k] = Qde[k] = 0.0;
    fb[k].delta = 0.0;
    if (st == 0) continue;
    fb[k] = feature_overlap(q, vb[k], rsum);
    if (!(fb[k].delta > 0.0)) continue;
    double e = 0.0;
    for (int j = 0; j < na; ++j) {
      const FeatureOverlap v = feature_overlap(va[j], vb[k], rsum);
      if (v.delta > 0.0) e += smooth_pow(v.delta);
    }
    const SmoothClip c = smooth_clip(smooth_pow(fb[k].delta), e);
    if (!(c.s > 0.0)) continue;
    Q[k] = c.s, Qdm[k] = c.dm, Qde[k] = c.de;
    s.sum += c.s;
    smooth_add_q_gradient(s, fb[k], c.dm, c.de, va, na, 1.0, rsum, xa, xb, ra, rb);
  }
  // M_ef: edges of A against edges of B, each with an end in its band. Two points within rsum
  // of each other lie in the bands (see above), so a pair whose in-band parts are farther than
  // rsum apart along an axis has no overlap: skipped before the segment distance.
  BandEdge ea[kMaxSmoothEdges], eb[kMaxSmoothEdges];
  const int nea = band_edges(A, ia, va, na, n0, hmin_a, ea, kMaxSmoothEdges);
  const int neb = band_edges(B, ib, vb, nb, -1.0 * n0, hmin_b, eb, kMaxSmoothEdges);
  if (nea < 0 || neb < 0) return false;
  const double reach = rsum + tol;
  for (int e = 0; e < nea; ++e) {
    const int sa0 = ea[e].s0, sa1 = ea[e].s1;
    const Vec3 p0 = ea[e].p0, p1 = ea[e].p1;
    for (int f = 0; f < neb; ++f) {
      if (!band_boxes_near(ea[e], eb[f], reach)) continue;
      const int sb0 = eb[f].s0, sb1 = eb[f].s1;
      const Vec3 q0 = eb[f].p0, q1 = eb[f].p1;
      Vec3 c1, c2;
      detail::closest_segments(p0, p1, q0, q1, c1, c2);
      const FeatureOverlap m = feature_overlap(c1, c2, rsum);
      if (!(m.delta > 0.0)) continue;
      if (!(rsum - m.delta > 0.0)) return false;  // the edges touch: the cores intersect
      double e_sum = 0.0;
      const int ends_a[2] = {sa0, sa1}, ends_b[2] = {sb0, sb1};
      for (int t = 0; t < 2; ++t) {
        if (ends_a[t] >= 0) e_sum += P[ends_a[t]];
        if (ends_b[t] >= 0) e_sum += Q[ends_b[t]];
      }
      const double mv = smooth_pow(m.delta);
      const SmoothClip c = smooth_clip(mv, e_sum);
      if (!(c.s > 0.0)) continue;
      // the fade of nearly parallel edges, χ(sin²θ) (see kParallelLo)
      const Vec3 ua = p1 - p0, ub = q1 - q0;
      const double la2 = norm2(ua), lb2 = norm2(ub);
      const Vec3 axb = cross(ua, ub);
      const double x = norm2(axb) / (la2 * lb2);
      const ParallelFade pf = parallel_fade(x);
      if (!(pf.chi > 0.0)) continue;
      s.sum += pf.chi * c.s;
      smooth_add_gradient(s, m, pf.chi * c.dm * smooth_dpow(m.delta), xa, xb, ra, rb);
      for (int t = 0; t < 2; ++t) {
        if (ends_a[t] >= 0 && P[ends_a[t]] > 0.0)
          smooth_add_gradient(s, fa[ends_a[t]], pf.chi * c.de * smooth_dpow(fa[ends_a[t]].delta),
                              xa, xb, ra, rb);
        const int kb = ends_b[t];
        if (kb >= 0 && Q[kb] > 0.0)  // B's end as it counts: after its own subtraction
          smooth_add_q_gradient(s, fb[kb], Qdm[kb], Qde[kb], va, na, pf.chi * c.de, rsum, xa, xb,
                                ra, rb);
      }
      if (pf.dchi != 0.0) {
        // ∂x/∂θ_A = −2 (â·b̂)(â × b̂), ∂x/∂θ_B = −∂x/∂θ_A: a couple
        const double inv = 1.0 / std::sqrt(la2 * lb2);
        const Vec3 dx = (-2.0 * dot(ua, ub) * inv * inv) * axb;
        const double k = c.s * pf.dchi;
        s.ta = s.ta + k * dx;
        s.tb = s.tb - k * dx;
      }
    }
  }
  return s.sum > 0.0 && s.wsum > 0.0;
}

/// The terms of particle A (dilation ra, centre xa) against a group of m wall triangles that
/// are one contact (poly_contact.hpp, poly_wall_contacts: adjacent, nearly parallel), given
/// each member's closest pair (pa[k] on A, pb[k] on the triangle) at positive distance: P_a of
/// every vertex of A in some member's band against the union of the members (the nearest
/// member; a flat or convex union has C¹ distance). A wall triangle's own vertices and edges
/// add no terms: a flat or concave wall touches a rock only with the rock's vertices (see
/// docs/polyhedra.md for the convex wall edges this leaves to the rock's vertices).
DEMFEM_HD bool smooth_wall_sum(const Core& A, double ra, Vec3 xa, const Vec3* tri, const Vec3* pa,
                               const Vec3* pb, int m, SmoothSum& s) {
  s = smooth_sum_zero();
  int ia[kMaxSmoothBand];
  Vec3 va[kMaxSmoothBand];
  int na = 0;
  for (int k = 0; k < m; ++k) {
    const FeatureOverlap o0 = feature_overlap(pa[k], pb[k], ra);
    if (!(ra - o0.delta > 0.0)) return false;
    const double tol = 1e-9 * (ra + std::sqrt(norm2(pa[k])) + std::sqrt(norm2(pb[k])));
    int ik[kMaxSmoothBand];
    Vec3 vk[kMaxSmoothBand];
    const int nk =
        band_vertices(A, o0.n, dot(o0.n, pa[k]) - o0.delta - tol, ik, vk, kMaxSmoothBand);
    if (nk < 0) return false;
    for (int j = 0; j < nk; ++j) {
      if (band_slot(ia, na, ik[j]) >= 0) continue;
      if (na == kMaxSmoothBand) return false;
      ia[na] = ik[j], va[na] = vk[j], ++na;
    }
  }
  const Vec3 xb{0, 0, 0};
  for (int j = 0; j < na; ++j) {
    double best = 1e300;
    Vec3 q{0, 0, 0};
    for (int k = 0; k < m; ++k) {
      const Vec3 c =
          closest_point_triangle(va[j], tri[3 * k], tri[3 * k + 1], tri[3 * k + 2]).point;
      const double d2 = norm2(c - va[j]);
      if (d2 < best) best = d2, q = c;
    }
    if (!(best > 0.0)) return false;
    const FeatureOverlap o = feature_overlap(va[j], q, ra);
    if (!(o.delta > 0.0)) continue;
    s.sum += smooth_pow(o.delta);
    smooth_add_gradient(s, o, smooth_dpow(o.delta), xa, xb, ra, 0.0);
  }
  return s.sum > 0.0 && s.wsum > 0.0;
}

/// The elastic part of the smooth law from the terms' sum: overlap δ_s, the gradient's length
/// g = |∂δ_s/∂x_A| and direction n (the normal, A → B), the force on A and the torques on A and
/// B (exact gradient of U_H(δ_s) = 8/15 E* √R δ_s^{5/2}), and the contact point of the
/// dissipative part (the terms' points weighted by their gradient).
struct SmoothElastic {
  double delta_s, g;
  Vec3 n, point, fa, ta, tb;
};

DEMFEM_HD bool smooth_elastic(const SmoothSum& s, double e_star, double reff, SmoothElastic& out) {
  if (!(s.sum > 0.0)) return false;
  const double ds = std::sqrt(std::sqrt(s.sum));     // Σ^{1/4}
  const double kappa = ds / (kSmoothPower * s.sum);  // ∂δ_s/∂Σ
  const Vec3 grad = kappa * s.g;
  const double g = std::sqrt(norm2(grad));
  if (!(g > 1e-3)) return false;
  const double fh = (4.0 / 3.0) * e_star * std::sqrt(reff * ds) * ds;
  out.delta_s = ds;
  out.g = g;
  out.n = (1.0 / g) * grad;
  out.point = (1.0 / s.wsum) * s.wpt;
  out.fa = (-fh) * grad;
  out.ta = (-fh * kappa) * s.ta;
  out.tb = (-fh * kappa) * s.tb;
  return true;
}

}  // namespace demfem::dem::phys
