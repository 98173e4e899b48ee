#pragma once
// Test builders for dilated polyhedra: simple solids by hand, random convex hulls by a
// brute-force facet search (tests only: O(n^4), fine for a dozen points; the engine's hulls come
// from Qhull through the shape library), and the exact mass properties of a rounded box.

#include <algorithm>
#include <array>
#include <cmath>
#include <random>
#include <vector>

#include "core/shape_table.hpp"
#include "dem_test_util.hpp"
#include "demfem/dem/dem_system.hpp"

namespace demfem::dem::test {

/// A polyhedron of shape `shape` at x, turned by q, moving at v, spinning at w.
inline ParticleInit poly(std::int32_t shape, std::array<double, 3> x,
                         std::array<double, 4> q = {1, 0, 0, 0}, std::array<double, 3> v = {},
                         std::array<double, 3> w = {}, double scale = 1.0) {
  ParticleInit p;
  p.shape = ParticleShape::polyhedron;
  p.shape_id = shape;
  p.position = x;
  p.orientation = q;
  p.velocity = v;
  p.angular_velocity = w;
  p.scale = scale;
  return p;
}

/// Hull triangles (outward, CCW) of points in general position: every triple whose plane has
/// all other points on one side.
inline std::vector<std::int32_t> brute_hull(const std::vector<double>& p) {
  const int n = static_cast<int>(p.size() / 3);
  auto P = [&](int k) { return std::array<double, 3>{p[3 * k], p[3 * k + 1], p[3 * k + 2]}; };
  std::vector<std::int32_t> tri;
  for (int i = 0; i < n; ++i)
    for (int j = i + 1; j < n; ++j)
      for (int k = j + 1; k < n; ++k) {
        const auto a = P(i), b = P(j), c = P(k);
        const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
        const double v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        const double nn[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2],
                              u[0] * v[1] - u[1] * v[0]};
        int pos = 0, neg = 0;
        for (int m = 0; m < n; ++m) {
          if (m == i || m == j || m == k) continue;
          const auto q = P(m);
          const double s = nn[0] * (q[0] - a[0]) + nn[1] * (q[1] - a[1]) + nn[2] * (q[2] - a[2]);
          (s > 0 ? pos : neg)++;
        }
        if (pos == 0) tri.insert(tri.end(), {i, j, k});
        if (neg == 0) tri.insert(tri.end(), {i, k, j});
      }
  return tri;
}

/// n random points on an ellipsoid with semi-axes (a, b, c), centred on their mean.
inline std::vector<double> random_points(std::mt19937_64& rng, int n, double a, double b,
                                         double c) {
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<double> p;
  for (int k = 0; k < n; ++k) {
    double x = g(rng), y = g(rng), z = g(rng);
    const double l = std::sqrt(x * x + y * y + z * z);
    p.insert(p.end(), {a * x / l, b * y / l, c * z / l});
  }
  double m[3] = {0, 0, 0};
  for (int k = 0; k < n; ++k)
    for (int d = 0; d < 3; ++d) m[d] += p[3 * k + d] / n;
  for (int k = 0; k < n; ++k)
    for (int d = 0; d < 3; ++d) p[3 * k + d] -= m[d];
  return p;
}

/// Box core with half-sides (a, b, c) as 12 triangles.
inline PolyhedronShape box_shape(double a, double b, double c, double rd) {
  PolyhedronShape s;
  s.name = "box";
  for (int k = 0; k < 8; ++k)
    s.vertices.insert(s.vertices.end(), {k & 1 ? a : -a, k & 2 ? b : -b, k & 4 ? c : -c});
  // faces as quads (outward, CCW), split into two triangles each
  const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                           {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& f : quads)
    s.triangles.insert(s.triangles.end(), {f[0], f[1], f[2], f[0], f[2], f[3]});
  s.dilation = rd;
  // dilated box (Steiner): core, 6 face slabs, 12 quarter cylinders, 8 eighth spheres
  const double pi = 3.14159265358979323846;
  const double A = 2 * a, B = 2 * b, C = 2 * c, r = rd;
  s.volume = A * B * C + 2 * r * (A * B + B * C + C * A) + pi * r * r * (A + B + C) +
             4.0 / 3.0 * pi * r * r * r;
  // second moment ∫ x_p² dV over the dilated box, x_p along the half side p (q, t the others):
  // core, 6 slabs, 12 quarter cylinders, 8 eighth balls (quarter disc: ∫u dA = r³/3,
  // ∫u² dA = π r⁴/16; eighth ball: ∫u dV = π r⁴/16, ∫u² dV = π r⁵/30)
  auto S = [&](double p, double q, double t) {
    const double p3 = 2 * p * p * p / 3.0;
    double v = p3 * 4 * q * t;
    v += 2 * ((p + r) * (p + r) * (p + r) - p * p * p) / 3.0 * 4 * q * t;
    v += 2 * p3 * r * 2 * t + 2 * p3 * r * 2 * q;
    v += 4 * p3 * pi * r * r / 4.0;
    const double qd =
        p * p * pi * r * r / 4.0 + 2 * p * r * r * r / 3.0 + pi * r * r * r * r / 16.0;
    v += 4 * 2 * q * qd + 4 * 2 * t * qd;
    v += 8 * (p * p * pi * r * r * r / 6.0 + 2 * p * pi * r * r * r * r / 16.0 +
              pi * r * r * r * r * r / 30.0);
    return v;
  };
  const double Sx = S(a, b, c), Sy = S(b, c, a), Sz = S(c, a, b);
  s.inertia = {Sy + Sz, Sx + Sz, Sx + Sy};
  return s;
}

/// A random convex rock: n points on an ellipsoid, brute-force hull; mass properties
/// placeholders (valid, not exact: for narrow-phase tests only).
inline PolyhedronShape random_rock(std::mt19937_64& rng, int n, double a, double b, double c,
                                   double rd) {
  PolyhedronShape s;
  s.name = "rock";
  s.vertices = random_points(rng, n, a, b, c);
  s.triangles = brute_hull(s.vertices);
  s.dilation = rd;
  s.volume = 4.0 / 3.0 * 3.14159265358979323846 * a * b * c;
  const double m = s.volume / 5.0;
  s.inertia = {m * (b * b + c * c), m * (a * a + c * c), m * (a * a + b * b)};
  return s;
}

inline PolyhedronShape point_shape(double r) {
  PolyhedronShape s;
  s.name = "point";
  s.vertices = {0, 0, 0};
  s.dilation = r;
  const double pi = 3.14159265358979323846;
  s.volume = 4.0 / 3.0 * pi * r * r * r;
  const double I = 0.4 * s.volume * r * r;
  s.inertia = {I, I, I};
  return s;
}

/// Shapes in the engine's shape table (the narrow-phase tests pose cores on its view).
struct ShapeSet {
  detail::ShapeTable table;
  std::vector<PolyhedronShape> list;
  phys::ShapeTableView view{};
};

/// The shape set of `list`.
inline ShapeSet shape_set(std::vector<PolyhedronShape> list) {
  ShapeSet s;
  s.list = std::move(list);
  for (const auto& sh : s.list) s.table.add(sh);
  s.view = s.table.view();
  return s;
}

/// Quaternion product a b (w, x, y, z).
inline std::array<double, 4> quat_mul(std::array<double, 4> a, std::array<double, 4> b) {
  return {a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
          a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
          a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
          a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0]};
}

/// Uniformly random unit quaternion.
inline std::array<double, 4> random_quaternion(std::mt19937_64& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  double q[4] = {g(rng), g(rng), g(rng), g(rng)};
  const double l = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  return {q[0] / l, q[1] / l, q[2] / l, q[3] / l};
}

/// A cloud thrown over a floor in a 0.04 m periodic cell (the periodic tests of both backends):
/// 6 x 6 x 4 sites 6.6 mm apart, sideways velocities of up to 2 m/s and 0.3 m/s down; every
/// third site a 2.2 mm sphere, the others polyhedra of `shape` at random orientations (all
/// spheres when `rocks` is false). The draws of `rng` are in site order.
inline std::vector<ParticleInit> periodic_thrown_cloud(std::int32_t shape, std::mt19937_64& rng,
                                                       bool rocks = true) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<ParticleInit> p;
  for (int k = 0; k < 4; ++k)
    for (int j = 0; j < 6; ++j)
      for (int i = 0; i < 6; ++i) {
        const std::array<double, 3> x{0.0066 * i + 0.003, 0.0066 * j + 0.003, 0.004 + 0.0066 * k};
        const std::array<double, 3> v{2.0 * u(rng), 2.0 * u(rng), -0.3};
        if (!rocks || (i + j + k) % 3 == 0)
          p.push_back(sphere(x, 0.0022, v, {10 * u(rng), 0, 0}));
        else
          p.push_back(poly(shape, x, random_quaternion(rng), v, {20 * u(rng), 20 * u(rng), 0}));
      }
  return p;
}

}  // namespace demfem::dem::test
