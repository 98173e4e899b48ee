#pragma once
// Small builders shared by the dem core tests.

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include "demfem/dem/dem_system.hpp"

namespace demfem::dem::test {

/// One particle material (index 0) and one wall material (index 1), all pairs alike.
inline DemSettings two_material_settings(double e_mod, double nu, double rho, double e, double mu,
                                         double dt, double rolling = 0.0) {
  DemSettings s;
  s.dt = dt;
  s.gravity = {0, 0, 0};
  s.materials = {{"grain", e_mod, nu, rho}, {"steel", e_mod, nu, 0.0}};
  s.pairs.assign(4, MaterialPair{mu, e, rolling});
  s.threads = 1;
  return s;
}

/// A square plane z = 0 (outward normal +z) of n x n cells, two triangles each, centred on
/// the origin, side L, optionally rotated about the y axis by `tilt` (rad).
inline WallMesh plane_mesh(double side, int n, double tilt = 0.0, std::int32_t material = 1) {
  WallMesh w;
  w.name = "plane";
  w.material = material;
  const double c = std::cos(tilt), s = std::sin(tilt);
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) {
      const double x = -side / 2 + side * i / n, y = -side / 2 + side * j / n;
      w.vertices.insert(w.vertices.end(), {c * x, y, -s * x});
    }
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const int a = j * (n + 1) + i, b = a + 1, d = a + n + 1, e = d + 1;
      w.triangles.insert(w.triangles.end(), {a, b, e, a, e, d});
    }
  return w;
}

/// The surface of `m` as an interface mesh: what set_flexible_mesh takes to make it the
/// flexible wall that the coupler moves (at its reference place until kinematics arrive).
inline demfem::InterfaceMesh interface_mesh_of(const WallMesh& m) {
  demfem::InterfaceMesh im;
  im.reference_positions = m.vertices;
  im.triangles = m.triangles;
  return im;
}

/// `m` as a rigid wall, or with `flexible` as the flexible mesh of material 1: the tests
/// that ask both to give the same contact forces.
inline void add_rigid_or_flexible(DemSystem& sys, const WallMesh& m, bool flexible) {
  if (flexible) {
    sys.set_flexible_mesh(interface_mesh_of(m), 1);
  } else {
    sys.add_wall(m);
  }
}

/// A roof of two faces, each two triangles over x in [-0.01, 0.01] m, falling from the ridge
/// y = 0, z = 0 to z = -0.01 at y = -0.01 and y = 0.01 (90 degrees between the faces): a
/// convex edge, material 1.
inline WallMesh roof_mesh() {
  WallMesh w;
  w.material = 1;
  w.vertices = {-0.01, 0,     0,     0.01,  0,    0,     -0.01, -0.01, -0.01,
                0.01,  -0.01, -0.01, -0.01, 0.01, -0.01, 0.01,  0.01,  -0.01};
  w.triangles = {0, 2, 3, 0, 3, 1, 0, 1, 5, 0, 5, 4};
  return w;
}

/// A floor z = 0 of two triangles over [-1, 1]^2 m (normal +z) whose shared edge is the line
/// x + y = 0: a region with x + y > 0 lies on one triangle (the wall contact history is keyed
/// by the triangle, so copies of a periodic block keep theirs).
inline WallMesh two_triangle_floor(std::int32_t material = 1) {
  WallMesh w;
  w.name = "floor";
  w.material = material;
  w.vertices = {-1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0};
  w.triangles = {0, 1, 3, 1, 2, 3};
  return w;
}

/// The closed box [lo, hi] (12 triangles, outward normals): a wall or a rigid mesh body.
inline WallMesh box_mesh(std::array<double, 3> lo, std::array<double, 3> hi,
                         std::int32_t material = 1) {
  WallMesh w;
  w.name = "box";
  w.material = material;
  for (int k = 0; k < 8; ++k)
    w.vertices.insert(w.vertices.end(),
                      {k & 1 ? hi[0] : lo[0], k & 2 ? hi[1] : lo[1], k & 4 ? hi[2] : lo[2]});
  // faces, counter-clockwise seen from outside
  const int q[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                       {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& f : q)
    w.triangles.insert(w.triangles.end(), {f[0], f[1], f[2], f[0], f[2], f[3]});
  return w;
}

inline ParticleInit sphere(std::array<double, 3> x, double r, std::array<double, 3> v = {},
                           std::array<double, 3> w = {}) {
  ParticleInit p;
  p.position = x;
  p.velocity = v;
  p.angular_velocity = w;
  p.radius = r;
  p.material = 0;
  return p;
}

/// Largest difference of one position coordinate between two states of the same particles, m.
inline double max_position_difference(const ParticleState& a, const ParticleState& b) {
  double worst = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i)
    worst = std::max({worst, std::abs(a.px[i] - b.px[i]), std::abs(a.py[i] - b.py[i]),
                      std::abs(a.pz[i] - b.pz[i])});
  return worst;
}

}  // namespace demfem::dem::test
