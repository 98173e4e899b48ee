#pragma once
// Explicit second-order integration (velocity Verlet, as in LIGGGHTS):
//   v_{n+1/2} = v_n + Δt/2 a_n,   x_{n+1} = x_n + Δt v_{n+1/2},
//   forces at x_{n+1} (damping sees v_{n+1/2}),   v_{n+1} = v_{n+1/2} + Δt/2 a_{n+1}.
// Spheres have an isotropic inertia tensor, so Euler's equation (eq. 2.2) is I ω̇ = M in the
// global frame; the orientation quaternion is advanced by the exact rotation of ω_{n+1/2} Δt.

#include "demfem/dem/physics/hd.hpp"

namespace demfem::dem::phys {

/// Half kick: v += h f / m.
DEMFEM_HD void kick(double& vx, double& vy, double& vz, double fx, double fy, double fz,
                    double h_over_m) {
  vx += h_over_m * fx;
  vy += h_over_m * fy;
  vz += h_over_m * fz;
}

/// A quaternion w + x i + y j + z k.
struct Quat {
  double w, x, y, z;
};

/// r ⊗ q, normalised: orientation q turned by the rotation r. Both are unit quaternions to
/// rounding, so |r ⊗ q|² = 1 + ε with ε ~ 1e-16, and one Newton step for 1/sqrt about 1,
/// (3 - |n|²) / 2 = 1 - ε/2, normalises it to O(ε²) without a square root and a division (they
/// were the most expensive part of the orientation update). The test against the exact
/// rotation holds |q| = 1 within 1e-13 over 1e5 steps.
DEMFEM_HD Quat turn_normalised(Quat r, Quat q) {
  const double nw = r.w * q.w - r.x * q.x - r.y * q.y - r.z * q.z;
  const double nx = r.w * q.x + r.x * q.w + r.y * q.z - r.z * q.y;
  const double ny = r.w * q.y - r.x * q.z + r.y * q.w + r.z * q.x;
  const double nz = r.w * q.z + r.x * q.y - r.y * q.x + r.z * q.w;
  const double inv = 1.5 - 0.5 * (nw * nw + nx * nx + ny * ny + nz * nz);
  return {nw * inv, nx * inv, ny * inv, nz * inv};
}

/// True when the rotation angle |ω| Δt of a step is small enough (< 2e-2 rad) for the series
/// of rotate_quaternion_small().
DEMFEM_HD bool small_rotation(double w2, double dt) {
  return 0.25 * w2 * dt * dt < 1e-4;
}

/// q ← rotation(ω Δt) ⊗ q, normalised, for small_rotation(|ω|², Δt): Taylor series of
/// sin(x)/x and cos(x) to x^6 (relative error < 1e-18 for x < 1e-2), no sin/cos and no
/// branch (the CPU runs it in SIMD lanes). ω = 0 leaves q unchanged.
DEMFEM_HD void rotate_quaternion_small(double& qw, double& qx, double& qy, double& qz, double wx,
                                       double wy, double wz, double dt) {
  const double w2 = wx * wx + wy * wy + wz * wz;
  const double h2 = 0.25 * w2 * dt * dt;                // (|ω| Δt / 2)^2
  const double q0w = qw, q0x = qx, q0y = qy, q0z = qz;  // selects read values, not memory
  const double s = 0.5 * dt * (1.0 - h2 / 6.0 * (1.0 - h2 / 20.0 * (1.0 - h2 / 42.0)));
  const double c = 1.0 - 0.5 * h2 * (1.0 - h2 / 12.0 * (1.0 - h2 / 30.0));
  const Quat n = turn_normalised({c, s * wx, s * wy, s * wz}, {q0w, q0x, q0y, q0z});
  const bool turn = w2 != 0.0;
  qw = turn ? n.w : q0w;
  qx = turn ? n.x : q0x;
  qy = turn ? n.y : q0y;
  qz = turn ? n.z : q0z;
}

/// q ← rotation(ω Δt) ⊗ q, normalised.
DEMFEM_HD void rotate_quaternion(double& qw, double& qx, double& qy, double& qz, double wx,
                                 double wy, double wz, double dt) {
  const double w2 = wx * wx + wy * wy + wz * wz;
  if (w2 == 0.0) return;
  if (small_rotation(w2, dt)) {
    rotate_quaternion_small(qw, qx, qy, qz, wx, wy, wz, dt);
    return;
  }
  const double wn = std::sqrt(w2);
  const double half = 0.5 * wn * dt;
  const double s = std::sin(half) / wn;
  const double c = std::cos(half);
  const Quat n = turn_normalised({c, s * wx, s * wy, s * wz}, {qw, qx, qy, qz});
  qw = n.w, qx = n.x, qy = n.y, qz = n.z;
}

}  // namespace demfem::dem::phys
