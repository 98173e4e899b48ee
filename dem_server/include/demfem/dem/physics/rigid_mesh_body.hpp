#pragma once
// A rigid triangle-mesh body moved by the forces of the particles on it (pressure cells, a
// rigid sleeper, a loose plate): the translational and rotational velocity-Verlet steps of a
// body with mass m, principal moments I (body frame) and orientation q, and the placement of
// its vertices. Shared by the CPU backend (DemSystem, rigid_mesh_bodies.cpp) and, later, a
// device kernel.
//
// Step (the particles' splitting, physics/integrator.hpp and rigid_body.hpp):
//   kick   v += h/2 (F + m g + F_ext) / m,  ω += h/2 R I⁻¹ Rᵀ τ          (last step's loads)
//   drift  c += h v; q, ω: free rotation over h (NO_SQUISH, rigid_body.hpp)
//   place  x_k = c + R(q) b_k,  v_k = v + ω × R(q) b_k            (b_k: body-frame vertex)
//   (the particles' contact forces on the mesh, summed about c)
//   kick   again with the new loads.
// Constraints: a fixed translation component keeps its velocity at zero (its force is
// ignored: the constraint takes it); a fixed rotation keeps ω = 0 and q as it was.

#include "demfem/dem/physics/rigid_body.hpp"

namespace demfem::dem::phys {

/// Kinematic state and constants of one rigid mesh body (a POD, device-copyable).
struct MeshBody {
  double c[3];             ///< centre of mass, m
  double v[3];             ///< velocity of the centre, m/s
  double q[4];             ///< orientation (w, x, y, z): principal frame to world
  double w[3];             ///< angular velocity, world frame, rad/s
  double force[3];         ///< contact force of the particles on the body, last step, N
  double torque[3];        ///< their torque about c, last step, N m
  double mass;             ///< kg
  double inertia[3];       ///< principal moments, kg m²
  double external[3];      ///< constant applied force (besides gravity), N
  double gravity[3];       ///< gravity acting on the body (zero when switched off), m/s²
  int fix_translation[3];  ///< 1: the component of c stays put
  int fix_rotation;        ///< 1: the orientation stays put
};

/// Half kick of a body: h = Δt/2.
DEMFEM_HD void body_kick(MeshBody& b, double h) {
  for (int d = 0; d < 3; ++d) {
    if (b.fix_translation[d]) {
      b.v[d] = 0.0;
      continue;
    }
    const double f = b.force[d] + b.external[d] + b.mass * b.gravity[d];
    b.v[d] += h * f / b.mass;
  }
  if (b.fix_rotation) {
    b.w[0] = b.w[1] = b.w[2] = 0.0;
    return;
  }
  angular_kick(b.w[0], b.w[1], b.w[2], b.q[0], b.q[1], b.q[2], b.q[3],
               Vec3{b.inertia[0], b.inertia[1], b.inertia[2]},
               Vec3{b.torque[0], b.torque[1], b.torque[2]}, h);
}

/// Drift of a body over dt.
DEMFEM_HD void body_drift(MeshBody& b, double dt) {
  for (int d = 0; d < 3; ++d) b.c[d] += dt * b.v[d];
  if (b.fix_rotation) return;
  free_rotation(b.q[0], b.q[1], b.q[2], b.q[3], b.w[0], b.w[1], b.w[2],
                Vec3{b.inertia[0], b.inertia[1], b.inertia[2]}, dt);
}

/// Position x and velocity v (3 each) of the vertex with body-frame position bv.
DEMFEM_HD void body_vertex(const MeshBody& b, const Rot& r, const double* bv, double* x,
                           double* v) {
  const Vec3 arm = to_world(r, Vec3{bv[0], bv[1], bv[2]});
  const Vec3 spin = cross(Vec3{b.w[0], b.w[1], b.w[2]}, arm);
  x[0] = b.c[0] + arm.x, x[1] = b.c[1] + arm.y, x[2] = b.c[2] + arm.z;
  v[0] = b.v[0] + spin.x, v[1] = b.v[1] + spin.y, v[2] = b.v[2] + spin.z;
}

/// Loads of the last step from the particles' force F on the mesh and its torque about the
/// origin T_o: the torque about the centre is T_o − c × F.
DEMFEM_HD void body_loads(MeshBody& b, Vec3 f, Vec3 torque_origin) {
  const Vec3 tc = torque_origin - cross(Vec3{b.c[0], b.c[1], b.c[2]}, f);
  b.force[0] = f.x, b.force[1] = f.y, b.force[2] = f.z;
  b.torque[0] = tc.x, b.torque[1] = tc.y, b.torque[2] = tc.z;
}

}  // namespace demfem::dem::phys
