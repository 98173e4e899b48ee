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
  const double rw = c, rx = s * wx, ry = s * wy, rz = s * wz;
  const double nw = rw * q0w - rx * q0x - ry * q0y - rz * q0z;
  const double nx = rw * q0x + rx * q0w + ry * q0z - rz * q0y;
  const double ny = rw * q0y - rx * q0z + ry * q0w + rz * q0x;
  const double nz = rw * q0z + rx * q0y - ry * q0x + rz * q0w;
  const double inv = 1.0 / std::sqrt(nw * nw + nx * nx + ny * ny + nz * nz);
  const bool turn = w2 != 0.0;
  qw = turn ? nw * inv : q0w;
  qx = turn ? nx * inv : q0x;
  qy = turn ? ny * inv : q0y;
  qz = turn ? nz * inv : q0z;
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
  const double rw = c, rx = s * wx, ry = s * wy, rz = s * wz;
  const double nw = rw * qw - rx * qx - ry * qy - rz * qz;
  const double nx = rw * qx + rx * qw + ry * qz - rz * qy;
  const double ny = rw * qy - rx * qz + ry * qw + rz * qx;
  const double nz = rw * qz + rx * qy - ry * qx + rz * qw;
  const double inv = 1.0 / std::sqrt(nw * nw + nx * nx + ny * ny + nz * nz);
  qw = nw * inv;
  qx = nx * inv;
  qy = ny * inv;
  qz = nz * inv;
}

}  // namespace demfem::dem::phys
