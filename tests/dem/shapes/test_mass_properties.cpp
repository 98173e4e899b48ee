// Mass properties of cores and dilated bodies against closed forms (cube, rounded box,
// sphere), a published tetrahedron (Tonon 2005), Steiner's formula, invariance under rigid
// motions, and stratified Monte Carlo integration of a dilated random hull.

#include <catch2/catch.hpp>

#include <cmath>
#include <numbers>
#include <random>

#include "demfem/dem/shapes/mass_properties.hpp"
#include "shape_test_util.hpp"

using namespace demfem::dem::shapes;
using std::numbers::pi;

namespace {

/// Second moment about the origin, C = int x x^T, from the inertia about the centroid.
Mat3 second_moment(const MassProperties& m) {
  const double tr = 0.5 * (m.inertia[0][0] + m.inertia[1][1] + m.inertia[2][2]);
  Mat3 c{};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      c[i][j] = (i == j ? tr : 0.0) - m.inertia[i][j] + m.volume * m.centroid[i] * m.centroid[j];
  return c;
}

/// Rounded box (the box a x b x c dilated by r) from its 27 pieces in Cartesian closed forms,
/// independent of the library's edge/vertex formulas: returns V and the diagonal of
/// int x x^T (the off-diagonal terms vanish by symmetry).
struct BoxRef {
  double v = 0;
  double xx = 0, yy = 0, zz = 0;
};
BoxRef rounded_box(double a, double b, double c, double r) {
  const double half[3] = {a / 2, b / 2, c / 2};
  BoxRef ref;
  for (int i = -1; i <= 1; ++i)
    for (int j = -1; j <= 1; ++j)
      for (int k = -1; k <= 1; ++k) {
        const int idx[3] = {i, j, k};
        int rounded = 0;
        for (int d = 0; d < 3; ++d) rounded += idx[d] != 0;
        double v = 0, m2[3] = {0, 0, 0};
        if (rounded <= 1) {  // core box or a face slab: a product of intervals
          double len[3], sq[3];
          for (int d = 0; d < 3; ++d) {
            const double lo = idx[d] == 0 ? -half[d] : half[d];
            const double hi = idx[d] == 0 ? half[d] : half[d] + r;
            len[d] = hi - lo;
            sq[d] = (hi * hi * hi - lo * lo * lo) / 3.0;  // int x^2 over [lo, hi]
          }
          v = len[0] * len[1] * len[2];
          for (int d = 0; d < 3; ++d) m2[d] = sq[d] * len[(d + 1) % 3] * len[(d + 2) % 3];
        } else if (rounded == 2) {
          // Quarter cylinder along the axis d0 with idx 0; in the two rounded directions
          // x = h + rho cos(phi): int x^2 dA = A h^2 + 2 h r^3/3 + pi r^4/16 (A = pi r^2/4).
          int d0 = 0;
          while (idx[d0] != 0) ++d0;
          const double len = 2 * half[d0];
          const double area = pi * r * r / 4;
          v = area * len;
          m2[d0] = area * len * len * len / 12.0;
          for (int d = 0; d < 3; ++d)
            if (d != d0)
              m2[d] = len * (area * half[d] * half[d] + 2 * half[d] * r * r * r / 3 +
                             pi * r * r * r * r / 16);
        } else {
          // Eighth ball at a corner: V = pi r^3/6, int xi dV = pi r^4/16, int xi^2 dV = pi r^5/30.
          v = pi * r * r * r / 6;
          for (int d = 0; d < 3; ++d)
            m2[d] = v * half[d] * half[d] + 2 * half[d] * pi * std::pow(r, 4) / 16 +
                    pi * std::pow(r, 5) / 30;
        }
        ref.v += v;
        ref.xx += m2[0];
        ref.yy += m2[1];
        ref.zz += m2[2];
      }
  return ref;
}

Mat3 rotation(double ax, double ay, double az) {
  const double cx = std::cos(ax), sx = std::sin(ax), cy = std::cos(ay), sy = std::sin(ay),
               cz = std::cos(az), sz = std::sin(az);
  // Rz Ry Rx
  return Mat3{Vec3{cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx},
              Vec3{sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx},
              Vec3{-sy, cy * sx, cy * cx}};
}

Mat3 rotate_tensor(const Mat3& r, const Mat3& t) {
  Mat3 out{};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k)
        for (int l = 0; l < 3; ++l) out[i][j] += r[i][k] * t[k][l] * r[j][l];
  return out;
}

}  // namespace

TEST_CASE("cube core: volume a^3, centroid, inertia a^5/6", "[shapes][mass]") {
  const double a = 0.3;
  const auto m = core_mass_properties(make_cube(a).translated({1, 2, 3}));
  // Exact in exact arithmetic; 1e-14 relative covers round-off of a few dozen operations.
  CHECK(m.volume == Approx(a * a * a).epsilon(1e-14));
  for (int i = 0; i < 3; ++i) CHECK(m.centroid[i] == Approx(i + 1.0).epsilon(1e-14));
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      CHECK(m.inertia[i][j] ==
            Approx(i == j ? std::pow(a, 5) / 6 : 0.0).margin(1e-14 * std::pow(a, 5)));
}

TEST_CASE("tetrahedron core against Tonon (2005), J. Math. Stat. 1(1), example", "[shapes][mass]") {
  // F. Tonon, "Explicit exact formulas for the 3-D tetrahedron inertia tensor in terms of its
  // vertex coordinates": vertices as printed, results printed to 5 decimals (the paper's
  // a' is the yz product, b' the xz, c' the xy; the inertia tensor has -a', -b', -c' off the
  // diagonal). Tolerances: half a unit of the printed last digit, doubled.
  const std::vector<Vec3> p{{8.33220, -11.86875, 0.93355},
                            {0.75523, 5.00000, 16.37072},
                            {52.61236, 5.00000, -5.38580},
                            {2.00000, 5.00000, 3.00000}};
  const auto m = core_mass_properties(ConvexPolyhedron::hull(p, "Tonon's tetrahedron"));
  CHECK(m.volume == Approx(1873.233236).margin(1e-6));
  CHECK(m.centroid[0] == Approx(15.92492).margin(1e-5));
  CHECK(m.centroid[1] == Approx(0.78281).margin(1e-5));
  CHECK(m.centroid[2] == Approx(3.72962).margin(1e-5));
  CHECK(m.inertia[0][0] == Approx(43520.33257).margin(1e-5));
  CHECK(m.inertia[1][1] == Approx(194711.28938).margin(1e-5));
  CHECK(m.inertia[2][2] == Approx(191168.76173).margin(1e-5));
  CHECK(m.inertia[1][2] == Approx(-4417.66150).margin(1e-5));
  CHECK(m.inertia[0][2] == Approx(46343.16662).margin(1e-5));
  CHECK(m.inertia[0][1] == Approx(-11996.20119).margin(1e-5));
}

TEST_CASE("point core dilated is a sphere", "[shapes][mass]") {
  const double r = 0.02;
  const auto m = dilated_mass_properties(ConvexPolyhedron::point({0.1, 0, 0}), r);
  const double v = 4.0 / 3.0 * pi * r * r * r;
  CHECK(m.volume == Approx(v).epsilon(1e-15));
  CHECK(m.centroid[0] == Approx(0.1).epsilon(1e-15));
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      CHECK(m.inertia[i][j] == Approx(i == j ? 0.4 * v * r * r : 0.0).margin(1e-15 * v * r * r));
  CHECK(vertex_solid_angles(ConvexPolyhedron::point()) == std::vector<double>{4 * pi});
}

TEST_CASE("Steiner's formula on a cube: a^3 + 6a^2 r + 3 pi a r^2 + 4/3 pi r^3", "[shapes][mass]") {
  const double a = 2.0, r = 0.25;
  const auto s = steiner_coefficients(make_cube(a));
  CHECK(s.volume == Approx(a * a * a).epsilon(1e-15));
  CHECK(s.area == Approx(6 * a * a).epsilon(1e-15));
  // 12 edges of length a, exterior angle pi/2: M = 12 a (pi/2) / 2 = 3 pi a.
  CHECK(s.edge_term == Approx(3 * pi * a).epsilon(1e-15));
  const double exact = a * a * a + 6 * a * a * r + 3 * pi * a * r * r + 4.0 / 3.0 * pi * r * r * r;
  CHECK(s.dilated_volume(r) == Approx(exact).epsilon(1e-15));
  CHECK(dilated_mass_properties(make_cube(a), r).volume == Approx(exact).epsilon(1e-14));
}

TEST_CASE("rounded box against its closed form from the 27 pieces", "[shapes][mass]") {
  const double a = 1.0, b = 0.6, c = 0.3;
  for (double r : {0.0, 0.05, 0.3, 2.0}) {
    const BoxRef ref = rounded_box(a, b, c, r);
    const auto m = dilated_mass_properties(make_box(a, b, c), r);
    const double scale = ref.xx + ref.yy + ref.zz;
    // Round-off only: 1e-13 relative.
    CHECK(m.volume == Approx(ref.v).epsilon(1e-13));
    for (int i = 0; i < 3; ++i) CHECK(m.centroid[i] == Approx(0.0).margin(1e-14));
    CHECK(m.inertia[0][0] == Approx(ref.yy + ref.zz).epsilon(1e-13));
    CHECK(m.inertia[1][1] == Approx(ref.xx + ref.zz).epsilon(1e-13));
    CHECK(m.inertia[2][2] == Approx(ref.xx + ref.yy).epsilon(1e-13));
    CHECK(std::abs(m.inertia[0][1]) < 1e-14 * scale);
    CHECK(std::abs(m.inertia[0][2]) < 1e-14 * scale);
    CHECK(std::abs(m.inertia[1][2]) < 1e-14 * scale);
  }
}

TEST_CASE("mass properties follow rigid motions of the core", "[shapes][mass]") {
  std::mt19937_64 gen(11);
  const auto k = ConvexPolyhedron::hull(test::random_points(gen, 40, {1.0, 0.7, 0.4}), "random");
  const Mat3 rot = rotation(0.3, -1.1, 2.0);
  const Vec3 t{5, -3, 2};
  const auto moved = k.transformed(rot, t);
  for (double r : {0.0, 0.1}) {
    const auto m0 = dilated_mass_properties(k, r);
    const auto m1 = dilated_mass_properties(moved, r);
    CHECK(m1.volume == Approx(m0.volume).epsilon(1e-13));
    for (int i = 0; i < 3; ++i)
      CHECK(m1.centroid[i] == Approx(dot(rot[i], m0.centroid) + t[i]).margin(1e-13));
    const Mat3 expect = rotate_tensor(rot, m0.inertia);
    const double scale = m0.inertia[0][0] + m0.inertia[1][1] + m0.inertia[2][2];
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        CHECK(m1.inertia[i][j] == Approx(expect[i][j]).margin(1e-13 * scale));
    const auto f0 = principal_frame(m0.inertia), f1 = principal_frame(m1.inertia);
    for (int i = 0; i < 3; ++i) CHECK(f1.moments[i] == Approx(f0.moments[i]).epsilon(1e-12));
  }
}

TEST_CASE("solid angles of the normal cones sum to 4 pi", "[shapes][mass]") {
  for (const auto& k : {make_cube(1.0), make_regular_tetrahedron(1.0), make_octahedron(1.0),
                        make_triangular_prism(1.0, 0.3)}) {
    double sum = 0;
    for (double w : vertex_solid_angles(k)) {
      CHECK(w > 0);
      sum += w;
    }
    CHECK(sum == Approx(4 * pi).epsilon(1e-14));
  }
  // A cube corner's normal cone is an octant: 4 pi / 8.
  for (double w : vertex_solid_angles(make_cube(1.0))) CHECK(w == Approx(pi / 2).epsilon(1e-14));
}

TEST_CASE("principal frame is right-handed and diagonalises the tensor", "[shapes][mass]") {
  const Mat3 rot = rotation(0.4, 0.2, -0.7);
  Mat3 diag{};
  diag[0][0] = 1.0;
  diag[1][1] = 2.0;
  diag[2][2] = 3.5;
  const auto f = principal_frame(rotate_tensor(rot, diag));
  CHECK(f.moments[0] == Approx(1.0).epsilon(1e-14));
  CHECK(f.moments[1] == Approx(2.0).epsilon(1e-14));
  CHECK(f.moments[2] == Approx(3.5).epsilon(1e-14));
  const Vec3 c0{f.axes[0][0], f.axes[1][0], f.axes[2][0]};
  const Vec3 c1{f.axes[0][1], f.axes[1][1], f.axes[2][1]};
  const Vec3 c2{f.axes[0][2], f.axes[1][2], f.axes[2][2]};
  CHECK(dot(cross(c0, c1), c2) == Approx(1.0).epsilon(1e-14));
  // column k is the rotated k-th axis up to sign
  for (int k = 0; k < 3; ++k) {
    const Vec3 col{f.axes[0][k], f.axes[1][k], f.axes[2][k]};
    const Vec3 ref{rot[0][k], rot[1][k], rot[2][k]};
    CHECK(std::abs(dot(col, ref)) == Approx(1.0).epsilon(1e-13));
  }
}

TEST_CASE("dilated random hull against stratified Monte Carlo", "[shapes][mass]") {
  // Independent reference: the indicator of dist(x, core) <= r (brute-force point-triangle
  // distances) integrated by stratified Monte Carlo, 48^3 cells x 2 samples. Tolerance:
  // 5 standard errors estimated from the sample pairs (the library's result is exact).
  std::mt19937_64 gen(3);
  const auto k =
      ConvexPolyhedron::hull(test::random_points(gen, 12, {1.0, 0.6, 0.4}), "random 12");
  const double r = 0.3;  // large, so that wedges and sectors are 20-40 % of the volume
  const auto m = dilated_mass_properties(k, r);
  Vec3 lo{INFINITY, INFINITY, INFINITY}, hi{-INFINITY, -INFINITY, -INFINITY};
  for (const Vec3& v : k.vertices())
    for (int d = 0; d < 3; ++d) {
      lo[d] = std::min(lo[d], v[d] - r);
      hi[d] = std::max(hi[d], v[d] + r);
    }
  const auto mc = test::monte_carlo_moments(k, r, lo, hi, 48, 17);
  const auto steiner = steiner_coefficients(k);
  CHECK(m.volume == Approx(steiner.dilated_volume(r)).epsilon(1e-13));
  CHECK(std::abs(m.volume - mc.v) < 5 * mc.v_se);
  for (int i = 0; i < 3; ++i) CHECK(std::abs(m.volume * m.centroid[i] - mc.s[i]) < 5 * mc.s_se[i]);
  const Mat3 c = second_moment(m);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) CHECK(std::abs(c[i][j] - mc.c[i][j]) < 5 * mc.c_se[i][j]);
  INFO("volume " << m.volume << " MC " << mc.v << " +- " << mc.v_se);
  // The Monte Carlo error is small enough to tell a missing piece: the sectors alone are
  // 4/3 pi r^3 = 0.113.
  CHECK(mc.v_se < 2e-3);
}
