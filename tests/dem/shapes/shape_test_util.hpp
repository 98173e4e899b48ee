#pragma once
// Test helpers for the shape library: an independent point-to-polyhedron distance (brute
// force over triangles) and a stratified Monte Carlo integrator of the dilated body.

#include <algorithm>
#include <array>
#include <cmath>
#include <random>
#include <vector>

#include "demfem/dem/shapes/convex_polyhedron.hpp"

namespace demfem::dem::shapes::test {

/// `n` points drawn uniformly from the box centre ± half (each point's x, y, z in that order
/// from `gen`): the cloud the tests take random hulls of.
inline std::vector<Vec3> random_points(std::mt19937_64& gen, std::size_t n, const Vec3& half,
                                       const Vec3& centre = {0.0, 0.0, 0.0}) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Vec3> p(n);
  for (Vec3& x : p) {
    const double ux = u(gen), uy = u(gen), uz = u(gen);
    x = {centre[0] + half[0] * ux, centre[1] + half[1] * uy, centre[2] + half[2] * uz};
  }
  return p;
}

/// Squared distance from p to triangle abc (Ericson, Real-Time Collision Detection, 5.1.5).
inline double point_triangle_distance2(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = dot(ab, ap), d2 = dot(ac, ap);
  auto d2of = [&](const Vec3& q) { return dot(p - q, p - q); };
  if (d1 <= 0 && d2 <= 0) return d2of(a);
  const Vec3 bp = p - b;
  const double d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return d2of(b);
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return d2of(a + (d1 / (d1 - d3)) * ab);
  const Vec3 cp = p - c;
  const double d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return d2of(c);
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return d2of(a + (d2 / (d2 - d6)) * ac);
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0)
    return d2of(b + ((d4 - d3) / ((d4 - d3) + (d5 - d6))) * (c - b));
  const double denom = 1.0 / (va + vb + vc);
  return d2of(a + (vb * denom) * ab + (vc * denom) * ac);
}

/// Is p within distance r of the core (inside the dilated body)?
inline bool in_dilated(const ConvexPolyhedron& k, const Vec3& p, double r) {
  if (k.is_point()) return dot(p - k.vertices()[0], p - k.vertices()[0]) <= r * r;
  bool inside = true;
  for (std::size_t f = 0; f < k.triangles().size() && inside; ++f)
    inside = dot(k.normals()[f], p - k.vertices()[std::size_t(k.triangles()[f][0])]) <= 0;
  if (inside) return true;
  double best = INFINITY;
  for (const Triangle& t : k.triangles())
    best = std::min(best, point_triangle_distance2(p, k.vertices()[std::size_t(t[0])],
                                                   k.vertices()[std::size_t(t[1])],
                                                   k.vertices()[std::size_t(t[2])]));
  return best <= r * r;
}

/// Stratified Monte Carlo estimate of V, int x and int x x^T of the dilated body over the box
/// [lo, hi] split into n^3 cells with two jittered samples each; `se` are the standard errors
/// estimated from the pairs (var of a cell's mean = (f1 - f2)^2 / 4).
struct McMoments {
  double v = 0, v_se = 0;
  std::array<double, 3> s{}, s_se{};
  std::array<std::array<double, 3>, 3> c{}, c_se{};
};

inline McMoments monte_carlo_moments(const ConvexPolyhedron& k, double r, const Vec3& lo,
                                     const Vec3& hi, int n, std::uint64_t seed) {
  std::mt19937_64 gen(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const Vec3 h{(hi[0] - lo[0]) / n, (hi[1] - lo[1]) / n, (hi[2] - lo[2]) / n};
  const double cell = h[0] * h[1] * h[2];
  McMoments m;
  std::array<std::array<double, 3>, 3> cvar{};
  std::array<double, 3> svar{};
  double vvar = 0;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      for (int l = 0; l < n; ++l) {
        double f[2] = {0, 0};
        Vec3 x[2];
        for (int s = 0; s < 2; ++s) {
          x[s] = {lo[0] + (i + u(gen)) * h[0], lo[1] + (j + u(gen)) * h[1],
                  lo[2] + (l + u(gen)) * h[2]};
          f[s] = in_dilated(k, x[s], r) ? 1.0 : 0.0;
        }
        if (f[0] == 0 && f[1] == 0) continue;
        m.v += 0.5 * (f[0] + f[1]) * cell;
        vvar += 0.25 * (f[0] - f[1]) * (f[0] - f[1]) * cell * cell;
        for (int a = 0; a < 3; ++a) {
          const double g0 = f[0] * x[0][a], g1 = f[1] * x[1][a];
          m.s[a] += 0.5 * (g0 + g1) * cell;
          svar[a] += 0.25 * (g0 - g1) * (g0 - g1) * cell * cell;
          for (int b = 0; b < 3; ++b) {
            const double q0 = f[0] * x[0][a] * x[0][b], q1 = f[1] * x[1][a] * x[1][b];
            m.c[a][b] += 0.5 * (q0 + q1) * cell;
            cvar[a][b] += 0.25 * (q0 - q1) * (q0 - q1) * cell * cell;
          }
        }
      }
  m.v_se = std::sqrt(vvar);
  for (int a = 0; a < 3; ++a) {
    m.s_se[a] = std::sqrt(svar[a]);
    for (int b = 0; b < 3; ++b) m.c_se[a][b] = std::sqrt(cvar[a][b]);
  }
  return m;
}

}  // namespace demfem::dem::shapes::test
