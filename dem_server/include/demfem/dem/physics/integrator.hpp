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

/// q ← rotation(ω Δt) ⊗ q, normalised.
DEMFEM_HD void rotate_quaternion(double& qw, double& qx, double& qy, double& qz, double wx,
                                 double wy, double wz, double dt) {
  const double w2 = wx * wx + wy * wy + wz * wz;
  if (w2 == 0.0) return;
  const double h2 = 0.25 * w2 * dt * dt;  // (|ω| Δt / 2)^2
  double s, c;
  if (h2 < 1e-4) {
    // Taylor series of sin(x)/x and cos(x) to x^6: relative error < 1e-18 for x < 1e-2;
    // avoids sin/cos/sqrt for the usual small rotation per step.
    s = 0.5 * dt * (1.0 - h2 / 6.0 * (1.0 - h2 / 20.0 * (1.0 - h2 / 42.0)));
    c = 1.0 - 0.5 * h2 * (1.0 - h2 / 12.0 * (1.0 - h2 / 30.0));
  } else {
    const double wn = std::sqrt(w2);
    const double half = 0.5 * wn * dt;
    s = std::sin(half) / wn;
    c = std::cos(half);
  }
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
