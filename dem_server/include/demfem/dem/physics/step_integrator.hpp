#pragma once
// One DEM time step around the force pass, written once for both backends: the first half
// kick and drift of a particle, the finish of the force pass (gravity and the second half
// kick), the displacement that the neighbour list's skin is checked against, and the rule that
// decides when the list is refiltered or rebuilt. The CPU loops (dem_step.cpp, polyhedra.cpp)
// and the CUDA kernels (dem_cuda.cu) call these per particle; the order of every operation is
// fixed here, so the backends round alike (velocity Verlet, integrator.hpp; rigid bodies,
// rigid_body.hpp).

#include <cstdint>

#include "demfem/dem/physics/integrator.hpp"
#include "demfem/dem/physics/rigid_body.hpp"

namespace demfem::dem::phys {

/// The particle arrays that a step moves (host or device pointers, one entry per particle).
/// A particle is a rigid body with a full inertia tensor (a polyhedron) when shape_id is not
/// null and shape_id[i] >= 0; otherwise a sphere (isotropic inertia `inertia`).
struct MotionArrays {
  double *px, *py, *pz;          ///< position, m
  double *vx, *vy, *vz;          ///< velocity, m/s
  double *wx, *wy, *wz;          ///< angular velocity (world frame), rad/s
  double *qw, *qx, *qy, *qz;     ///< orientation
  double *fx, *fy, *fz;          ///< force of the last force pass, N
  double *tx, *ty, *tz;          ///< torque of the last force pass, N m
  const double* mass;            ///< kg
  const double* inertia;         ///< a sphere's moment of inertia, kg m²
  const double *ix, *iy, *iz;    ///< a rigid body's principal moments, kg m² (null: none)
  const std::int32_t* shape_id;  ///< >= 0: a rigid body's shape (null: spheres only)
};

/// Puts particle i back at rest in the pose `h` (x, y, z, qw, qx, qy, qz) it was frozen in
/// (DemSystem::freeze): after the drift and after the force pass, bit for bit, on both
/// backends.
DEMFEM_HD void hold_pose(const MotionArrays& m, std::int64_t i, const double* h) {
  m.px[i] = h[0], m.py[i] = h[1], m.pz[i] = h[2];
  m.qw[i] = h[3], m.qx[i] = h[4], m.qy[i] = h[5], m.qz[i] = h[6];
  m.vx[i] = m.vy[i] = m.vz[i] = 0.0;
  m.wx[i] = m.wy[i] = m.wz[i] = 0.0;
}

/// True when particle i turns as a rigid body with a full inertia tensor.
DEMFEM_HD bool rigid_body(const MotionArrays& m, std::int64_t i) {
  return m.shape_id != nullptr && m.shape_id[i] >= 0;
}

/// First half kick of i's velocity by its last force, then the drift over dt.
DEMFEM_HD void kick_drift_translation(const MotionArrays& m, std::int64_t i, double dt) {
  const double h = 0.5 * dt;
  kick(m.vx[i], m.vy[i], m.vz[i], m.fx[i], m.fy[i], m.fz[i], h / m.mass[i]);
  m.px[i] += dt * m.vx[i];
  m.py[i] += dt * m.vy[i];
  m.pz[i] += dt * m.vz[i];
}

/// Half kick of sphere i's angular velocity by torque t over h = Δt/2.
DEMFEM_HD void kick_sphere_spin(const MotionArrays& m, std::int64_t i, double tx, double ty,
                                double tz, double h) {
  kick(m.wx[i], m.wy[i], m.wz[i], tx, ty, tz, h / m.inertia[i]);
}

/// First half kick of i's rotation by its last torque and the turn of its orientation over dt:
/// a rigid body by its full inertia (NO_SQUISH, rigid_body.hpp); a sphere's spin is kicked when
/// `spin` (friction or rolling resistance gives it a torque) and its orientation turned by the
/// exact rotation of ω Δt when `turn` (the orientation is integrated).
DEMFEM_HD void kick_turn(const MotionArrays& m, std::int64_t i, double dt, bool spin, bool turn) {
  const double h = 0.5 * dt;
  if (rigid_body(m, i)) {
    const Vec3 I{m.ix[i], m.iy[i], m.iz[i]};
    angular_kick(m.wx[i], m.wy[i], m.wz[i], m.qw[i], m.qx[i], m.qy[i], m.qz[i], I,
                 Vec3{m.tx[i], m.ty[i], m.tz[i]}, h);
    free_rotation(m.qw[i], m.qx[i], m.qy[i], m.qz[i], m.wx[i], m.wy[i], m.wz[i], I, dt);
    return;
  }
  if (spin) kick_sphere_spin(m, i, m.tx[i], m.ty[i], m.tz[i], h);
  if (turn) rotate_quaternion(m.qw[i], m.qx[i], m.qy[i], m.qz[i], m.wx[i], m.wy[i], m.wz[i], dt);
}

/// The whole first half of a step for particle i: kick_drift_translation, then kick_turn.
DEMFEM_HD void kick_drift(const MotionArrays& m, std::int64_t i, double dt, bool spin, bool turn) {
  kick_drift_translation(m, i, dt);
  kick_turn(m, i, dt, spin, turn);
}

/// Squared distance of i from where it was at the last list update (bx, by, bz).
DEMFEM_HD double displacement2(const MotionArrays& m, std::int64_t i, const double* bx,
                               const double* by, const double* bz) {
  const double dx = m.px[i] - bx[i], dy = m.py[i] - by[i], dz = m.pz[i] - bz[i];
  return dx * dx + dy * dy + dz * dz;
}

/// The finish of the force pass for particle i, given the contact force f and torque q summed
/// on it: adds gravity g (m/s²), stores the force, and gives the second half kick; the torque
/// is stored and kicks the rotation of a rigid body always, of a sphere when `spin`.
DEMFEM_HD void finish_kick(const MotionArrays& m, std::int64_t i, Vec3 f, Vec3 q, double gx,
                           double gy, double gz, double dt, bool spin) {
  const double h = 0.5 * dt;
  const double mass = m.mass[i];
  f.x += mass * gx, f.y += mass * gy, f.z += mass * gz;
  m.fx[i] = f.x, m.fy[i] = f.y, m.fz[i] = f.z;
  kick(m.vx[i], m.vy[i], m.vz[i], f.x, f.y, f.z, h / mass);
  if (rigid_body(m, i)) {
    m.tx[i] = q.x, m.ty[i] = q.y, m.tz[i] = q.z;
    angular_kick(m.wx[i], m.wy[i], m.wz[i], m.qw[i], m.qx[i], m.qy[i], m.qz[i],
                 Vec3{m.ix[i], m.iy[i], m.iz[i]}, q, h);
  } else if (spin) {
    m.tx[i] = q.x, m.ty[i] = q.y, m.tz[i] = q.z;
    kick_sphere_spin(m, i, q.x, q.y, q.z, h);
  }
}

/// The neighbour list's update rule. A grid build keeps the candidate pairs within
/// r_i + r_j + skin; the list proper holds those within r_i + r_j + skin_in and is refiltered
/// from them (two levels; skin_in >= skin: one level, the list is the build's). pd bounds
/// d_i + d_j of any pair since the last list update (build or refilter).
struct ListRule {
  double skin;      ///< build skin, m
  double skin_in;   ///< list skin, m
  double out_pair;  ///< bound of d_i + d_j of any pair since the build, refilters summed, m

  DEMFEM_HD bool one_level() const { return skin_in >= skin; }
  /// The candidates may miss a pair that comes within skin_in: build.
  DEMFEM_HD bool build_by_pairs(double pd) const {
    return one_level() ? pd > skin : out_pair + pd > skin - skin_in;
  }
  /// A pair outside the list may touch: refilter (two levels only).
  DEMFEM_HD bool refilter_by_pairs(double pd) const { return !one_level() && pd > skin_in; }
  /// A particle (moved by at most `dbuild` since the build) and a wall vertex (moved by at
  /// most `wdisp`) may have closed the skin: build.
  DEMFEM_HD bool build_by_walls(double dbuild, double wdisp) const { return dbuild + wdisp > skin; }
};

}  // namespace demfem::dem::phys
