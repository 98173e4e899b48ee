// Narrow phase of dilated polyhedra (physics/narrow_phase.hpp) against brute force.

#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <random>

#include "core/shape_table.hpp"
#include "demfem/dem/physics/narrow_phase.hpp"
#include "poly_test_util.hpp"

using namespace demfem::dem;
using namespace demfem::dem::test;
using phys::Vec3;

namespace {

// ---- brute force, independent of the engine's geometry ----------------------------------

double dist_point_segment(Vec3 p, Vec3 a, Vec3 b, Vec3& q) {
  const Vec3 e = b - a;
  const double ee = phys::norm2(e);
  double t = ee > 0 ? phys::dot(p - a, e) / ee : 0.0;
  t = std::clamp(t, 0.0, 1.0);
  q = a + t * e;
  return std::sqrt(phys::norm2(p - q));
}

// point–triangle: the plane projection when it falls inside, else the nearest edge point
double dist_point_triangle(Vec3 p, Vec3 a, Vec3 b, Vec3 c, Vec3& q) {
  const Vec3 n = phys::cross(b - a, c - a);
  const double nn = phys::norm2(n);
  const Vec3 pr = p - (phys::dot(p - a, n) / nn) * n;
  const double u = phys::dot(phys::cross(b - pr, c - pr), n),
               v = phys::dot(phys::cross(c - pr, a - pr), n),
               w = phys::dot(phys::cross(a - pr, b - pr), n);
  if (u >= 0 && v >= 0 && w >= 0) {
    q = pr;
    return std::sqrt(phys::norm2(p - q));
  }
  Vec3 q1, q2, q3;
  const double d1 = dist_point_segment(p, a, b, q1), d2 = dist_point_segment(p, b, c, q2),
               d3 = dist_point_segment(p, c, a, q3);
  if (d1 <= d2 && d1 <= d3) return q = q1, d1;
  if (d2 <= d3) return q = q2, d2;
  return q = q3, d3;
}

// segment–segment: the interior critical point of non-parallel lines, and the four
// endpoint–segment distances
double dist_segment_segment(Vec3 a0, Vec3 a1, Vec3 b0, Vec3 b1, Vec3& qa, Vec3& qb) {
  double best = 1e300;
  Vec3 t1, t2;
  auto take = [&](double d, Vec3 x, Vec3 y) {
    if (d < best) best = d, qa = x, qb = y;
  };
  take(dist_point_segment(a0, b0, b1, t1), a0, t1);
  take(dist_point_segment(a1, b0, b1, t1), a1, t1);
  take(dist_point_segment(b0, a0, a1, t2), t2, b0);
  take(dist_point_segment(b1, a0, a1, t2), t2, b1);
  const Vec3 u = a1 - a0, v = b1 - b0, w = a0 - b0;
  const double A = phys::dot(u, u), B = phys::dot(u, v), C = phys::dot(v, v), D = phys::dot(u, w),
               E = phys::dot(v, w);
  const double den = A * C - B * B;
  if (den > 1e-14 * A * C) {
    const double s = (B * E - C * D) / den, t = (A * E - B * D) / den;
    if (s > 0 && s < 1 && t > 0 && t < 1) {
      const Vec3 x = a0 + s * u, y = b0 + t * v;
      take(std::sqrt(phys::norm2(x - y)), x, y);
    }
  }
  return best;
}

struct World;
struct World {
  std::vector<Vec3> v;
  std::vector<std::array<int, 3>> tri;
  std::vector<std::array<int, 2>> edge;
};

World world_of(const PolyhedronShape& s, const phys::Core& c) {
  World w;
  for (std::size_t k = 0; k < s.vertices.size() / 3; ++k)
    w.v.push_back(phys::core_vertex(c, static_cast<int>(k)));
  for (std::size_t t = 0; t < s.triangles.size() / 3; ++t) {
    w.tri.push_back({s.triangles[3 * t], s.triangles[3 * t + 1], s.triangles[3 * t + 2]});
    for (int e = 0; e < 3; ++e)
      w.edge.push_back({s.triangles[3 * t + e], s.triangles[3 * t + (e + 1) % 3]});
  }
  if (w.v.size() == 2) w.edge.push_back({0, 1});
  return w;
}

// whether segment pq crosses triangle abc
bool segment_crosses_triangle(Vec3 p, Vec3 q, Vec3 a, Vec3 b, Vec3 c) {
  const Vec3 n = phys::cross(b - a, c - a);
  const double sp = phys::dot(n, p - a), sq = phys::dot(n, q - a);
  if ((sp > 0 && sq > 0) || (sp < 0 && sq < 0) || sp == sq) return false;
  const Vec3 x = p + (sp / (sp - sq)) * (q - p);
  const double u = phys::dot(phys::cross(b - x, c - x), n),
               v = phys::dot(phys::cross(c - x, a - x), n),
               w = phys::dot(phys::cross(a - x, b - x), n);
  return u >= 0 && v >= 0 && w >= 0;
}

double outside(const struct World& A, Vec3 p);

// brute-force minimum over vertex–triangle, triangle–vertex, edge–edge (and vertex–vertex,
// vertex–edge for cores without faces); qa, qb the minimising points
double brute_distance(const World& A, const World& B, Vec3& qa, Vec3& qb) {
  double best = 1e300;
  Vec3 x, y;
  auto take = [&](double d, Vec3 p, Vec3 q) {
    if (d < best) best = d, qa = p, qb = q;
  };
  for (const auto& p : A.v)
    for (const auto& t : B.tri)
      take(dist_point_triangle(p, B.v[t[0]], B.v[t[1]], B.v[t[2]], y), p, y);
  for (const auto& p : B.v)
    for (const auto& t : A.tri)
      take(dist_point_triangle(p, A.v[t[0]], A.v[t[1]], A.v[t[2]], x), x, p);
  for (const auto& e : A.edge)
    for (const auto& f : B.edge)
      take(dist_segment_segment(A.v[e[0]], A.v[e[1]], B.v[f[0]], B.v[f[1]], x, y), x, y);
  for (const auto& p : A.v) {
    for (const auto& q : B.v) take(std::sqrt(phys::norm2(p - q)), p, q);
    for (const auto& f : B.edge) take(dist_point_segment(p, B.v[f[0]], B.v[f[1]], y), p, y);
  }
  for (const auto& q : B.v)
    for (const auto& e : A.edge) take(dist_point_segment(q, A.v[e[0]], A.v[e[1]], x), x, q);
  // intersecting cores: an edge crosses a triangle, or one core holds the other
  for (const auto& e : A.edge)
    for (const auto& t : B.tri)
      if (segment_crosses_triangle(A.v[e[0]], A.v[e[1]], B.v[t[0]], B.v[t[1]], B.v[t[2]])) best = 0;
  for (const auto& e : B.edge)
    for (const auto& t : A.tri)
      if (segment_crosses_triangle(B.v[e[0]], B.v[e[1]], A.v[t[0]], A.v[t[1]], A.v[t[2]])) best = 0;
  if ((!B.tri.empty() && outside(B, A.v[0]) < 0) || (!A.tri.empty() && outside(A, B.v[0]) < 0))
    best = 0;
  return best;
}

// how far p lies outside the hull (largest distance above a triangle plane; points: distance)
double outside(const World& A, Vec3 p) {
  if (A.tri.empty()) {
    if (A.v.size() == 1) return std::sqrt(phys::norm2(p - A.v[0]));
    Vec3 q;
    return dist_point_segment(p, A.v[0], A.v[1], q);
  }
  double m = -1e300;
  for (const auto& t : A.tri) {
    Vec3 n = phys::cross(A.v[t[1]] - A.v[t[0]], A.v[t[2]] - A.v[t[0]]);
    n = (1.0 / std::sqrt(phys::norm2(n))) * n;
    m = std::max(m, phys::dot(n, p - A.v[t[0]]));
  }
  return m;
}

// rotation taking unit a onto unit b (quaternion w, x, y, z)
std::array<double, 4> align(Vec3 a, Vec3 b) {
  const Vec3 c = phys::cross(a, b);
  const double d = phys::dot(a, b);
  if (d < -1 + 1e-12) {  // opposite: half turn about any perpendicular axis
    Vec3 p = std::abs(a.x) < 0.9 ? phys::cross(a, Vec3{1, 0, 0}) : phys::cross(a, Vec3{0, 1, 0});
    p = (1.0 / std::sqrt(phys::norm2(p))) * p;
    return {0, p.x, p.y, p.z};
  }
  const double w = 1 + d;
  const double l = std::sqrt(w * w + phys::norm2(c));
  return {w / l, c.x / l, c.y / l, c.z / l};
}

std::array<double, 4> axis_angle(Vec3 u, double th) {
  const double s = std::sin(th / 2);
  return {std::cos(th / 2), s * u.x, s * u.y, s * u.z};
}

phys::Core pose(const detail::ShapeTable& tab, const phys::ShapeTableView& view, int shape, Vec3 x,
                std::array<double, 4> q) {
  (void)tab;
  return phys::polyhedron_core(view, shape, x, q[0], q[1], q[2], q[3], 1.0);
}

using Shapes = ShapeSet;

Shapes make_shapes() {
  std::vector<PolyhedronShape> list;
  std::mt19937_64 rng(11);
  list.push_back(box_shape(0.01, 0.007, 0.005, 0.001));
  list.push_back(box_shape(0.006, 0.006, 0.006, 0.0005));
  PolyhedronShape tet;
  tet.name = "tetrahedron";
  tet.vertices = {0.01, 0.01, 0.01, -0.01, -0.01, 0.01, -0.01, 0.01, -0.01, 0.01, -0.01, -0.01};
  tet.triangles = brute_hull(tet.vertices);
  tet.dilation = 0.001, tet.volume = 1e-6, tet.inertia = {1e-11, 1e-11, 1e-11};
  list.push_back(tet);
  for (int k = 0; k < 6; ++k)
    list.push_back(random_rock(rng, 7 + 2 * k, 0.012, 0.008 - 0.0005 * k, 0.005, 0.001));
  list.push_back(point_shape(0.004));
  PolyhedronShape seg = point_shape(0.002);
  seg.vertices = {-0.005, 0, 0, 0.005, 0, 0};
  list.push_back(seg);
  return shape_set(std::move(list));
}

struct Checked {
  int separated = 0, touching = 0, penetrating = 0;
  double worst_dist = 0, worst_diff = 0, worst_out = 0;
};

// One pair: GJK against brute force (tolerance 1e-10 m on the distance, on the difference
// vector p_B - p_A (unique for convex bodies) and on how far p_A, p_B lie outside their own
// cores: then p_A, p_B are closest points, whichever pair of them GJK found where they are not
// unique); intersecting cores: the SAT depth moves them apart exactly.
void check_pair(const Shapes& S, int ia, Vec3 xa, std::array<double, 4> qa, int ib, Vec3 xb,
                std::array<double, 4> qb, Checked& out) {
  const phys::Core A = pose(S.table, S.view, ia, xa, qa);
  const phys::Core B = pose(S.table, S.view, ib, xb, qb);
  const World WA = world_of(S.list[ia], A), WB = world_of(S.list[ib], B);
  Vec3 qa0, qb0;
  const double bf = brute_distance(WA, WB, qa0, qb0);
  const bool intersect = bf < 1e-12 || (outside(WA, xb) < 0 && !WA.tri.empty());
  const phys::GjkResult g = phys::gjk_distance(A, B, 1e300);
  if (g.status == 1 && bf > 1e-9) {
    ++out.touching;
    const double ed = std::abs(g.dist - bf);
    const Vec3 dv = (g.pb - g.pa) - (qb0 - qa0);
    const double ev = std::sqrt(phys::norm2(dv));
    const double eo = std::max(outside(WA, g.pa), outside(WB, g.pb));
    out.worst_dist = std::max(out.worst_dist, ed);
    out.worst_diff = std::max(out.worst_diff, ev);
    out.worst_out = std::max(out.worst_out, eo);
    if (ed > 1e-10 || ev > 1e-10 || eo > 1e-10) {
      INFO("shapes " << ia << ", " << ib << ": gjk " << g.dist << " brute " << bf << " diff " << ev
                     << " outside " << eo);
      CHECK(false);
    }
    // the contact query agrees: separated exactly when Δ > r_A + r_B
    const double ra = S.list[ia].dilation, rb = S.list[ib].dilation;
    const phys::ConvexContact c = phys::convex_contact(A, ra, B, rb, 0.0, Vec3{0, 0, 0});
    if (bf > ra + rb + 1e-12) CHECK(c.separated);
    if (bf < ra + rb - 1e-12) {
      CHECK(!c.separated);
      CHECK(std::abs(c.dist - bf) <= 1e-10);
    }
  } else if (g.status == 2 || bf <= 1e-9) {
    if (bf > 1e-9) {
      INFO("GJK reports intersection at brute-force distance " << bf);
      CHECK(false);
      return;
    }
    (void)intersect;
    ++out.penetrating;
    // SAT depth: B moved by depth + eps along n is at distance eps from A; no direction of a
    // sample of 200 gives a smaller overlap
    Vec3 n;
    const double depth = phys::sat_penetration(A, B, n);
    const double eps = 1e-5;
    const phys::Core B2 = pose(S.table, S.view, ib, xb + (depth + eps) * n, qb);
    const World WB2 = world_of(S.list[ib], B2);
    Vec3 u0, u1;
    const double d2 = brute_distance(WA, WB2, u0, u1);
    CHECK(std::abs(d2 - eps) <= 1e-10);
    std::mt19937_64 rng(static_cast<unsigned>(ia * 131 + ib));
    for (int k = 0; k < 200; ++k) {
      const auto q = random_quaternion(rng);
      const Vec3 u{q[1], q[2], q[3]};
      const Vec3 d = (1.0 / std::sqrt(phys::norm2(u))) * u;
      int i0, i1;
      const double o =
          phys::dot(phys::support(A, d, i0), d) - phys::dot(phys::support(B, -1.0 * d, i1), d);
      CHECK(o >= depth - 1e-12);
    }
  } else {
    ++out.separated;
  }
}

}  // namespace

TEST_CASE("Narrow phase: GJK distance, normal and closest points agree with brute force",
          "[dem][poly][narrow]") {
  // Independent reference: the minimum over all vertex–triangle, triangle–vertex and edge–edge
  // distances (own point–triangle and segment–segment routines). Tolerance 1e-10 m on the
  // distance, the difference of the closest points and the closest points' distance from
  // their own core (1e-10 m in 1-2 cm bodies: about 1e-8 relative). Random pairs of 11 shapes
  // (boxes, a tetrahedron, random hulls of 7-17 vertices, a point and a segment core) in
  // random poses, plus posed cases: parallel faces, faces tilted by 1e-12-1e-3 rad, edge on
  // face. DEMFEM_NARROW_PAIRS sets the count (default 10^4; the documented run: 10^5).
  const Shapes S = make_shapes();
  const int nshape = static_cast<int>(S.list.size());
  long pairs = 10000;
  if (const char* e = std::getenv("DEMFEM_NARROW_PAIRS")) pairs = std::atol(e);
  std::mt19937_64 rng(2024);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  std::uniform_int_distribution<int> pick(0, nshape - 1);
  Checked c;
  for (long k = 0; k < pairs; ++k) {
    const int ia = pick(rng), ib = pick(rng);
    const auto qa = random_quaternion(rng);
    auto qb = random_quaternion(rng);
    const Vec3 xa{0.001 * U(rng), 0.001 * U(rng), 0.001 * U(rng)};
    const double ra = S.table.bound(ia), rb = S.table.bound(ib);
    Vec3 xb;
    const int kind = static_cast<int>(k % 4);
    const phys::Core A0 = pose(S.table, S.view, ia, xa, qa);
    if (kind <= 1 || phys::core_face_count(A0) == 0) {
      // random direction and centre distance
      const auto r = random_quaternion(rng);
      Vec3 u{r[1], r[2], r[3]};
      u = (1.0 / std::sqrt(phys::norm2(u))) * u;
      xb = xa + (0.3 + 0.9 * U(rng)) * (ra + rb) * u;
    } else {
      // a face of B laid on a face of A (parallel), spun about the normal, shifted sideways,
      // tilted by 0 or 10^-12..10^-3 rad, at gap 0..2 mm
      const int fa = static_cast<int>(U(rng) * phys::core_face_count(A0));
      const Vec3 na = phys::core_face_normal(A0, fa);
      const phys::Core B0 = pose(S.table, S.view, ib, Vec3{0, 0, 0}, {1, 0, 0, 0});
      if (phys::core_face_count(B0) > 0) {
        const int fb = static_cast<int>(U(rng) * phys::core_face_count(B0));
        const Vec3 nb = phys::core_face_normal(B0, fb);
        qb = align(nb, -1.0 * na);
        qb = quat_mul(axis_angle(na, 6.28 * U(rng)), qb);
        if (kind == 3) {
          const auto r = random_quaternion(rng);
          Vec3 t = phys::cross(na, Vec3{r[1], r[2], r[3]});
          t = (1.0 / std::sqrt(phys::norm2(t))) * t;
          qb = quat_mul(axis_angle(t, std::pow(10.0, -12.0 + 9.0 * U(rng))), qb);
        }
        // B's lowest point along na at `gap` above A's face plane; B's face centre above A's
        // face centre, shifted sideways
        Vec3 pa[phys::kMaxFaceVertices], pb[phys::kMaxFaceVertices];
        const int na_ = phys::core_face_polygon(A0, fa, pa);
        const phys::Core B1 = pose(S.table, S.view, ib, Vec3{0, 0, 0}, qb);
        const int nb_ = phys::core_face_polygon(B1, fb, pb);
        Vec3 fc{0, 0, 0}, bc{0, 0, 0};
        for (int m = 0; m < na_; ++m) fc = fc + (1.0 / na_) * pa[m];
        for (int m = 0; m < nb_; ++m) bc = bc + (1.0 / nb_) * pb[m];
        int idx;
        const Vec3 low = phys::support(B1, -1.0 * na, idx);
        const double gap = 0.002 * U(rng) * U(rng);
        const auto r = random_quaternion(rng);
        Vec3 side = phys::cross(na, Vec3{r[1], r[2], r[3]});
        side = (0.3 * (ra + rb) * U(rng) / std::sqrt(phys::norm2(side))) * side;
        const Vec3 lat = fc + side - bc;
        xb = lat - phys::dot(na, lat) * na + (phys::dot(na, pa[0]) + gap - phys::dot(na, low)) * na;
      } else {
        xb = xa + (ra + rb) * na;
      }
    }
    check_pair(S, ia, xa, qa, ib, xb, qb, c);
  }
  INFO("separated " << c.separated << " distance " << c.touching << " intersecting "
                    << c.penetrating);
  CHECK(c.touching > pairs / 4);
  CHECK(c.penetrating > 0);
  WARN("narrow phase, " << pairs << " pairs: " << c.touching << " distances, " << c.penetrating
                        << " intersecting; worst |Δ - Δ_bf| " << c.worst_dist
                        << " m, worst |d - d_bf| " << c.worst_diff << " m, worst outside "
                        << c.worst_out << " m");
}

TEST_CASE("Narrow phase: a face on a face puts the contact point at the middle of the overlap",
          "[dem][poly][narrow]") {
  // Reference: geometry. A box (half sides 10, 7, 5 mm, r_d 1 mm) resting face down on a
  // larger box, shifted sideways by (3, -2) mm: the touching region is the intersection of
  // the two faces, a rectangle whose centre is known; the contact point lies there, in the
  // middle of the overlap (z = top of the lower core + r_d - δ/2... the midpoint of the
  // dilated surfaces). Tilting the upper box by θ about y moves the point towards its lower
  // edge by θ a² / (12 δ) (linear overlap over the face width a) while the region stays whole.
  // Tolerance 1e-12 m (closed forms).
  detail::ShapeTable tab;
  tab.add(box_shape(0.01, 0.007, 0.005, 0.001));
  tab.add(box_shape(0.03, 0.03, 0.01, 0.001));
  const auto view = tab.view();
  const phys::Core low = phys::polyhedron_core(view, 1, Vec3{0, 0, 0}, 1, 0, 0, 0, 1.0);
  const double delta = 2e-5;
  const double z = 0.01 + 0.002 - delta + 0.005;
  const phys::Core up = phys::polyhedron_core(view, 0, Vec3{0.003, -0.002, z}, 1, 0, 0, 0, 1.0);
  const phys::ConvexContact c = phys::convex_contact(low, 0.001, up, 0.001, 0.0, Vec3{0, 0, 0});
  REQUIRE(!c.separated);
  CHECK(c.dist == Approx(0.002 - delta).epsilon(1e-12));
  CHECK(c.n.z == Approx(1.0).epsilon(1e-15));
  CHECK(std::abs(c.point.x - 0.003) < 1e-12);
  CHECK(std::abs(c.point.y + 0.002) < 1e-12);
  CHECK(std::abs(c.point.z - (0.01 + 0.001 - delta / 2)) < 1e-12);
  // shifted beyond the lower face's edge in x: the overlap rectangle is [0.025, 0.03] in x
  const phys::Core up2 = phys::polyhedron_core(view, 0, Vec3{0.035, 0.0, z}, 1, 0, 0, 0, 1.0);
  const phys::ConvexContact c2 = phys::convex_contact(low, 0.001, up2, 0.001, 0.0, Vec3{0, 0, 0});
  CHECK(std::abs(c2.point.x - 0.0275) < 1e-12);
  // tilted by θ about y: the lower (+x) edge goes down by θ a; the overlap at the face centre
  // stays about δ, the point shifts by θ a_w² / (12 δ_c) towards +x (a_w = 20 mm face width,
  // δ_c the overlap at the centre), whole region: θ a_w / 2 < δ_c
  const double th = 1e-4 * delta / 0.01;
  const phys::Core up3 = phys::polyhedron_core(view, 0, Vec3{0.0, 0.0, z}, std::cos(th / 2), 0,
                                               std::sin(th / 2), 0, 1.0);
  const phys::ConvexContact c3 = phys::convex_contact(low, 0.001, up3, 0.001, 0.0, Vec3{0, 0, 0});
  // the face's centre is at x = -0.005 sin θ below... at x = -h sin θ with h = 5 mm
  const double xc = -0.005 * std::sin(th);
  const double dc = delta - 0.005 * (1 - std::cos(th));
  const double shift = th * 0.02 * 0.02 / (12 * dc);
  CHECK(std::abs(c3.point.x - (xc + shift)) < 1e-9 * 0.02);
}

namespace {
bool same_bits(double a, double b) {
  return std::memcmp(&a, &b, sizeof a) == 0;
}
bool same_bits(Vec3 a, Vec3 b) {
  return same_bits(a.x, b.x) && same_bits(a.y, b.y) && same_bits(a.z, b.z);
}
bool same_contact(const phys::ConvexContact& a, const phys::ConvexContact& b) {
  bool s = a.separated == b.separated && same_bits(a.dist, b.dist) && same_bits(a.axis, b.axis);
  if (a.separated || !s) return s;
  s = same_bits(a.n, b.n) && same_bits(a.pa, b.pa) && same_bits(a.pb, b.pb) &&
      same_bits(a.point, b.point) && same_bits(a.weight, b.weight) &&
      same_bits(a.moment, b.moment) && a.ref_side == b.ref_side && a.ref_face == b.ref_face;
  for (int m = 0; m < 6; ++m) s = s && same_bits(a.second[m], b.second[m]);
  return s;
}
}  // namespace

TEST_CASE("Narrow phase: the column loops of the CPU table give the bits of the row loops",
          "[dem][poly][narrow]") {
  // Reference: the same contacts with the table's columns (vsoa, fsoa: the CPU's SIMD loops)
  // left out, so that support, best face and vertex heights read the rows as the device
  // table does. Tolerance: none (bitwise), cold and warm-started (the second call starts from
  // the first one's features and axis). Poses: random directions at 0.5-1.1 of the bounding
  // sum, and faces laid on faces tilted by up to 10 degrees at overlaps of -1..2 r_d (touching
  // regions).
  const Shapes S = make_shapes();
  phys::ShapeTableView rows = S.view;
  REQUIRE(rows.vsoa != nullptr);
  rows.vsoa = rows.fsoa = nullptr;
  rows.vsoa_base = rows.fsoa_base = nullptr;
  const int nshape = static_cast<int>(S.list.size());
  std::mt19937_64 rng(77);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  std::uniform_int_distribution<int> pick(0, nshape - 1);
  int touching = 0, regions = 0, differ = 0;
  for (int k = 0; k < 4000; ++k) {
    const int ia = pick(rng), ib = pick(rng);
    const auto qa = random_quaternion(rng);
    auto qb = random_quaternion(rng);
    const Vec3 xa{0.001 * U(rng), 0.001 * U(rng), 0.001 * U(rng)};
    const double ra = S.list[ia].dilation, rb = S.list[ib].dilation;
    const phys::Core A0 = pose(S.table, S.view, ia, xa, qa);
    const phys::Core B0 = pose(S.table, S.view, ib, Vec3{0, 0, 0}, {1, 0, 0, 0});
    Vec3 xb;
    if (k % 2 == 0 || phys::core_face_count(A0) == 0 || phys::core_face_count(B0) == 0) {
      const auto r = random_quaternion(rng);
      Vec3 u{r[1], r[2], r[3]};
      u = (1.0 / std::sqrt(phys::norm2(u))) * u;
      xb = xa + (0.5 + 0.6 * U(rng)) * (S.table.bound(ia) + S.table.bound(ib)) * u;
    } else {
      const int fa = static_cast<int>(U(rng) * phys::core_face_count(A0));
      const int fb = static_cast<int>(U(rng) * phys::core_face_count(B0));
      const Vec3 na = phys::core_face_normal(A0, fa);
      qb = align(phys::core_face_normal(B0, fb), -1.0 * na);
      const auto r = random_quaternion(rng);
      Vec3 t = phys::cross(na, Vec3{r[1], r[2], r[3]});
      t = (1.0 / std::sqrt(phys::norm2(t))) * t;
      qb = quat_mul(axis_angle(t, 0.17 * U(rng) * U(rng)),
                    quat_mul(axis_angle(na, 6.28 * U(rng)), qb));
      Vec3 pa[phys::kMaxFaceVertices];
      phys::core_face_polygon(A0, fa, pa);
      const phys::Core B1 = pose(S.table, S.view, ib, Vec3{0, 0, 0}, qb);
      int idx;
      const Vec3 low = phys::support(B1, -1.0 * na, idx);
      const double gap = (ra + rb) * (1.0 - 3.0 * U(rng));
      const Vec3 side = phys::cross(na, Vec3{r[2], r[3], r[1]});
      xb = pa[0] + 0.5 * S.table.bound(ib) * U(rng) * side - phys::dot(na, pa[0] + side) * na +
           (phys::dot(na, pa[0]) + gap - phys::dot(na, low)) * na;
    }
    const phys::Core Ac = pose(S.table, S.view, ia, xa, qa), Bc = pose(S.table, S.view, ib, xb, qb);
    const phys::Core Ar = pose(S.table, rows, ia, xa, qa), Br = pose(S.table, rows, ib, xb, qb);
    int fc[6] = {-1, -1, -1, -1, -1, -1}, fr[6] = {-1, -1, -1, -1, -1, -1};
    const phys::ConvexContact c1 =
        phys::convex_contact(Ac, ra, Bc, rb, 0.0, Vec3{0, 0, 0}, false, fc);
    const phys::ConvexContact r1 =
        phys::convex_contact(Ar, ra, Br, rb, 0.0, Vec3{0, 0, 0}, false, fr);
    const phys::ConvexContact c2 = phys::convex_contact(Ac, ra, Bc, rb, 0.0, c1.axis, false, fc);
    const phys::ConvexContact r2 = phys::convex_contact(Ar, ra, Br, rb, 0.0, r1.axis, false, fr);
    const bool same =
        same_contact(c1, r1) && same_contact(c2, r2) && std::memcmp(fc, fr, sizeof fc) == 0;
    differ += same ? 0 : 1;
    touching += !c1.separated && c1.dist < ra + rb ? 1 : 0;
    regions += !c1.separated && c1.ref_side >= 0 ? 1 : 0;
  }
  WARN("column vs row loops, 4000 pairs: " << touching << " touching, " << regions
                                           << " with a touching region, " << differ << " differ");
  CHECK(differ == 0);
  CHECK(touching > 500);
  CHECK(regions > 100);
}

TEST_CASE("Narrow phase: a wall triangle's GJK start gives the contact of a cold start",
          "[dem][poly][narrow]") {
  // convex_contact against a triangle with the triangle's normal as the axis (the wall
  // contacts' call) starts GJK from the particle's lowest vertex paired with the three triangle
  // vertices. Reference: the same query without an axis (GJK from the centre difference).
  // Tolerance 1e-12 m on distance, contact point and closest points, 1e-12 on the normal
  // (rounding; the bits agree wherever the closest features are unique). Poses: rocks and
  // boxes over a triangle, random or with a face laid on it tilted by up to 10 degrees, at
  // overlaps of -1..2 r_d.
  const Shapes S = make_shapes();
  const int nshape = static_cast<int>(S.list.size()) - 2;  // polyhedra only
  std::mt19937_64 rng(91);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  std::uniform_int_distribution<int> pick(0, nshape - 1);
  const Vec3 t0{-0.03, -0.02, 0.0}, t1{0.03, -0.025, 0.0}, t2{0.0, 0.035, 0.001};
  const phys::Core T = phys::triangle_core(t0, t1, t2);
  const Vec3 nt = phys::core_face_normal(T, 0);
  int touching = 0, same = 0;
  for (int k = 0; k < 4000; ++k) {
    const int ia = pick(rng);
    auto qa = random_quaternion(rng);
    const phys::Core A0 = pose(S.table, S.view, ia, Vec3{0, 0, 0}, qa);
    if (k % 2 == 1) {  // a face of A on the triangle, tilted
      const int fa = static_cast<int>(U(rng) * phys::core_face_count(A0));
      const auto r = random_quaternion(rng);
      Vec3 t = phys::cross(nt, Vec3{r[1], r[2], r[3]});
      t = (1.0 / std::sqrt(phys::norm2(t))) * t;
      qa = quat_mul(axis_angle(t, 0.17 * U(rng) * U(rng)),
                    quat_mul(axis_angle(nt, 6.28 * U(rng)),
                             quat_mul(align(phys::core_face_normal(A0, fa), -1.0 * nt), qa)));
    }
    const phys::Core A1 = pose(S.table, S.view, ia, Vec3{0, 0, 0}, qa);
    int idx;
    const Vec3 low = phys::support(A1, -1.0 * nt, idx);
    const double ra = S.list[ia].dilation;
    const double gap = ra * (1.0 - 3.0 * U(rng));
    const Vec3 c{0.02 * (U(rng) - 0.5), 0.02 * (U(rng) - 0.5), 0.0};
    const Vec3 xa = c + (phys::dot(nt, t0) + gap - phys::dot(nt, low)) * nt;
    const phys::Core A = pose(S.table, S.view, ia, xa, qa);
    // the wall contacts' axis: the triangle's normal, pointing from the particle to it
    const Vec3 axis = (phys::dot(nt, xa - t0) > 0.0 ? -1.0 : 1.0) * nt;
    const phys::ConvexContact w = phys::convex_contact(A, ra, T, 0.0, 0.0, axis, true);
    const phys::ConvexContact r = phys::convex_contact(A, ra, T, 0.0, 0.0, Vec3{0, 0, 0}, true);
    const bool wt = !w.separated && w.dist < ra, rt = !r.separated && r.dist < ra;
    CHECK(wt == rt);
    if (!wt || !rt) continue;
    ++touching;
    const double e =
        std::max({std::abs(w.dist - r.dist), std::sqrt(phys::norm2(w.n - r.n)),
                  std::sqrt(phys::norm2(w.point - r.point)), std::sqrt(phys::norm2(w.pa - r.pa)),
                  std::sqrt(phys::norm2(w.pb - r.pb))});
    if (e > 1e-12) {
      INFO("shape " << ia << ", pose " << k << ": seeded vs cold " << e);
      CHECK(false);
    }
    same += same_contact(w, r) ? 1 : 0;
  }
  WARN("wall triangle start vs cold start, 4000 poses: " << touching << " touching, " << same
                                                         << " bitwise equal");
  CHECK(touching > 1000);
}
