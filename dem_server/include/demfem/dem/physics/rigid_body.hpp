#pragma once
// Rigid-body rotation with a full inertia tensor (non-spherical particles), shared by both
// backends. The body frame is the principal frame of the particle (its shape's vertices are
// given in it, origin at the centre of mass), so the inertia tensor there is diag(I1, I2, I3).
// The orientation quaternion q maps body to world: x_world = x + R(q) x_body.
//
// Time stepping (the same velocity-Verlet splitting as the spheres, physics/integrator.hpp):
//   kick   ω ← ω + Δt/2 · R I⁻¹ Rᵀ τ          (world-frame angular momentum L += Δt/2 τ)
//   drift  free rotation of the body over Δt with L fixed in the world frame, by the NO_SQUISH
//          splitting of Miller, Eleftheriou, Pattnaik, Ndirango, Newns & Martyna (J. Chem. Phys.
//          116, 8649, 2002): the free-rotor energy T = Σ π_k² / (2 I_k) (π = I ω_b, the body
//          angular momentum) is split into its three terms, each of which is integrated exactly
//          (a rotation about one principal axis at the constant rate π_k / I_k), composed
//          symmetrically as R3(Δt/2) R2(Δt/2) R1(Δt) R2(Δt/2) R3(Δt/2)
//   kick   again with the new torque.
// Every sub-step is an exact rotation, so |π| and the world-frame L are conserved to rounding
// during the drift; the composition is symplectic and time-reversible, so the energy error of
// a free body stays bounded, O((|ω| Δt)²), without drift (tests/dem/core/test_rigid_body.cpp).
// ω is kept in the world frame in the state (as for spheres); the drift converts it to π and
// back.

#include "demfem/dem/physics/integrator.hpp"

namespace demfem::dem::phys {

/// Rotation matrix of a unit quaternion, row-major: world = R body.
struct Rot {
  double m[9];
};

DEMFEM_HD Rot rotation(double qw, double qx, double qy, double qz) {
  const double xx = qx * qx, yy = qy * qy, zz = qz * qz;
  const double xy = qx * qy, xz = qx * qz, yz = qy * qz;
  const double wx = qw * qx, wy = qw * qy, wz = qw * qz;
  return Rot{{1.0 - 2.0 * (yy + zz), 2.0 * (xy - wz), 2.0 * (xz + wy), 2.0 * (xy + wz),
              1.0 - 2.0 * (xx + zz), 2.0 * (yz - wx), 2.0 * (xz - wy), 2.0 * (yz + wx),
              1.0 - 2.0 * (xx + yy)}};
}

/// R a (body to world).
DEMFEM_HD Vec3 to_world(const Rot& r, Vec3 a) {
  return {r.m[0] * a.x + r.m[1] * a.y + r.m[2] * a.z, r.m[3] * a.x + r.m[4] * a.y + r.m[5] * a.z,
          r.m[6] * a.x + r.m[7] * a.y + r.m[8] * a.z};
}

/// Rᵀ a (world to body).
DEMFEM_HD Vec3 to_body(const Rot& r, Vec3 a) {
  return {r.m[0] * a.x + r.m[3] * a.y + r.m[6] * a.z, r.m[1] * a.x + r.m[4] * a.y + r.m[7] * a.z,
          r.m[2] * a.x + r.m[5] * a.y + r.m[8] * a.z};
}

/// R diag(1/I) Rᵀ a: the world-frame inverse inertia tensor applied to a.
DEMFEM_HD Vec3 inverse_inertia_world(const Rot& r, Vec3 inertia, Vec3 a) {
  const Vec3 b = to_body(r, a);
  return to_world(r, Vec3{b.x / inertia.x, b.y / inertia.y, b.z / inertia.z});
}

/// Rotational kinetic energy ½ ω·(I ω) of a body with principal moments `inertia` and
/// orientation r, ω in the world frame.
DEMFEM_HD double rotational_energy(const Rot& r, Vec3 inertia, Vec3 w) {
  const Vec3 b = to_body(r, w);
  return 0.5 * (inertia.x * b.x * b.x + inertia.y * b.y * b.y + inertia.z * b.z * b.z);
}

/// cos(θ/2) and sin(θ/2) of an angle θ: the Taylor series for small angles (the usual DEM
/// step: |θ| < 2e-2, relative error < 1e-18, as rotate_quaternion_small()), sin/cos otherwise.
DEMFEM_HD void half_angle(double theta, double& c, double& s) {
  const double h = 0.5 * theta;
  const double h2 = h * h;
  if (h2 < 1e-4) {
    s = h * (1.0 - h2 / 6.0 * (1.0 - h2 / 20.0 * (1.0 - h2 / 42.0)));
    c = 1.0 - 0.5 * h2 * (1.0 - h2 / 12.0 * (1.0 - h2 / 30.0));
  } else {
    s = std::sin(h);
    c = std::cos(h);
  }
}

/// One NO_SQUISH sub-step: free rotation about principal axis k (0, 1, 2) for time h. The body
/// turns by θ = h π_k / I_k about its axis k: q ← q ⊗ (cos θ/2, sin θ/2 e_k); in the body frame
/// π turns the other way, by −θ about e_k (Euler's equation dπ/dt = π × ω_b).
DEMFEM_HD void rotate_about_principal(Quat& q, Vec3& pi, int k, double inertia_k, double h) {
  const double pk = k == 0 ? pi.x : (k == 1 ? pi.y : pi.z);
  double c, s;
  half_angle(h * pk / inertia_k, c, s);
  // π rotated by -θ about e_k: cos θ = c² - s², sin θ = 2 s c
  const double ct = c * c - s * s, st = 2.0 * s * c;
  Quat r{c, 0, 0, 0};
  if (k == 0) {
    r.x = s;
    const double y = pi.y, z = pi.z;
    pi.y = ct * y + st * z;
    pi.z = -st * y + ct * z;
  } else if (k == 1) {
    r.y = s;
    const double z = pi.z, x = pi.x;
    pi.z = ct * z + st * x;
    pi.x = -st * z + ct * x;
  } else {
    r.z = s;
    const double x = pi.x, y = pi.y;
    pi.x = ct * x + st * y;
    pi.y = -st * x + ct * y;
  }
  // q ⊗ r (body-frame rotation: multiplied on the right)
  q = Quat{
      q.w * r.w - q.x * r.x - q.y * r.y - q.z * r.z, q.w * r.x + q.x * r.w + q.y * r.z - q.z * r.y,
      q.w * r.y - q.x * r.z + q.y * r.w + q.z * r.x, q.w * r.z + q.x * r.y - q.y * r.x + q.z * r.w};
}

/// Drift of the orientation over dt for a free body (NO_SQUISH, see the file comment): q and
/// the world-frame ω are advanced; the world-frame angular momentum R I Rᵀ ω is conserved to
/// rounding. The quaternion is renormalised (one Newton step, as turn_normalised()).
DEMFEM_HD void free_rotation(double& qw, double& qx, double& qy, double& qz, double& wx, double& wy,
                             double& wz, Vec3 inertia, double dt) {
  Quat q{qw, qx, qy, qz};
  const Rot r0 = rotation(qw, qx, qy, qz);
  const Vec3 wb = to_body(r0, Vec3{wx, wy, wz});
  Vec3 pi{inertia.x * wb.x, inertia.y * wb.y, inertia.z * wb.z};
  const double h = 0.5 * dt;
  rotate_about_principal(q, pi, 2, inertia.z, h);
  rotate_about_principal(q, pi, 1, inertia.y, h);
  rotate_about_principal(q, pi, 0, inertia.x, dt);
  rotate_about_principal(q, pi, 1, inertia.y, h);
  rotate_about_principal(q, pi, 2, inertia.z, h);
  const double inv = 1.5 - 0.5 * (q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z);
  qw = q.w * inv, qx = q.x * inv, qy = q.y * inv, qz = q.z * inv;
  const Rot r1 = rotation(qw, qx, qy, qz);
  const Vec3 w = to_world(r1, Vec3{pi.x / inertia.x, pi.y / inertia.y, pi.z / inertia.z});
  wx = w.x, wy = w.y, wz = w.z;
}

/// Half kick of the angular velocity of a rigid body: ω += h R I⁻¹ Rᵀ τ (world frame).
DEMFEM_HD void angular_kick(double& wx, double& wy, double& wz, double qw, double qx, double qy,
                            double qz, Vec3 inertia, Vec3 torque, double h) {
  const Vec3 dw = inverse_inertia_world(rotation(qw, qx, qy, qz), inertia, torque);
  wx += h * dw.x;
  wy += h * dw.y;
  wz += h * dw.z;
}

}  // namespace demfem::dem::phys
