#pragma once
// Prescribed kinematics of the walls and the force transfer to the flexible mesh, shared by
// the CPU backend (WallStore::update, WallStore::reduce in src/core) and the CUDA backend
// (cuda/dem_cuda.cu):
//   * rigid motion of a wall (WallMotion: translation, rotation about an axis (Rodrigues),
//     sinusoid along an axis with an optional steady drift), active in [start_time, end_time) and
//     at rest with the reached pose outside; the reference vertices are the pose at start_time;
//   * a node of the flexible mesh within one advance(): x(τ) = x + v τ + a τ²/2,
//     v(τ) = v + a τ (the constant acceleration of the structure's step);
//   * the share of a contact force that a node of the touched triangle receives (barycentric
//     weight of the contact point: sum and moment of the force are preserved).
// Plain structs only, so that the device takes them by value.

#include "demfem/dem/physics/hd.hpp"

namespace demfem::dem::phys {

/// Kinds of rigid motion; the values equal those of WallMotion::Kind.
enum : int { kMotionFixed = 0, kMotionTranslation = 1, kMotionRotation = 2, kMotionSinusoid = 3 };

/// Rigid motion of one wall (a POD copy of WallMotion). axis is unit length for the sinusoid
/// (add_wall normalises it); the rotation normalises it here.
struct RigidMotion {
  int kind;
  double velocity[3];                                    ///< translation, m/s
  double axis_point[3];                                  ///< rotation: a point on the axis, m
  double axis[3];                                        ///< rotation axis / sinusoid direction
  double angular_velocity, amplitude, frequency, phase;  ///< rad/s, m, Hz, rad
  double start_time, end_time;                           ///< s
};

/// The motion of a wall at one time, common to all its vertices.
struct RigidPose {
  int kind;
  double shift[3];  ///< translation, sinusoid: x = x0 + shift
  double vel[3];    ///< translation, sinusoid: v = vel
  Vec3 a, o;        ///< rotation: unit axis, point on the axis
  double c, s, w;   ///< rotation: cos θ, sin θ, angular velocity (0 when inactive)
};

/// Pose of a wall at time t whose drift (the translation's velocity, the sinusoid's steady
/// velocity) has advanced for `drift_el` seconds and moves now at `drift_rate` (in [0, 1]) of
/// its velocity. The clamped elapsed time el = clamp(t, t0, t1) - t0 gives the rest of the
/// pose; the velocity is zero outside [t0, t1).
DEMFEM_HD RigidPose rigid_pose(const RigidMotion& m, double t, double drift_el, double drift_rate) {
  RigidPose p{};
  p.kind = m.kind;
  const double tc = t < m.start_time ? m.start_time : (m.end_time < t ? m.end_time : t);
  const double el = tc - m.start_time;
  const bool active = t >= m.start_time && t < m.end_time;
  if (m.kind == kMotionTranslation) {
    for (int d = 0; d < 3; ++d) {
      p.shift[d] = m.velocity[d] * drift_el;
      p.vel[d] = drift_rate > 0.0 ? drift_rate * m.velocity[d] : 0.0;
    }
  } else if (m.kind == kMotionSinusoid) {
    const double pi = 3.14159265358979323846;
    const double arg = 2 * pi * m.frequency * el + m.phase;
    const double u = m.amplitude * std::sin(arg);
    const double du = active ? m.amplitude * 2 * pi * m.frequency * std::cos(arg) : 0.0;
    // plus a steady drift (a compaction plate that descends while it vibrates; 0 = none)
    for (int d = 0; d < 3; ++d) {
      p.shift[d] = m.axis[d] * u + m.velocity[d] * drift_el;
      p.vel[d] = m.axis[d] * du + (drift_rate > 0.0 ? drift_rate * m.velocity[d] : 0.0);
    }
  } else if (m.kind == kMotionRotation) {
    const Vec3 ax{m.axis[0], m.axis[1], m.axis[2]};
    const double an = std::sqrt(norm2(ax));
    p.a = (1.0 / an) * ax;
    const double th = m.angular_velocity * el;
    p.c = std::cos(th);
    p.s = std::sin(th);
    p.o = Vec3{m.axis_point[0], m.axis_point[1], m.axis_point[2]};
    p.w = active ? m.angular_velocity : 0.0;
  }
  return p;
}

/// Pose of a wall at time t whose drift is not force-limited: it has advanced for the
/// clamped elapsed time and moves while the motion is active.
DEMFEM_HD RigidPose rigid_pose(const RigidMotion& m, double t) {
  const double tc = t < m.start_time ? m.start_time : (m.end_time < t ? m.end_time : t);
  return rigid_pose(m, t, tc - m.start_time, t >= m.start_time && t < m.end_time ? 1.0 : 0.0);
}

/// Angular velocity of a wall at time t: ω â for a rotation while it is active, else zero.
/// (The contact point's velocity needs no spin: the vertex velocities carry it, and their
/// barycentric interpolation is exact for a rigid motion; the rolling resistance needs the
/// wall's spin to take the particle's rolling relative to the wall.)
DEMFEM_HD Vec3 rigid_spin(const RigidMotion& m, double t) {
  if (m.kind != kMotionRotation || !(t >= m.start_time && t < m.end_time)) return Vec3{0, 0, 0};
  const Vec3 ax{m.axis[0], m.axis[1], m.axis[2]};
  return (m.angular_velocity / std::sqrt(norm2(ax))) * ax;
}

/// Position x and velocity v (3 each) of the vertex with reference position x0 in pose p.
/// A fixed wall (kind 0) leaves x and v untouched.
DEMFEM_HD void rigid_vertex(const RigidPose& p, const double* x0, double* x, double* v) {
  if (p.kind == kMotionTranslation || p.kind == kMotionSinusoid) {
    for (int d = 0; d < 3; ++d) {
      x[d] = x0[d] + p.shift[d];
      v[d] = p.vel[d];
    }
  } else if (p.kind == kMotionRotation) {
    const Vec3 r = Vec3{x0[0], x0[1], x0[2]} - p.o;
    const Vec3 rr = p.c * r + p.s * cross(p.a, r) + ((1 - p.c) * dot(p.a, r)) * p.a;
    const Vec3 q = p.o + rr;
    const Vec3 vel = p.w * cross(p.a, rr);
    x[0] = q.x, x[1] = q.y, x[2] = q.z;
    v[0] = vel.x, v[1] = vel.y, v[2] = vel.z;
  }
}

/// One coordinate of a flexible node at time tau into the advance(): start position x0,
/// velocity v0, constant acceleration a.
DEMFEM_HD void flexible_node(double x0, double v0, double a, double tau, double& x, double& v) {
  x = x0 + v0 * tau + 0.5 * a * tau * tau;
  v = v0 + a * tau;
}

/// Share of the force f_on_wall (the negated force on the particle) that the node with
/// barycentric weight b of the contact point receives.
DEMFEM_HD Vec3 node_share(double b, Vec3 f_on_wall) {
  return b * f_on_wall;
}

}  // namespace demfem::dem::phys
