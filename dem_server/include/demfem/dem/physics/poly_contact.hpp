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
#include "demfem/dem/physics/smooth_contact.hpp"
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

/// The touching region of a contact for the distributed dashpot: its weight W = ∫ o dA and
/// second moment ∫ o u uᵀ dA about body i's centre (xx, yy, zz, xy, xz, yz); W = 0: a point.
struct Region {
  double weight;
  double second[6];
  Vec3 centre;  ///< ∫ x o dA / W: the pivot of the smooth law's couples (see dilated_law)
};

/// In-plane mean moment of inertia of a body about its centre for axes perpendicular to n:
/// (tr I − n·I n) / 2.
DEMFEM_HD double in_plane_inertia(const BodyState& b, Vec3 n) {
  const Vec3 nb = to_body(b.r, n);
  const double tr = b.inertia.x + b.inertia.y + b.inertia.z;
  const double nn =
      b.inertia.x * nb.x * nb.x + b.inertia.y * nb.y * nb.y + b.inertia.z * nb.z * nb.z;
  return 0.5 * (tr - nn);
}

/// Evaluates the contact law at a contact (normal n from i to j, overlap delta, point c,
/// effective radius reff) between bodies i and j (j may be a wall: bj = nullptr, velocity
/// vwall at c, spin wwall). `shear` is the tangential spring (history, contact frame),
/// updated when Friction.
///
/// Rocking. At a face contact the force acts at the overlap-weighted centre of the touching
/// region (narrow_phase.hpp), which a tilt θ shifts by about θ a² / (12 δ): a restoring couple
/// like the pressure centre of an elastic foundation, so that a cube resting on a face does
/// not rock (with the closest point instead, the force jumps from edge to edge and a cube on
/// an incline chatters and creeps: measured, docs/dem.md). The law's magnitude is Hertz's of
/// the deepest overlap, so this couple is not the gradient of the contact's energy: the
/// normal and the rocking motion are coupled unsymmetrically, and a cube sliding on a face
/// fluttered (the normal force swinging between 0.1 and 1.5 of its weight, a = 0.60 instead
/// of 0.66 m/s², measured) unless the rocking is damped. The dashpot of the law is therefore
/// spread over the region, with a couple against the relative rocking rate ω_⊥ that damps the
/// contact's rocking mode critically: −(C / j) n × (J (ω_rel × n)), J = ∫ o u uᵀ dA about c,
/// j = its mean in-plane moment, C = 2 √(K_r I_r), with the rocking stiffness K_r = S_n j / W of
/// an elastic foundation carrying S_n over the region and I_r the bodies' in-plane moment of
/// inertia about their centres (combined harmonically for two bodies). (Spread with the
/// weight of the elastic part alone, the dashpot damps the rocking by a ratio of only 0.03
/// to 0.07: not enough.) With e = 1 there is no dashpot and no such couple. The tangential
/// dashpot is spread alike: a couple −(γ_t / W) J_p (ω_rel·n) n against the twist about n
/// (J_p = ∫ o |u|² dA), at most the Coulomb couple μ |F_n| √(J_p / W), since a single point has
/// no resistance to twisting. For a point contact (W = 0) the law is the single-point law.
///
/// Smooth law (`el` not null, smooth_contact.hpp): the elastic force and torques are el's (the
/// gradient of the contact energy); n, c are el's normal and point, and the Hertz law is
/// evaluated at the overlap δ_s / g and radius R g⁵, for which its elastic force is el's
/// (F_H(δ_s) g) and its stiffness dF/dδ along n is F_H'(δ_s) g²: the dashpot (Tsuji's with that
/// stiffness, so a central impact keeps e), the tangential spring (stiffness in the same ratio
/// to it) and the Coulomb limit act at c as in the pressure-centre law. `delta` is then the
/// geometric overlap reported.
template <bool Friction>
DEMFEM_HD DilatedResult dilated_law(const PairConstants& pc, Vec3 n, double delta, Vec3 c,
                                    double reff, const BodyState& bi, const BodyState* bj,
                                    Vec3 vwall, Vec3 wwall, const Region& reg, Vec3& shear,
                                    double dt, const SmoothElastic* el = nullptr) {
  DilatedResult out{};
  const double delta_geom = delta;
  if (el != nullptr) {
    n = el->n;
    c = el->point;
    const double g2 = el->g * el->g;
    delta = el->delta_s / el->g;
    reff = reff * g2 * g2 * el->g;
  }
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
  out.delta = delta_geom;
  if (el != nullptr) {
    const Vec3 rest = r.force - el->fa;  // dashpot and tangential force, at c
    out.torque_i = el->ta + cross(ai, rest);
    out.torque_j = el->tb + cross(aj, -1.0 * rest);
  } else {
    out.torque_i = cross(ai, r.force);
    out.torque_j = cross(aj, -1.0 * r.force);
  }
  if (reg.weight > 0.0 && r.gamma_n != 0.0) {
    // second moment about c (parallel axes; its components along n do not act below). The
    // shift J_c = J_0 − W d dᵀ holds about the region's centre only: the pressure-centre law's
    // c is that centre (up to a shift along n), the smooth law's c is its terms' weighted
    // point, so the smooth law's couples pivot on the region's centre (about another point the
    // shifted moment can turn negative, and the rocking dashpot would drive the rocking).
    const double* s0 = reg.second;
    const double W = reg.weight;
    const Vec3 d = el != nullptr ? reg.centre - bi.x : ai;
    const double sxx = s0[0] - W * d.x * d.x, syy = s0[1] - W * d.y * d.y,
                 szz = s0[2] - W * d.z * d.z, sxy = s0[3] - W * d.x * d.y,
                 sxz = s0[4] - W * d.x * d.z, syz = s0[5] - W * d.y * d.z;
    const double trace = sxx + syy + szz;
    const double snn = n.x * (sxx * n.x + sxy * n.y + sxz * n.z) +
                       n.y * (sxy * n.x + syy * n.y + syz * n.z) +
                       n.z * (sxz * n.x + syz * n.y + szz * n.z);
    const double jp = trace - snn > 0.0 ? trace - snn : 0.0;  // in-plane polar moment
    const double jm = 0.5 * jp;                               // mean in-plane moment
    const Vec3 wrel = bi.w - (bj != nullptr ? bj->w : wwall);
    Vec3 td{0, 0, 0};
    if (jm > 0.0) {
      double ir = in_plane_inertia(bi, n);
      if (bj != nullptr) {
        const double ij = in_plane_inertia(*bj, n);
        ir = ir * ij / (ir + ij);
      }
      const double kr = r.sn * jm / W;
      const double cr = 2.0 * pc.rocking * std::sqrt(kr * ir);
      const Vec3 a = cross(wrel, n);
      const Vec3 sa{sxx * a.x + sxy * a.y + sxz * a.z, sxy * a.x + syy * a.y + syz * a.z,
                    sxz * a.x + syz * a.y + szz * a.z};
      td = (-cr / jm) * cross(n, sa);
    }
    if constexpr (Friction) {
      double tw = -(r.gamma_t / W) * jp * dot(wrel, n);
      const double cap = pc.friction * (r.fn > 0.0 ? r.fn : -r.fn) * std::sqrt(jp / W);
      tw = tw > cap ? cap : (tw < -cap ? -cap : tw);
      td = td + tw * n;
    }
    out.torque_i = out.torque_i + td;
    out.torque_j = out.torque_j - td;
  }
  return out;
}

/// Contact of two bodies with dilated cores (polyhedron–polyhedron, polyhedron–sphere: a
/// sphere is a point core of radius r). `axis` (unit, i → j, or zero) and `feat` (6 ints, the
/// closest features) are the pair's narrow-phase cache, updated (warm start; the result does
/// not depend on them, see gjk_distance). Returns false (out zero, shear reset) when they do
/// not touch. `slack` (may be null) gets, when the narrow phase proved them apart (no GJK
/// distance: the cached axis or GJK's lower bound), how far the dilated bodies are apart at
/// least (m), else -1.
template <bool Friction>
DEMFEM_HD bool dilated_pair(const Core& ci, double ri, const BodyState& bi, const Core& cj,
                            double rj, const BodyState& bj, const PairConstants& pc, double dt,
                            Vec3& shear, Vec3& axis, int* feat, DilatedResult& out,
                            double* slack = nullptr) {
  const ConvexContact k = convex_contact(ci, ri, cj, rj, 0.0, axis, false, feat);
  axis = k.axis;
  const double delta = ri + rj - k.dist;
  if (slack != nullptr) *slack = k.separated ? k.dist - (ri + rj) : -1.0;
  if (k.separated || !(delta > 0.0)) {
    out = DilatedResult{};
    shear = Vec3{0, 0, 0};
    return false;
  }
  const double reff = ri * rj / (ri + rj);
  Region reg{k.ref_side >= 0 ? k.weight : 0.0, {}, Vec3{0, 0, 0}};
  for (int m = 0; m < 6; ++m) reg.second[m] = k.second[m];
  if (pc.law == kLawSmooth && ci.kind != Core::kPoint && cj.kind != Core::kPoint && k.dist > 0.0) {
    if (reg.weight > 0.0) reg.centre = (1.0 / reg.weight) * k.moment;  // the couples' pivot
    SmoothSum sum;
    SmoothElastic el;
    if (smooth_pair_sum(ci, ri, cj, rj, k.pa, k.pb, bi.x, bj.x, sum) &&
        smooth_elastic(sum, pc.e_star, reff, el)) {
      out = dilated_law<Friction>(pc, k.n, delta, k.point, reff, bi, &bj, Vec3{0, 0, 0},
                                  Vec3{0, 0, 0}, reg, shear, dt, &el);
      return true;
    }
  }
  out = dilated_law<Friction>(pc, k.n, delta, k.point, reff, bi, &bj, Vec3{0, 0, 0}, Vec3{0, 0, 0},
                              reg, shear, dt);
  return true;
}

/// Per-particle data of the polyhedron–wall contacts beyond the sphere's WallView.
struct PolyWallParticle {
  Core core;
  double r;  ///< dilation radius
  BodyState body;
};

/// Read-only view of the particle arrays of a system with polyhedra (host or device).
struct PolyView {
  ParticleView p;  ///< positions, velocities, angular velocities, radius, mass
  const double *qw, *qx, *qy, *qz;
  const double *ix, *iy, *iz;  ///< principal moments
  const double* inertia;       ///< spheres' moment
  const double* scale;
  const std::int32_t* shape_id;  ///< -1: sphere
  ShapeTableView table;
  /// 9 per particle: rotation(q) of each polyhedron, formed once per step by the caller so
  /// that the pairs do not form it again (null: formed per pair from the quaternion).
  const double* rot = nullptr;
};

/// The convex core of particle i (a sphere: its centre).
DEMFEM_HD Core particle_core(const PolyView& v, int i) {
  const Vec3 x{v.p.px[i], v.p.py[i], v.p.pz[i]};
  if (v.shape_id[i] < 0) return point_core(x);
  if (v.rot != nullptr)
    return polyhedron_core(v.table, v.shape_id[i], x, v.rot + 9 * i, v.scale[i]);
  return polyhedron_core(v.table, v.shape_id[i], x, v.qw[i], v.qx[i], v.qy[i], v.qz[i], v.scale[i]);
}

/// The contact radius of particle i: a sphere's radius, a polyhedron's dilation.
DEMFEM_HD double particle_contact_radius(const PolyView& v, int i) {
  return v.shape_id[i] >= 0 ? v.scale[i] * v.table.dilation[v.shape_id[i]] : v.p.radius[i];
}

/// Kinematics and mass of particle i (c: its core, for the orientation).
DEMFEM_HD BodyState particle_body(const PolyView& v, int i, const Core& c) {
  BodyState b;
  b.x = Vec3{v.p.px[i], v.p.py[i], v.p.pz[i]};
  b.v = Vec3{v.p.vx[i], v.p.vy[i], v.p.vz[i]};
  b.w = Vec3{v.p.wx[i], v.p.wy[i], v.p.wz[i]};
  b.m = v.p.mass[i];
  if (v.shape_id[i] >= 0) {
    b.r = c.r;
    b.inertia = Vec3{v.ix[i], v.iy[i], v.iz[i]};
  } else {
    b.r = Rot{{1, 0, 0, 0, 1, 0, 0, 0, 1}};
    b.inertia = Vec3{v.inertia[i], v.inertia[i], v.inertia[i]};
  }
  return b;
}

/// One pair (i, j) of a system with polyhedra: two spheres by the sphere law (rolling
/// resistance included), else the dilated law after the bounding spheres (particle radius)
/// overlap. Fills the force on i and the torques on i and j; updates the spring, the
/// rolling history (sphere pairs), the axis and feature caches. Returns the overlap (0: no
/// contact). `slack` (may be null) gets a distance by which the pair is proven apart, less a
/// margin for rounding (the gap of the bounding spheres, or dilated_pair's), else -1: while
/// the two bodies move by less in sum, this function gives no contact and changes no cache.
/// Periodic (`box` not null): j is taken at its image nearest to i (periodic_image.hpp).
template <bool Friction>
DEMFEM_HD double mixed_pair(const PolyView& v, int i, int j, const PairConstants& c, double dt,
                            bool rolling, Vec3& shear, Vec3& rhist, Vec3& axis, int* feat,
                            Vec3& force, Vec3& ti, Vec3& tj, double* slack = nullptr,
                            const PeriodicBox* box = nullptr) {
  double delta = 0.0;
  force = ti = tj = Vec3{0, 0, 0};
  if (v.shape_id[i] < 0 && v.shape_id[j] < 0) {
    ContactResult r;
    if (box != nullptr && rolling)
      sphere_sphere_select<Friction, true, true>(v.p, i, j, c, dt, shear, rhist, r, delta, box);
    else if (box != nullptr)
      sphere_sphere_select<Friction, false, true>(v.p, i, j, c, dt, shear, rhist, r, delta, box);
    else if (rolling)
      sphere_sphere_select<Friction, true>(v.p, i, j, c, dt, shear, rhist, r, delta);
    else
      sphere_sphere_select<Friction, false>(v.p, i, j, c, dt, shear, rhist, r, delta);
    force = r.force;
    ti = v.p.radius[i] * r.torque + r.roll;
    tj = v.p.radius[j] * r.torque - 1.0 * r.roll;
    return delta;
  }
  double dx = v.p.px[j] - v.p.px[i], dy = v.p.py[j] - v.p.py[i], dz = v.p.pz[j] - v.p.pz[i];
  Vec3 xj{v.p.px[j], v.p.py[j], v.p.pz[j]};  // j's image nearest to i
  if (box != nullptr) {
    const Vec3 s{image_shift(*box, 0, dx), image_shift(*box, 1, dy), image_shift(*box, 2, dz)};
    xj = xj + s;
    dx += s.x, dy += s.y, dz += s.z;
  }
  const double rs = v.p.radius[i] + v.p.radius[j];
  // rounding of the proofs below (positions, support points): far below 1e-9 of the scale
  const double eps = 1e-9 * (rs + std::abs(v.p.px[i]) + std::abs(v.p.py[i]) + std::abs(v.p.pz[i]) +
                             std::abs(xj.x) + std::abs(xj.y) + std::abs(xj.z));
  const double d2 = dx * dx + dy * dy + dz * dz;
  if (!(d2 < rs * rs)) {
    shear = Vec3{0, 0, 0};
    if (slack != nullptr) *slack = std::sqrt(d2) - rs - eps;
    return 0.0;
  }
  const Core ci = particle_core(v, i);
  Core cj = particle_core(v, j);
  BodyState bj = particle_body(v, j, cj);
  cj.x = xj, bj.x = xj;
  DilatedResult r;
  if (dilated_pair<Friction>(ci, particle_contact_radius(v, i), particle_body(v, i, ci), cj,
                             particle_contact_radius(v, j), bj, c, dt, shear, axis, feat, r,
                             slack)) {
    force = r.force, ti = r.torque_i, tj = r.torque_j, delta = r.delta;
  }
  if (slack != nullptr && *slack >= 0.0) *slack -= eps;
  return delta;
}

/// The wall-contact data of polyhedron i.
DEMFEM_HD PolyWallParticle poly_wall_particle(const PolyView& v, int i) {
  PolyWallParticle w;
  w.core = particle_core(v, i);
  w.r = particle_contact_radius(v, i);
  w.body = particle_body(v, i, w.core);
  return w;
}

/// The feature of triangle abc (normal nt) at a contact of normal n: its face when n is its
/// normal, else its support feature towards the particle (along -n).
DEMFEM_HD int triangle_contact_feature(Vec3 a, Vec3 b, Vec3 c, Vec3 nt, Vec3 n) {
  const double al = dot(nt, n);
  if (al >= kFaceAlign || al <= -kFaceAlign) return kFace;
  const double h[3] = {-dot(a, n), -dot(b, n), -dot(c, n)};
  const double hm = h[0] > h[1] ? (h[0] > h[2] ? h[0] : h[2]) : (h[1] > h[2] ? h[1] : h[2]);
  const double tol = 1e-9 * std::sqrt(norm2(b - a) + norm2(c - a));
  const bool top[3] = {h[0] >= hm - tol, h[1] >= hm - tol, h[2] >= hm - tol};
  const int ntop = int(top[0]) + int(top[1]) + int(top[2]);
  if (ntop >= 3) return kFace;
  if (ntop == 2) return top[0] && top[1] ? kEdgeAB : (top[1] && top[2] ? kEdgeBC : kEdgeCA);
  return top[0] ? kVertexA : (top[1] ? kVertexB : kVertexC);
}

/// The triangles that touch a polyhedron (poly_wall_contacts), and how they group into
/// contacts. Per touching triangle: overlap, normal, point, touching region (the triangle as
/// the reference face) and the triangle's feature the contact is at.
struct PolyWallTouches {
  int count = 0;
  std::int32_t tri[kMaxPolyWallCandidates];
  int feature[kMaxPolyWallCandidates];  // 0 face, 1..3 edge ab/bc/ca, 4..6 vertex a/b/c
  double delta[kMaxPolyWallCandidates], weight[kMaxPolyWallCandidates];
  double second[kMaxPolyWallCandidates][6];
  Vec3 n[kMaxPolyWallCandidates], point[kMaxPolyWallCandidates], moment[kMaxPolyWallCandidates];
  Vec3 pa[kMaxPolyWallCandidates], pb[kMaxPolyWallCandidates];  // closest core points
  double dist[kMaxPolyWallCandidates];
  int group[kMaxPolyWallCandidates];  // label of each touch's contact: its smallest member
  bool keep[kMaxPolyWallCandidates];  // false: the group is shadowed by a face contact
};

/// Vertex k of triangle tri of the wall store.
DEMFEM_HD Vec3 wall_vertex(const WallView& w, std::int32_t tri, int k) {
  const std::int32_t u = w.tri_v[3 * tri + k];
  return Vec3{w.vpos[3 * u], w.vpos[3 * u + 1], w.vpos[3 * u + 2]};
}

/// The candidate triangles of polyhedron i that touch it, into t (first the face normal of
/// each triangle is tried as the separating axis).
DEMFEM_HD void poly_wall_touches(const PolyWallParticle& p, const WallView& w, std::int64_t i,
                                 PolyWallTouches& t) {
  int nc = 0;
  const double* v = w.vpos;
  for (std::int64_t k = w.prow[i]; k < w.prow[i + 1] && nc < kMaxPolyWallCandidates; ++k) {
    const std::int32_t tri = w.ptri[k];
    const std::int32_t* tv = w.tri_v + 3 * tri;
    const Vec3 a{v[3 * tv[0]], v[3 * tv[0] + 1], v[3 * tv[0] + 2]};
    const Vec3 b{v[3 * tv[1]], v[3 * tv[1] + 1], v[3 * tv[1] + 2]};
    const Vec3 c{v[3 * tv[2]], v[3 * tv[2] + 1], v[3 * tv[2] + 2]};
    const Core tc = triangle_core(a, b, c);
    // the triangle's normal towards the particle's centre, turned to point from the particle
    // to the triangle, is the first axis tried: it rejects a triangle whose plane the
    // particle's lowest point is more than r_d above, and it starts GJK at the lowest point
    Vec3 nt0 = cross(b - a, c - a);
    nt0 = (dot(nt0, p.core.x - a) > 0.0 ? -1.0 : 1.0) / std::sqrt(norm2(nt0)) * nt0;
    const ConvexContact k2 = convex_contact(p.core, p.r, tc, 0.0, 0.0, nt0, true);
    const double delta = p.r - k2.dist;
    if (k2.separated || !(delta > 0.0)) continue;
    t.tri[nc] = tri;
    t.feature[nc] = triangle_contact_feature(a, b, c, core_face_normal(tc, 0), k2.n);
    t.delta[nc] = delta;
    t.n[nc] = k2.n;
    t.point[nc] = k2.point;
    t.weight[nc] = k2.ref_side >= 0 ? k2.weight : 0.0;
    t.moment[nc] = k2.moment;
    t.pa[nc] = k2.pa, t.pb[nc] = k2.pb, t.dist[nc] = k2.dist;
    for (int m = 0; m < 6; ++m) t.second[nc][m] = k2.second[m];
    ++nc;
  }
  t.count = nc;
}

/// Groups: triangles sharing a vertex (transitively) whose contact normals differ by less than
/// kMergeAngle are one contact (label = smallest member); their touching regions partition the
/// overlap (each is clipped to its own triangle).
DEMFEM_HD void group_poly_wall_touches(const WallView& w, PolyWallTouches& t) {
  const int nc = t.count;
  int* group = t.group;
  for (int a = 0; a < nc; ++a) group[a] = a;
  for (bool changed = true; changed;) {
    changed = false;
    for (int a = 0; a < nc; ++a)
      for (int b = a + 1; b < nc; ++b) {
        if (group[a] == group[b] || dot(t.n[a], t.n[b]) < kMergeCos) continue;
        bool adjacent = false;
        for (int e = 0; e < 3; ++e)
          for (int g = 0; g < 3; ++g)
            adjacent = adjacent || w.tri_v[3 * t.tri[a] + e] == w.tri_v[3 * t.tri[b] + g];
        if (!adjacent) continue;
        const int lo = group[a] < group[b] ? group[a] : group[b];
        const int hi = group[a] < group[b] ? group[b] : group[a];
        for (int k = 0; k < nc; ++k)
          if (group[k] == hi) group[k] = lo;
        changed = true;
      }
  }
}

/// A group of edge and vertex contacts only is dropped (keep = false) when one of its edges or
/// vertices belongs to a triangle touching with its face in another group (the sphere rule:
/// the face contact is that contact).
DEMFEM_HD void drop_shadowed_poly_wall_groups(const WallView& w, PolyWallTouches& t) {
  const int nc = t.count;
  const int* group = t.group;
  const int* cfeat = t.feature;
  for (int a = 0; a < nc; ++a) t.keep[a] = true;
  for (int a = 0; a < nc; ++a) {
    if (group[a] != a) continue;
    bool has_face = false;
    for (int b = a; b < nc; ++b) has_face = has_face || (group[b] == a && cfeat[b] == kFace);
    if (has_face) continue;
    bool shadowed = false;
    for (int b = a; b < nc && !shadowed; ++b) {
      if (group[b] != a) continue;
      const std::int32_t* tb = w.tri_v + 3 * t.tri[b];
      for (int o = 0; o < nc && !shadowed; ++o) {
        if (group[o] == a || cfeat[o] != kFace) continue;
        const std::int32_t* to = w.tri_v + 3 * t.tri[o];
        if (cfeat[b] <= kEdgeCA) {  // the edge's two vertices both on the face triangle
          const int e0 = cfeat[b] - 1;
          const std::int32_t u0 = tb[e0], u1 = tb[(e0 + 1) % 3];
          int hits = 0;
          for (int g = 0; g < 3; ++g) hits += (to[g] == u0) + (to[g] == u1);
          shadowed = hits == 2;
        } else {
          const std::int32_t u = tb[cfeat[b] - kVertexA];
          for (int g = 0; g < 3; ++g) shadowed = shadowed || to[g] == u;
        }
      }
    }
    if (shadowed)
      for (int b = a; b < nc; ++b)
        if (group[b] == a) t.keep[b] = false;
  }
}

/// The contact of group a (label a) as one: its deepest member, the touching region summed over
/// the members, and from it the normal n and the point c (the deepest member's where no member
/// has a region).
DEMFEM_HD int poly_wall_group_region(const PolyWallTouches& t, int a, Region& reg, Vec3& n,
                                     Vec3& c) {
  int deep = a;
  reg = Region{0.0, {0, 0, 0, 0, 0, 0}, Vec3{0, 0, 0}};
  Vec3 nsum{0, 0, 0}, msum{0, 0, 0};
  for (int b = a; b < t.count; ++b) {
    if (t.group[b] != a) continue;
    if (t.delta[b] > t.delta[deep]) deep = b;
    reg.weight += t.weight[b];
    nsum = nsum + t.weight[b] * t.n[b];
    msum = msum + t.moment[b];
    if (t.weight[b] > 0.0)
      for (int m = 0; m < 6; ++m) reg.second[m] += t.second[b][m];
  }
  n = t.n[deep];
  c = t.point[deep];
  if (reg.weight > 0.0) {
    n = (1.0 / std::sqrt(norm2(nsum))) * nsum;
    const Vec3 cen = (1.0 / reg.weight) * msum;
    c = cen + dot(n, t.point[deep] - cen) * n;
    reg.centre = cen;
  }
  return deep;
}

/// True when group a's contact takes the smooth law (el: its elastic part): the law asks for
/// it, the particle is a polyhedron, every member is apart from the core and the rock's
/// vertices see enough of the overlap delta.
DEMFEM_HD bool smooth_poly_wall_group(const PolyWallParticle& p, const WallView& w,
                                      const PolyWallTouches& t, int a, const PairConstants& pcw,
                                      double delta, SmoothElastic& el) {
  if (!(pcw.law == kLawSmooth && p.core.kind == Core::kPolyhedron)) return false;
  // the group's members, their closest pairs (all at positive distance)
  Vec3 gt[3 * kMaxPolyWallCandidates], gpa[kMaxPolyWallCandidates], gpb[kMaxPolyWallCandidates];
  int m = 0;
  bool apart = true;
  for (int b = a; b < t.count; ++b) {
    if (t.group[b] != a) continue;
    for (int e = 0; e < 3; ++e) gt[3 * m + e] = wall_vertex(w, t.tri[b], e);
    gpa[m] = t.pa[b], gpb[m] = t.pb[b];
    apart = apart && t.dist[b] > 0.0;
    ++m;
  }
  SmoothSum sum;
  // the wall's own edges and vertices have no terms (smooth_wall_sum): where the group's
  // deepest point is one of them in the rock's face, the rock's vertices see less than the
  // overlap, and the pressure-centre law takes the contact
  return apart && smooth_wall_sum(p.core, p.r, p.body.x, gt, gpa, gpb, m, sum) &&
         smooth_elastic(sum, pcw.e_star, p.r, el) && el.delta_s >= kSmoothWallFloor * delta;
}

/// The carrier of group a's contact at point c: the member triangle nearest c (the first of
/// equally near ones), and c's closest point on it in cpc.
DEMFEM_HD std::int32_t poly_wall_carrier(const WallView& w, const PolyWallTouches& t, int a,
                                         int deep, Vec3 c, ClosestPoint& cpc) {
  std::int32_t tri = t.tri[deep];
  cpc = ClosestPoint{};
  double best = 1e300;
  for (int b = a; b < t.count; ++b) {
    if (t.group[b] != a) continue;
    const ClosestPoint cp = closest_point_triangle(
        c, wall_vertex(w, t.tri[b], 0), wall_vertex(w, t.tri[b], 1), wall_vertex(w, t.tri[b], 2));
    const double dd = norm2(cp.point - c);
    if (dd < best) best = dd, tri = t.tri[b], cpc = cp;
  }
  return tri;
}

/// Adds the wall contact forces and torques of polyhedron i to f and q (world), fills its
/// wall slots (the sphere layout of WallView: key, spring, force, point, barycentric weights
/// and triangle per contact) and raises mo / fmo (largest overlap, with the flexible mesh).
template <bool Friction>
DEMFEM_HD void poly_wall_contacts(const PolyWallParticle& p, const WallView& w, std::int64_t i,
                                  const PairConstants* pc_row, double dt, Vec3& f, Vec3& q,
                                  double& mo, double& fmo) {
  if (w.prow[i] == w.prow[i + 1] && w.wcount[i] == 0) return;
  PolyWallTouches t;
  poly_wall_touches(p, w, i, t);
  group_poly_wall_touches(w, t);
  drop_shadowed_poly_wall_groups(w, t);
  const int nc = t.count;
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
    if (!t.keep[a] || t.group[a] != a) continue;  // each group once, at its first member
    Region reg;
    Vec3 n, c;
    const int deep = poly_wall_group_region(t, a, reg, n, c);
    const double delta = t.delta[deep];
    const PairConstants& pcw = pc_row[w.tri_mat[t.tri[deep]]];
    SmoothElastic el;
    const bool smooth = smooth_poly_wall_group(p, w, t, a, pcw, delta, el);
    if (smooth) c = el.point;  // the force's point: the carrier's and the record's
    ClosestPoint cpc;
    const std::int32_t tri = poly_wall_carrier(w, t, a, deep, c, cpc);
    const std::int32_t* tv = w.tri_v + 3 * tri;
    const double* vv = w.vvel;
    const Vec3 vw = cpc.u * Vec3{vv[3 * tv[0]], vv[3 * tv[0] + 1], vv[3 * tv[0] + 2]} +
                    cpc.v * Vec3{vv[3 * tv[1]], vv[3 * tv[1] + 1], vv[3 * tv[1] + 2]} +
                    cpc.w * Vec3{vv[3 * tv[2]], vv[3 * tv[2] + 1], vv[3 * tv[2] + 2]};
    // the spring: of the old slot keyed by any member triangle (a group is keyed by its
    // deepest member)
    Vec3 sh{0, 0, 0};
    if constexpr (Friction) {
      bool found = false;
      for (int o = 0; o < oc && !found; ++o)
        for (int b = a; b < nc && !found; ++b) {
          if (t.group[b] != a || okey[o] != t.tri[b]) continue;
          sh = Vec3{osh[3 * o], osh[3 * o + 1], osh[3 * o + 2]};
          found = true;
        }
    }
    const std::int32_t wall = w.tri_wall[tri];
    const Vec3 ww =
        w.motion != nullptr && wall >= 0 ? rigid_spin(w.motion[wall], w.time) : Vec3{0, 0, 0};
    // the law of the carrier's material; under the smooth law the deepest member's, whose
    // stiffness el holds (a group of mixed materials)
    const DilatedResult r =
        dilated_law<Friction>(smooth ? pcw : pc_row[w.tri_mat[tri]], n, delta, c, p.r, p.body,
                              nullptr, vw, ww, reg, sh, dt, smooth ? &el : nullptr);
    f = f + r.force;
    q = q + r.torque_i;
    if constexpr (Friction) shr[3 * cnt] = sh.x, shr[3 * cnt + 1] = sh.y, shr[3 * cnt + 2] = sh.z;
    key[cnt] = t.tri[deep];
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
