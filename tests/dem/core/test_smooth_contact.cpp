// The smooth contact law of dilated polyhedra (physics/smooth_contact.hpp): its force and
// torques are the gradient of its energy (against finite differences), the energy has no kink
// along paths through every kind of tie (the power is continuous), its overlap agrees with the
// closest-point overlap of eq. 2.5 where one feature pair is closest and within the stated bounds
// elsewhere, and it is eq. 2.20 itself for a point core.

#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <random>

#include "core/shape_table.hpp"
#include "dem_test_util.hpp"
#include "demfem/dem/dem_system.hpp"
#include "demfem/dem/physics/poly_contact.hpp"
#include "demfem/dem/physics/smooth_contact.hpp"
#include "poly_test_util.hpp"

using namespace demfem::dem;
using namespace demfem::dem::test;
using phys::Vec3;

namespace {

using Quat = std::array<double, 4>;

Quat turn(Vec3 w, Quat q) {  // q turned by the world rotation vector w
  const double th = std::sqrt(phys::norm2(w));
  if (th == 0.0) return q;
  const double s = std::sin(th / 2) / th;
  return quat_mul({std::cos(th / 2), s * w.x, s * w.y, s * w.z}, q);
}

using Shapes = ShapeSet;

Shapes make_shapes() {
  std::vector<PolyhedronShape> list;
  std::mt19937_64 rng(23);
  list.push_back(box_shape(0.006, 0.006, 0.006, 0.001));   // 0: cube
  list.push_back(box_shape(0.010, 0.007, 0.004, 0.0008));  // 1: flat box
  for (int k = 0; k < 4; ++k)                              // 2..5: rocks
    list.push_back(random_rock(rng, 9 + 3 * k, 0.011, 0.008, 0.006, 0.001));
  list.push_back(point_shape(0.003));  // 6: sphere
  return shape_set(std::move(list));
}

struct Pose {
  int shape;
  Vec3 x;
  Quat q;
};

phys::Core core_of(const Shapes& S, const Pose& p) {
  return phys::polyhedron_core(S.view, p.shape, p.x, p.q[0], p.q[1], p.q[2], p.q[3], 1.0);
}

double dil(const Shapes& S, const Pose& p) {
  return S.list[p.shape].dilation;
}

// The law's energy (E* = 1) and gradient of a pair; false when it does not apply.
struct Eval {
  bool ok;
  double u, delta0;
  phys::SmoothElastic el;
};

Eval evaluate(const Shapes& S, const Pose& a, const Pose& b) {
  Eval e{};
  const phys::Core A = core_of(S, a), B = core_of(S, b);
  const double ra = dil(S, a), rb = dil(S, b);
  const phys::GjkResult g = phys::gjk_distance(A, B, 1e300);
  if (g.status != 1) return e;
  e.delta0 = ra + rb - g.dist;
  phys::SmoothSum sum;
  if (!phys::smooth_pair_sum(A, ra, B, rb, g.pa, g.pb, a.x, b.x, sum)) return e;
  const double reff = ra * rb / (ra + rb);
  if (!phys::smooth_elastic(sum, 1.0, reff, e.el)) return e;
  e.ok = true;
  e.u = 8.0 / 15.0 * std::sqrt(reff) * std::pow(e.el.delta_s, 2.5);  // U_H(δ_s), E* = 1
  return e;
}

// B placed from A along direction u so that the cores are `gap` apart
Pose place(const Shapes& S, const Pose& a, Pose b, Vec3 u, double gap) {
  double L = 0.05;
  for (int it = 0; it < 60; ++it) {
    b.x = a.x + L * u;
    const phys::GjkResult g = phys::gjk_distance(core_of(S, a), core_of(S, b), 1e300);
    const double d = g.status == 1 ? g.dist : -1e-3;
    const double slope =
        g.status == 1 ? std::max(0.2, phys::dot(u, (1.0 / g.dist) * (g.pb - g.pa))) : 1.0;
    const double step = (d - gap) / slope;
    L -= step;
    if (std::abs(d - gap) < 1e-13) break;
  }
  b.x = a.x + L * u;
  return b;
}

Vec3 random_unit(std::mt19937_64& rng) {
  const Quat q = random_quaternion(rng);
  const Vec3 v{q[1], q[2], q[3]};
  return (1.0 / std::sqrt(phys::norm2(v))) * v;
}

// Two random shapes of S in random orientations, B placed to overlap A by depth() of the
// smaller dilation.
template <class Depth>
std::pair<Pose, Pose> touching_pair(const Shapes& S, std::mt19937_64& rng, Depth depth) {
  std::uniform_int_distribution<int> pick(0, 5);
  Pose a{pick(rng), Vec3{0, 0, 0}, random_quaternion(rng)};
  Pose b{pick(rng), Vec3{0, 0, 0}, random_quaternion(rng)};
  const double rsum = dil(S, a) + dil(S, b);
  b = place(S, a, b, random_unit(rng), rsum - depth() * std::min(dil(S, a), dil(S, b)));
  return {a, b};
}

}  // namespace

TEST_CASE("Smooth polyhedron law: force and torques are the gradient of its energy",
          "[poly][smooth]") {
  const Shapes S = make_shapes();
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> frac(0.02, 0.4);
  double worst = 0.0;
  int checked = 0;
  for (int trial = 0; trial < 400; ++trial) {
    const auto [a, b] = touching_pair(S, rng, [&] { return frac(rng); });
    const Eval e0 = evaluate(S, a, b);
    if (!e0.ok) continue;
    ++checked;
    const double fscale = std::sqrt(phys::norm2(e0.el.fa));
    const double tscale = fscale * 0.02;
    const double h = 1e-9, hr = 1e-7;
    const Vec3 axes[3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    // central difference of U against the analytic derivative, relative to its scale
    auto check = [&](const Pose& pp, const Pose& pm, const Pose& qp, const Pose& qm, double step,
                     double analytic, double scale) {
      const double fd = (evaluate(S, pp, qp).u - evaluate(S, pm, qm).u) / (2 * step);
      const double err = std::abs(fd - analytic) / scale;
      worst = std::max(worst, err);
      CHECK(err < 1e-5);
    };
    for (const Vec3& ax : axes) {
      Pose ap = a, am = a, aq = a, aw = a, bq = b, bw = b;
      ap.x = a.x + h * ax, am.x = a.x - h * ax;
      aq.q = turn(hr * ax, a.q), aw.q = turn(-hr * ax, a.q);
      bq.q = turn(hr * ax, b.q), bw.q = turn(-hr * ax, b.q);
      check(ap, am, b, b, h, -phys::dot(e0.el.fa, ax), fscale);   // translation of A
      check(aq, aw, b, b, hr, -phys::dot(e0.el.ta, ax), tscale);  // rotation of A
      check(a, a, bq, bw, hr, -phys::dot(e0.el.tb, ax), tscale);  // rotation of B
    }
  }
  WARN("gradient check: " << checked << " contacts, worst relative error " << worst);
  CHECK(checked > 300);
}

TEST_CASE("Smooth polyhedron law: no kink along paths through ties", "[poly][smooth]") {
  // A kink of the energy is a jump of the power dU/dt along a path: sampled 10 times finer,
  // the largest change between neighbouring samples stays. A C¹ energy's falls in proportion
  // (a steep but smooth tie falls too). Paths: A slides 2 mm and turns 0.3 rad about a random
  // axis while touching B (every kind of tie is crossed somewhere: edges turning parallel to
  // faces and edges, faces to faces, vertices over edges). Tolerance: the fine sampling's
  // largest change at most 0.25 of the coarse one's (0.1 for a C¹ energy, 1 for a kink) or
  // below 1e-3 of the path's largest power.
  const Shapes S = make_shapes();
  std::mt19937_64 rng(8);
  auto largest_change = [&](const Pose& a, const Pose& b, Vec3 v, Vec3 w, double rmin, int n,
                            double& pmax) {
    double pprev = 0.0, jump = 0.0;
    bool have = false;
    pmax = 0.0;
    for (int k = 0; k <= n; ++k) {
      const double t = double(k) / n;
      Pose ak = a;
      ak.x = a.x + t * v;
      ak.q = turn(t * w, a.q);
      const Eval e = evaluate(S, ak, b);
      if (!e.ok || e.delta0 > 0.6 * rmin) {
        have = false;
        continue;
      }
      const double p = -(phys::dot(e.el.fa, v) + phys::dot(e.el.ta, w));  // dU/dt
      pmax = std::max(pmax, std::abs(p));
      if (have) jump = std::max(jump, std::abs(p - pprev));
      pprev = p;
      have = true;
    }
    return jump;
  };
  double worst = 0.0;
  int paths = 0;
  for (int trial = 0; trial < 100; ++trial) {
    const auto [a, b] = touching_pair(S, rng, [] { return 0.25; });
    const double rmin = std::min(dil(S, a), dil(S, b));
    const Vec3 v = 0.002 * random_unit(rng), w = 0.3 * random_unit(rng);
    double pmax = 0.0, pmax_fine = 0.0;
    const double coarse = largest_change(a, b, v, w, rmin, 1000, pmax);
    const double fine = largest_change(a, b, v, w, rmin, 10000, pmax_fine);
    if (pmax == 0.0) continue;
    ++paths;
    const double ratio = fine / coarse;
    INFO("trial " << trial << " shapes " << a.shape << ", " << b.shape << ": largest change "
                  << coarse / pmax << " of the largest power at 1/1000, " << fine / pmax
                  << " at 1/10000");
    CHECK((ratio < 0.25 || fine < 1e-3 * pmax));
    if (fine >= 1e-3 * pmax) worst = std::max(worst, ratio);
  }
  WARN("paths: " << paths
                 << "; the largest change of dU/dt between neighbouring samples falls "
                    "by at least "
                 << 1.0 / worst << " when sampled 10 times finer (a kink: 1)");
  CHECK(paths > 60);
}

namespace {
// The smallest angle (sin²) between an edge of A and an edge of B that come within rsum of
// each other: the contacts where the fade of nearly parallel edges acts (below sin² 2°).
double closest_parallel(const Shapes& S, const Pose& a, const Pose& b) {
  const phys::Core A = core_of(S, a), B = core_of(S, b);
  const double rsum = dil(S, a) + dil(S, b);
  double best = 1.0;
  for (int e = 0; e < phys::core_edge_count(A); ++e)
    for (int f = 0; f < phys::core_edge_count(B); ++f) {
      Vec3 p0, p1, q0, q1, c1, c2;
      phys::core_edge(A, e, p0, p1);
      phys::core_edge(B, f, q0, q1);
      phys::detail::closest_segments(p0, p1, q0, q1, c1, c2);
      if (!(phys::norm2(c2 - c1) < rsum * rsum)) continue;
      const Vec3 u = p1 - p0, v = q1 - q0;
      best = std::min(best, phys::norm2(phys::cross(u, v)) / (phys::norm2(u) * phys::norm2(v)));
    }
  return best;
}
}  // namespace

TEST_CASE("Smooth polyhedron law: the overlap against eq. 2.5", "[poly][smooth]") {
  // δ_s against the closest-point overlap δ of eq. 2.5 over random contacts. Where no two
  // edges within reach are nearer parallel than 2°: at most 2.5 % below δ (the end subtraction
  // of an edge term, smooth_contact.hpp) and at most 4^{1/4} above it (four features tie: a
  // face on a face). Nearly parallel edges are faded out and their ends carry the overlap,
  // short of it by (s sin θ)² / (2 (r_i + r_j)) at a crossing s from an end: reported.
  const Shapes S = make_shapes();
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> frac(0.02, 0.4);
  double lo = 1e300, hi = 0.0, lo_parallel = 1e300;
  int exact = 0, n = 0, parallel = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    const auto [a, b] = touching_pair(S, rng, [&] { return frac(rng); });
    const Eval e = evaluate(S, a, b);
    if (!e.ok) continue;
    ++n;
    const double r = e.el.delta_s / e.delta0;
    hi = std::max(hi, r);
    exact += std::abs(r - 1.0) < 1e-9 ? 1 : 0;
    if (closest_parallel(S, a, b) < phys::kParallelHi) {
      ++parallel;
      lo_parallel = std::min(lo_parallel, r);
    } else {
      lo = std::min(lo, r);
    }
  }
  WARN("δ_s / δ over " << n << " random contacts: " << lo << " .. " << hi << "; equal (1e-9) in "
                       << exact << "; " << parallel << " with edges within 2° of parallel: down to "
                       << lo_parallel);
  CHECK(n > 1500);
  CHECK(lo > 0.975);
  CHECK(hi < std::pow(4.0, 0.25) + 1e-9);
  CHECK(exact > n / 2);  // most contacts are one feature pair
}

TEST_CASE("Smooth polyhedron law: a sphere against a rock is the pressure-centre law's contact",
          "[poly][smooth]") {
  // A point core has unique closest points: dilated_pair takes eq. 2.20 on Δ itself for it
  // under either law (the sphere limit of the smooth law): the same bits.
  const Shapes S = make_shapes();
  std::mt19937_64 rng(19);
  const Pose rock{2, Vec3{0, 0, 0}, random_quaternion(rng)};
  for (int k = 0; k < 100; ++k) {
    Pose ball{6, Vec3{0, 0, 0}, Quat{1, 0, 0, 0}};
    ball = place(S, rock, ball, random_unit(rng), dil(S, rock) + dil(S, ball) - 0.0004);
    const phys::Core A = core_of(S, rock), B = phys::point_core(ball.x);
    phys::BodyState ba{rock.x, Vec3{0.1, 0, 0}, Vec3{0, 0, 3}, 0.01, A.r, Vec3{1e-6, 2e-6, 3e-6}};
    phys::BodyState bb{ball.x,
                       Vec3{0, 0, 0},
                       Vec3{0, 0, 0},
                       0.01,
                       phys::Rot{{1, 0, 0, 0, 1, 0, 0, 0, 1}},
                       Vec3{1e-6, 1e-6, 1e-6}};
    phys::DilatedResult r[2];
    for (int law = 0; law < 2; ++law) {
      const phys::PairConstants pc =
          phys::pair_constants(1e8, 0.3, 1e8, 0.3, 0.5, 0.4, 0.0, 1.0, law);
      Vec3 shear{0, 0, 0}, axis{0, 0, 0};
      int feat[6] = {-1, -1, -1, -1, -1, -1};
      REQUIRE(phys::dilated_pair<true>(A, dil(S, rock), ba, B, dil(S, ball), bb, pc, 1e-6, shear,
                                       axis, feat, r[law]));
    }
    CHECK(r[0].force.x == r[1].force.x);
    CHECK(r[0].force.z == r[1].force.z);
    CHECK(r[0].torque_i.y == r[1].torque_i.y);
  }
}

namespace {

// A roof: two slopes falling by `beta` on either side of a ridge along x through the origin.
WallMesh ridge_mesh(double beta) {
  const double L = 0.05, W = 0.05, h = -W * std::tan(beta);
  WallMesh w;
  w.name = "ridge";
  w.material = 1;
  w.vertices = {-L, 0, 0, L, 0, 0, L, W, h, -L, W, h, L, -W, h, -L, -W, h};
  w.triangles = {0, 1, 2, 0, 2, 3, 0, 5, 4, 0, 4, 1};
  return w;
}

// The contact force on a cube (core half side 6 mm, r_d 1 mm) at rest at x, turned by q, on
// the wall, under the law (no velocity: the elastic force alone).
Vec3 wall_force(const WallMesh& wall, std::array<double, 3> x, Quat q, MaterialPair::PolyLaw law) {
  auto s = two_material_settings(1e8, 0.3, 2500.0, 0.5, 0.5, 1e-9);
  for (auto& p : s.pairs) p.poly_law = law;
  DemSystem sys(s);
  sys.add_shape(box_shape(0.006, 0.006, 0.006, 0.001));
  sys.add_wall(wall);
  sys.add_particles(std::vector<ParticleInit>{poly(0, x, q)});
  sys.advance(1);
  const auto& st = sys.particles();
  return Vec3{st.fx[0], st.fy[0], st.fz[0]};
}

}  // namespace

TEST_CASE("Smooth polyhedron law: a face across a convex wall edge is not softer than eq. 2.20",
          "[poly][smooth]") {
  // A cube's face lies across the ridge of a roof whose slopes fall by beta (the two slopes one
  // wall contact: their contact normals agree), its core 0.8 r_d above the ridge: the overlap
  // δ = 0.2 r_d is the ridge's in the face. The smooth wall law has terms for the rock's
  // vertices only; at beta = 1° they lie 0.095 r_d deep (δ_s 0.67 δ, 55 % of the force) and
  // at 2° out of reach. Reference: the pressure-centre law, eq. 2.20 at δ. Required: the
  // smooth law's force at least 0.975^1.5 = 0.963 of it (kSmoothWallFloor) for every roof,
  // turn about z and shift along y, and at most that of four corners tied at δ: δ_s = 4^{1/4} δ
  // with gradient 4^{1/4}, 4^{5/8} = 2.38 times the reference, which the flat wall (beta 0)
  // gives to 1e-9.
  for (const double beta_deg : {0.0, 0.5, 1.0, 2.0, 5.0})
    for (const double yaw_deg : {0.0, 20.0, 45.0})
      for (const double y : {0.0, 0.002, -0.004}) {
        INFO("beta " << beta_deg << " deg, yaw " << yaw_deg << " deg, y " << y);
        const double pi = 3.14159265358979323846;
        const double yaw = yaw_deg * pi / 180;
        const Quat q{std::cos(yaw / 2), 0, 0, std::sin(yaw / 2)};
        const WallMesh wall = ridge_mesh(beta_deg * pi / 180);
        const std::array<double, 3> x{0, y, 0.006 + 0.0008};
        const Vec3 fp = wall_force(wall, x, q, MaterialPair::PolyLaw::pressure_centre);
        const Vec3 fs = wall_force(wall, x, q, MaterialPair::PolyLaw::smooth);
        const double np = std::sqrt(phys::norm2(fp)), ns = std::sqrt(phys::norm2(fs));
        REQUIRE(np > 0.0);
        const double tied = std::pow(4.0, 0.625);
        CHECK(ns >= 0.963 * np);
        CHECK(ns <= tied * np * (1 + 1e-9));
        if (beta_deg == 0.0) CHECK(ns == Approx(tied * np).epsilon(1e-9));
      }
}
