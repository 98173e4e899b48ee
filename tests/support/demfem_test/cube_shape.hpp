#pragma once
// A test shape with closed-form geometry: the cube core of half side 0.3 (dilation 0.2, volume
// 1, inertia 0.1), and a particle of it at scale 0.05 turned by 0.6 rad about x, at (1, 2, 3):
// its surface and top follow from sin 0.6 and cos 0.6 (tests of sensors and output).

#include <array>
#include <cmath>
#include <vector>

#include "demfem/dem/dem_system.hpp"

namespace demfem::test {

inline dem::PolyhedronShape cube_shape() {
  dem::PolyhedronShape cube;
  cube.name = "cube";
  for (int k = 0; k < 8; ++k)
    cube.vertices.insert(cube.vertices.end(),
                         {k & 1 ? 0.3 : -0.3, k & 2 ? 0.3 : -0.3, k & 4 ? 0.3 : -0.3});
  const int q[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                       {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& f : q)
    cube.triangles.insert(cube.triangles.end(), {f[0], f[1], f[2], f[0], f[2], f[3]});
  cube.dilation = 0.2, cube.volume = 1.0, cube.inertia = {0.1, 0.1, 0.1};
  return cube;
}

/// A particle of shape `shape_id` (a cube_shape()) at scale 0.05, turned by 0.6 rad about x.
inline dem::ParticleInit tilted_cube(std::int32_t shape_id) {
  dem::ParticleInit p;
  p.shape = dem::ParticleShape::polyhedron;
  p.shape_id = shape_id;
  p.scale = 0.05;
  p.position = {1.0, 2.0, 3.0};
  p.orientation = {std::cos(0.3), std::sin(0.3), 0.0, 0.0};
  return p;
}

/// A system (dt 1e-5 s) of the one particle material `material`, its pair μ 0.5, e 0.5, holding
/// the tilted cube (shape 0, particle 0) and a sphere of radius 10 mm at `sphere_at`
/// (particle 1): the polyhedron beside a sphere that the output and sensor tests compare.
inline dem::DemSystem cube_and_sphere(const dem::Material& material,
                                      std::array<double, 3> sphere_at) {
  dem::DemSettings st;
  st.dt = 1e-5;
  st.materials = {material};
  st.pairs = {dem::MaterialPair{0.5, 0.5, 0.0}};
  dem::DemSystem sys(st);
  sys.add_shape(cube_shape());
  dem::ParticleInit sphere;
  sphere.radius = 0.01;
  sphere.position = sphere_at;
  sys.add_particles(std::vector<dem::ParticleInit>{tilted_cube(0), sphere});
  return sys;
}

}  // namespace demfem::test
