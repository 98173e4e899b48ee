#pragma once
// Contacts of dilated convex polyhedra (thesis §2.1.1–2.1.2, eq. 2.5, 2.20–2.24) with each
// other, with spheres and with wall triangles, shared by both backends.
//
// Contact law. Eq. 2.20, F_n = 2√2 G / (3(1 − ν)) r_d^½ δ^{3/2}, is exactly the Hertz force of
// two equal spheres of radius r_d (with E* = G / (1 − ν) and R = r_d / 2 for equal materials), so
// the law is the sphere law of physics/contact.hpp (one source) evaluated with the effective
// radius R = r_i r_j / (r_i + r_j) of the two dilation radii (a sphere's is its radius; a wall
// triangle is flat, R = r_i) and the overlap δ = r_i + r_j − Δ of eq. 2.5:
//   * normal F_n = 4/3 E* √(R δ) δ + γ_n v_n (eq. 2.20 for equal r_d and materials);
//   * tangential: the Mindlin spring with history in the contact frame, S_t = 8 G* √(R δ). For
//     equal materials and r_d this is k_t = 2 (3 G² (1 − ν) F_n r_d)^{1/3} / (2 − ν), Mindlin's
//     stiffness written with the normal force (Di Renzo & Di Maio 2004); eq. 2.22 of the thesis
//     prints it without the 3 (0.69 of Mindlin's stiffness), which we take for a typo, since
//     eq. 2.20 is Hertz's law exactly. The spring is a displacement (the force follows the
//     stiffness on unloading, as eq. 2.15 for spheres) where eq. 2.21 increments the force;
//     both agree while δ does not change;
//   * Coulomb limit |F_t| ≤ μ |F_n| (eq. 2.24);
//   * normal damping γ_n = 2 √(5/6) |β| √(S_n m*), β = ln e / √(ln² e + π²): the law has the
//     Hertz form F = k δ^{3/2}, for which this damping (Tsuji et al. 1992, docs/dem.md) gives the
//     restitution e of a contact of effective mass m*. m* is the mass of the normal relative
//     motion at the contact point, 1/m* = Σ (1/m + (r × n)·I⁻¹(r × n)) (r from the centre of
//     mass to the contact point): the two-body reduced mass m_i m_j / (m_i + m_j) of the sphere
//     law for a central contact, smaller for an eccentric one (the body turns as it is pushed).
//   * no rolling resistance: a polyhedron's shape resists rolling; μ_r of a pair acts between
//     two spheres only.
// The relative velocity is taken at the contact point c (eq. 2.23 with the lever c − x of each
// body) and the force acts there on both bodies, so linear and angular momentum are conserved
// exactly. (The sphere law uses the lever r_i n instead of c − x_i: for a point core the two
// differ by δ/2 in the tangential torque; see tests/dem/core/test_poly_dynamics.cpp.)
//
// Walls (poly_wall_contacts): each candidate triangle is a convex core (radius 0). A contact
// is classified by the triangle's feature it touches: the face when the normal is the
// triangle's normal (|n·n_t| ≥ kFaceAlign), else the edge or vertex of the triangle that is
// closest along the normal (its support feature towards the particle). Edge and vertex
// contacts follow the sphere rules (physics/wall_contact.hpp: an edge counts unless a
// triangle with that edge touches with its face, and once per edge id; a vertex counts unless
// a triangle with it touches with its face or an edge with it touches, and once per vertex
// id). A flat face of a particle can rest on several triangles at once (a rock on a floor of
// two triangles) where a sphere cannot: face contacts of triangles that share an edge and
// whose normals differ by less than kMergeAngle are one contact (transitively): its overlap
// is the deepest member's, its normal the region-weighted mean of the members' normals and its
// point the weighted centroid of the union of their touching regions (so a cube resting on
// two triangles feels one Hertz force at the middle of its face). The merged contact is
// carried by the member triangle nearest its point (flexible mesh: barycentric node split of
// that triangle, as for spheres) and keeps its tangential spring while any member stays in
// contact.

#include <cstdint>

#include "demfem/dem/physics/contact.hpp"
#include "demfem/dem/physics/narrow_phase.hpp"
#include "demfem/dem/physics/wall_contact.hpp"

namespace demfem::dem::phys {

/// Cosine of the largest angle between the normals of adjacent triangles whose face contacts
/// with one particle merge (10°: a flexible mesh bends by far less between neighbours; a
/// wall corner is far steeper).
constexpr double kMergeCos = 0.98480775301220805936;  // cos 10°
/// Touching triangles examined per polyhedron (a rock on a fine flexible mesh touches many).
constexpr int kMaxPolyWallCandidates = 48;

/// Kinematic and mass data of one body at a contact.
struct BodyState {
  Vec3 x, v, w;  ///< centre of mass, velocity, angular velocity (world)
  double m;      ///< mass
  Rot r;         ///< orientation (for the inertia)
  Vec3 inertia;  ///< principal moments; all equal for a sphere
};

/// 1 / m of the normal relative motion of a body at lever arm a along n:
/// 1/m + (a × n)·I⁻¹(a × n).
DEMFEM_HD double normal_inverse_mass(const BodyState& b, Vec3 a, Vec3 n) {
  const Vec3 an = cross(a, n);
  const Vec3 bn = to_body(b.r, an);
  return 1.0 / b.m + bn.x * bn.x / b.inertia.x + bn.y * bn.y / b.inertia.y +
         bn.z * bn.z / b.inertia.z;
}

/// Force and torques of one contact.
struct DilatedResult {
  Vec3 force;     ///< on body i (j gets −force)
  Vec3 torque_i;  ///< (c − x_i) × force
  Vec3 torque_j;  ///< (c − x_j) × (−force)
  double delta;   ///< overlap r_i + r_j − Δ, m
  double fn;      ///< normal force magnitude (damped), N
};

/// Evaluates the contact law at a contact (normal n from i to j, overlap delta, point c,
/// effective radius reff) between bodies i and j (j may be a wall: mj = nullptr, velocity vj
/// at c). `shear` is the tangential spring (history, contact frame), updated when Friction.
template <bool Friction>
DEMFEM_HD DilatedResult dilated_law(const PairConstants& pc, Vec3 n, double delta, Vec3 c,
                                    double reff, const BodyState& bi, const BodyState* bj,
                                    Vec3 vwall, Vec3& shear, double dt) {
  DilatedResult out{};
  const Vec3 ai = c - bi.x;
  double inv_m = normal_inverse_mass(bi, ai, n);
  Vec3 vrel = bi.v + cross(bi.w, ai);
  Vec3 aj{0, 0, 0};
  if (bj != nullptr) {
    aj = c - bj->x;
    inv_m += normal_inverse_mass(*bj, aj, n);
    vrel = vrel - (bj->v + cross(bj->w, aj));
  } else {
    vrel = vrel - vwall;
  }
  Vec3 roll{0, 0, 0};
  const ContactResult r = hertz_mindlin<Friction, false>(pc, n, delta, reff, 1.0 / inv_m, vrel,
                                                         Vec3{0, 0, 0}, shear, roll, dt);
  out.force = r.force;
  out.fn = r.fn;
  out.delta = delta;
  out.torque_i = cross(ai, r.force);
  out.torque_j = cross(aj, -1.0 * r.force);
  return out;
}

/// Contact of two bodies with dilated cores (polyhedron–polyhedron, polyhedron–sphere: a
/// sphere is a point core of radius r). `axis` is the per-pair separating-axis cache (unit,
/// i → j, or zero), updated. Returns false (out zero, shear reset) when they do not touch.
template <bool Friction>
DEMFEM_HD bool dilated_pair(const Core& ci, double ri, const BodyState& bi, const Core& cj,
                            double rj, const BodyState& bj, const PairConstants& pc, double dt,
                            Vec3& shear, Vec3& axis, DilatedResult& out) {
  const ConvexContact k = convex_contact(ci, ri, cj, rj, 0.0, axis);
  axis = k.axis;
  const double delta = ri + rj - k.dist;
  if (k.separated || !(delta > 0.0)) {
    out = DilatedResult{};
    shear = Vec3{0, 0, 0};
    return false;
  }
  const double reff = ri * rj / (ri + rj);
  out = dilated_law<Friction>(pc, k.n, delta, k.point, reff, bi, &bj, Vec3{0, 0, 0}, shear, dt);
  return true;
}

/// Per-particle data of the polyhedron–wall contacts beyond the sphere's WallView.
struct PolyWallParticle {
  Core core;
  double r;  ///< dilation radius
  BodyState body;
};

/// Adds the wall contact forces and torques of polyhedron i to f and q (world), fills its
/// wall slots (the sphere layout of WallView: key, spring, force, point, barycentric weights
/// and triangle per contact) and raises mo / fmo (largest overlap, with the flexible mesh).
template <bool Friction>
DEMFEM_HD void poly_wall_contacts(const PolyWallParticle& p, const WallView& w, std::int64_t i,
                                  const PairConstants* pc_row, double dt, Vec3& f, Vec3& q,
                                  double& mo, double& fmo) {
  if (w.prow[i] == w.prow[i + 1] && w.wcount[i] == 0) return;
  // the touching candidates
  std::int32_t ctri[kMaxPolyWallCandidates];
  std::int64_t ckey[kMaxPolyWallCandidates];
  int cfeat[kMaxPolyWallCandidates];  // 0 face, 1..3 edge ab/bc/ca, 4..6 vertex a/b/c
  double cdelta[kMaxPolyWallCandidates], cw[kMaxPolyWallCandidates];
  Vec3 cn[kMaxPolyWallCandidates], cpt[kMaxPolyWallCandidates], cm[kMaxPolyWallCandidates];
  int nc = 0;
  const double* v = w.vpos;
  for (std::int64_t k = w.prow[i]; k < w.prow[i + 1] && nc < kMaxPolyWallCandidates; ++k) {
    const std::int32_t tri = w.ptri[k];
    const std::int32_t* tv = w.tri_v + 3 * tri;
    const Vec3 a{v[3 * tv[0]], v[3 * tv[0] + 1], v[3 * tv[0] + 2]};
    const Vec3 b{v[3 * tv[1]], v[3 * tv[1] + 1], v[3 * tv[1] + 2]};
    const Vec3 c{v[3 * tv[2]], v[3 * tv[2] + 1], v[3 * tv[2] + 2]};
    const Core t = triangle_core(a, b, c);
    const ConvexContact k2 = convex_contact(p.core, p.r, t, 0.0, 0.0, Vec3{0, 0, 0});
    const double delta = p.r - k2.dist;
    if (k2.separated || !(delta > 0.0)) continue;
    // the triangle's feature: its face when n is its normal, else its support feature
    // towards the particle (along -n)
    const Vec3 nt = core_face_normal(t, 0);
    const double al = dot(nt, k2.n);
    int feat;
    if (al >= kFaceAlign || al <= -kFaceAlign) {
      feat = kFace;
    } else {
      const double h[3] = {-dot(a, k2.n), -dot(b, k2.n), -dot(c, k2.n)};
      const double hm = h[0] > h[1] ? (h[0] > h[2] ? h[0] : h[2]) : (h[1] > h[2] ? h[1] : h[2]);
      const double size = norm2(b - a) + norm2(c - a);
      const double tol = 1e-9 * std::sqrt(size);
      const bool top[3] = {h[0] >= hm - tol, h[1] >= hm - tol, h[2] >= hm - tol};
      const int ntop = int(top[0]) + int(top[1]) + int(top[2]);
      if (ntop >= 3)
        feat = kFace;
      else if (ntop == 2)
        feat = top[0] && top[1] ? kEdgeAB : (top[1] && top[2] ? kEdgeBC : kEdgeCA);
      else
        feat = top[0] ? kVertexA : (top[1] ? kVertexB : kVertexC);
    }
    std::int64_t key;
    if (feat == kFace)
      key = tri;
    else if (feat <= kEdgeCA)
      key = (std::int64_t{1} << kFeatureShift) | w.tri_e[3 * tri + feat - 1];
    else
      key = (std::int64_t{2} << kFeatureShift) | tv[feat - kVertexA];
    ctri[nc] = tri;
    ckey[nc] = key;
    cfeat[nc] = feat;
    cdelta[nc] = delta;
    cn[nc] = k2.n;
    cpt[nc] = k2.point;
    cw[nc] = k2.weight;
    cm[nc] = k2.moment;
    ++nc;
  }
  // edge and vertex contacts: the sphere rules (count once, and not beside a face contact)
  bool keep[kMaxPolyWallCandidates];
  for (int a = 0; a < nc; ++a) {
    keep[a] = true;
    const std::int64_t type = ckey[a] >> kFeatureShift;
    if (type == 0) continue;
    const std::int64_t fid = ckey[a] & ((std::int64_t{1} << kFeatureShift) - 1);
    for (int b = 0; b < nc && keep[a]; ++b) {
      if (b == a) continue;
      const std::int64_t tb = ckey[b] >> kFeatureShift;
      if (ckey[b] == ckey[a] && b < a) keep[a] = false;
      if (type == 1 && tb == 0) {
        for (int e = 0; e < 3; ++e)
          if (w.tri_e[3 * ctri[b] + e] == fid) keep[a] = false;
      } else if (type == 2 && tb == 0) {
        for (int e = 0; e < 3; ++e)
          if (w.tri_v[3 * ctri[b] + e] == fid) keep[a] = false;
      } else if (type == 2 && tb == 1) {
        const int fe = cfeat[b] - 1;
        const std::int32_t* tv = w.tri_v + 3 * ctri[b];
        if (tv[fe] == fid || tv[(fe + 1) % 3] == fid) keep[a] = false;
      }
    }
  }
  // face contacts of adjacent, nearly coplanar triangles: one group (label = smallest member)
  int group[kMaxPolyWallCandidates];
  for (int a = 0; a < nc; ++a) group[a] = a;
  for (bool changed = true; changed;) {
    changed = false;
    for (int a = 0; a < nc; ++a) {
      if (!keep[a] || cfeat[a] != kFace) continue;
      for (int b = a + 1; b < nc; ++b) {
        if (!keep[b] || cfeat[b] != kFace || group[a] == group[b]) continue;
        if (dot(cn[a], cn[b]) < kMergeCos) continue;
        bool adjacent = false;
        for (int e = 0; e < 3; ++e)
          for (int g = 0; g < 3; ++g)
            adjacent = adjacent || w.tri_e[3 * ctri[a] + e] == w.tri_e[3 * ctri[b] + g];
        if (!adjacent) continue;
        const int lo = group[a] < group[b] ? group[a] : group[b];
        const int hi = group[a] < group[b] ? group[b] : group[a];
        for (int k = 0; k < nc; ++k)
          if (group[k] == hi) group[k] = lo;
        changed = true;
      }
    }
  }
  std::int64_t* key = w.wkey + kMaxWallContacts * i;
  double* shr = w.wshear + 3 * kMaxWallContacts * i;
  std::int64_t okey[kMaxWallContacts];
  double osh[3 * kMaxWallContacts];
  const int oc = w.wcount[i];
  if constexpr (Friction) {
    for (int o = 0; o < oc; ++o) {
      okey[o] = key[o];
      osh[3 * o] = shr[3 * o], osh[3 * o + 1] = shr[3 * o + 1], osh[3 * o + 2] = shr[3 * o + 2];
    }
  }
  int cnt = 0;
  for (int a = 0; a < nc && cnt < kMaxWallContacts; ++a) {
    if (!keep[a] || group[a] != a) continue;  // each group once, at its first member
    // the group's deepest member, weight, normal and centroid
    int deep = a;
    double wsum = 0.0;
    Vec3 nsum{0, 0, 0}, msum{0, 0, 0};
    for (int b = a; b < nc; ++b) {
      if (!keep[b] || group[b] != a) continue;
      if (cdelta[b] > cdelta[deep]) deep = b;
      wsum += cw[b];
      nsum = nsum + cw[b] * cn[b];
      msum = msum + cm[b];
    }
    Vec3 n = cn[deep];
    Vec3 c = cpt[deep];
    if (wsum > 0.0) {
      n = (1.0 / std::sqrt(norm2(nsum))) * nsum;
      const Vec3 cen = (1.0 / wsum) * msum;
      c = cen + dot(n, cpt[deep] - cen) * n;
    }
    const double delta = cdelta[deep];
    // the carrier: the member triangle nearest the contact point
    std::int32_t tri = ctri[deep];
    ClosestPoint cpc{};
    double best = 1e300;
    for (int b = a; b < nc; ++b) {
      if (!keep[b] || group[b] != a) continue;
      const std::int32_t* tv = w.tri_v + 3 * ctri[b];
      const ClosestPoint cp =
          closest_point_triangle(c, Vec3{v[3 * tv[0]], v[3 * tv[0] + 1], v[3 * tv[0] + 2]},
                                 Vec3{v[3 * tv[1]], v[3 * tv[1] + 1], v[3 * tv[1] + 2]},
                                 Vec3{v[3 * tv[2]], v[3 * tv[2] + 1], v[3 * tv[2] + 2]});
      const double dd = norm2(cp.point - c);
      if (dd < best) best = dd, tri = ctri[b], cpc = cp;
    }
    const std::int32_t* tv = w.tri_v + 3 * tri;
    const double* vv = w.vvel;
    const Vec3 vw = cpc.u * Vec3{vv[3 * tv[0]], vv[3 * tv[0] + 1], vv[3 * tv[0] + 2]} +
                    cpc.v * Vec3{vv[3 * tv[1]], vv[3 * tv[1] + 1], vv[3 * tv[1] + 2]} +
                    cpc.w * Vec3{vv[3 * tv[2]], vv[3 * tv[2] + 1], vv[3 * tv[2] + 2]};
    // the spring of an old slot whose key is any member's
    Vec3 sh{0, 0, 0};
    std::int64_t gkey = ckey[a];
    if constexpr (Friction) {
      bool found = false;
      for (int o = 0; o < oc && !found; ++o)
        for (int b = a; b < nc && !found; ++b) {
          if (!keep[b] || group[b] != a || okey[o] != ckey[b]) continue;
          sh = Vec3{osh[3 * o], osh[3 * o + 1], osh[3 * o + 2]};
          found = true;
        }
    }
    // a face group is keyed by its carrier triangle: the next step's group finds this spring
    // while the carrier is one of its members
    if (cfeat[a] == kFace) gkey = tri;
    const DilatedResult r = dilated_law<Friction>(pc_row[w.tri_mat[tri]], n, delta, c, p.r, p.body,
                                                  nullptr, vw, sh, dt);
    f = f + r.force;
    q = q + r.torque_i;
    if constexpr (Friction) shr[3 * cnt] = sh.x, shr[3 * cnt + 1] = sh.y, shr[3 * cnt + 2] = sh.z;
    key[cnt] = gkey;
    const std::int64_t slot = kMaxWallContacts * i + cnt;
    w.wf[3 * slot] = r.force.x, w.wf[3 * slot + 1] = r.force.y, w.wf[3 * slot + 2] = r.force.z;
    w.wp[3 * slot] = c.x, w.wp[3 * slot + 1] = c.y, w.wp[3 * slot + 2] = c.z;
    w.wb[3 * slot] = cpc.u, w.wb[3 * slot + 1] = cpc.v, w.wb[3 * slot + 2] = cpc.w;
    w.wtri[slot] = tri;
    mo = mo > delta ? mo : delta;
    if (w.tri_wall[tri] < 0) fmo = fmo > delta ? fmo : delta;
    ++cnt;
  }
  w.wcount[i] = static_cast<std::uint8_t>(cnt);
}

}  // namespace demfem::dem::phys
