#pragma once
// Sphere–sphere and sphere–wall contact kinematics (overlap, normal, effective radius and
// mass, relative velocity at the contact point, eq. 2.8, 2.9, 2.11, 2.23), feeding the
// contact law of contact.hpp. Called by both backends over their SoA arrays.

#include "demfem/dem/physics/contact.hpp"
#include "demfem/dem/physics/periodic_image.hpp"

namespace demfem::dem::phys {

/// Read-only view of the particle arrays (host or device pointers).
struct ParticleView {
  const double *px, *py, *pz, *vx, *vy, *vz, *wx, *wy, *wz, *radius, *mass;
};

/// Contact of spheres i and j (i's row in the pair list), evaluated without a branch on
/// the overlap (the CPU runs it in SIMD lanes over the pair list). Returns whether they
/// overlap. On contact: `out` holds the force on i (j gets the opposite), n × F_t (torque on
/// i = r_i n × F_t, on j = r_j n × F_t) and the rolling torque on i; `shear` and `roll` (the
/// rolling-torque history, used when Friction and Rolling) are updated; `delta` is the
/// overlap. Without contact `out`, `shear` and `roll` are zero and `delta` is 0.
/// Periodic: j is taken at its image nearest to i (periodic_image.hpp; `box` not null).
template <bool Friction, bool Rolling = true, bool Periodic = false>
DEMFEM_HD bool sphere_sphere_select(const ParticleView& p, int i, int j, const PairConstants& c,
                                    double dt, Vec3& shear, Vec3& roll, ContactResult& out,
                                    double& delta, const PeriodicBox* box = nullptr) {
  double dx = p.px[j] - p.px[i], dy = p.py[j] - p.py[i], dz = p.pz[j] - p.pz[i];
  if constexpr (Periodic) {
    dx += image_shift(*box, 0, dx);
    dy += image_shift(*box, 1, dy);
    dz += image_shift(*box, 2, dz);
  }
  const double ri = p.radius[i], rj = p.radius[j];
  const double rs = ri + rj;
  const double d2 = dx * dx + dy * dy + dz * dz;
  const bool touch = d2 < rs * rs;
  const double d = std::sqrt(d2);
  // 1/d and 1/(r_s (m_i + m_j)) (for R* and m*, eq. 2.8, 2.11) from one division: division
  // and square root are the slowest operations of the pair loop
  const double mi = p.mass[i], mj = p.mass[j];
  const double q = rs * (mi + mj);
  const double inv_dq = 1.0 / (d * q);
  const double inv = q * inv_dq;
  const double inv_rm = d * inv_dq;
  const Vec3 n{dx * inv, dy * inv, dz * inv};
  delta = touch ? rs - d : 0.0;  // eq. 2.9
  const double reff = ri * rj * (mi + mj) * inv_rm;
  const double meff = mi * mj * rs * inv_rm;
  Vec3 vrel{p.vx[i] - p.vx[j], p.vy[i] - p.vy[j], p.vz[i] - p.vz[j]};
  Vec3 wrel{0, 0, 0};
  if constexpr (Friction) {
    // v_ij = v_i - v_j + ω_i × (r_i n) - ω_j × (-r_j n)   (eq. 2.23)
    const Vec3 wsum{ri * p.wx[i] + rj * p.wx[j], ri * p.wy[i] + rj * p.wy[j],
                    ri * p.wz[i] + rj * p.wz[j]};
    vrel = vrel + cross(wsum, n);
    wrel = Vec3{p.wx[i] - p.wx[j], p.wy[i] - p.wy[j], p.wz[i] - p.wz[j]};
  }
  const ContactResult r =
      hertz_mindlin<Friction, Rolling>(c, n, delta, reff, meff, vrel, wrel, shear, roll, dt);
  const double z = 0.0;
  out.force = Vec3{touch ? r.force.x : z, touch ? r.force.y : z, touch ? r.force.z : z};
  out.torque = Vec3{touch ? r.torque.x : z, touch ? r.torque.y : z, touch ? r.torque.z : z};
  out.roll = Vec3{touch ? r.roll.x : z, touch ? r.roll.y : z, touch ? r.roll.z : z};
  out.fn = touch ? r.fn : z;
  if constexpr (Friction) {
    const Vec3 sh = shear;  // select between values, not a conditional load (vectorises)
    shear = Vec3{touch ? sh.x : z, touch ? sh.y : z, touch ? sh.z : z};
    if constexpr (Rolling) {
      const Vec3 rh = roll;
      roll = Vec3{touch ? rh.x : z, touch ? rh.y : z, touch ? rh.z : z};
    }
  }
  return touch;
}

/// Contact of spheres i and j (i's row in the pair list). Returns false when they do not
/// overlap (then nothing is written). On contact as sphere_sphere_select(); with `box` (not
/// null) j is taken at its image nearest to i.
template <bool Friction>
DEMFEM_HD bool sphere_sphere(const ParticleView& p, int i, int j, const PairConstants& c, double dt,
                             Vec3& shear, Vec3& roll, ContactResult& out, double& delta,
                             const PeriodicBox* box = nullptr) {
  double dx = p.px[j] - p.px[i], dy = p.py[j] - p.py[i], dz = p.pz[j] - p.pz[i];
  if (box != nullptr)
    dx += image_shift(*box, 0, dx), dy += image_shift(*box, 1, dy), dz += image_shift(*box, 2, dz);
  const double rs = p.radius[i] + p.radius[j];
  if (dx * dx + dy * dy + dz * dz >= rs * rs) return false;
  if (box != nullptr)
    return sphere_sphere_select<Friction, true, true>(p, i, j, c, dt, shear, roll, out, delta, box);
  return sphere_sphere_select<Friction>(p, i, j, c, dt, shear, roll, out, delta);
}

/// Contact of sphere i with a wall point `cp` (closest point of a triangle) moving with
/// velocity `vw` on a wall spinning at `ww` (rad/s). Returns false without overlap or with the
/// centre on the wall. Torque on the particle: r_i n × F_t + out.roll; `roll` is the rolling-torque
/// history (updated only where the pair has μ_r > 0).
template <bool Friction>
DEMFEM_HD bool sphere_wall(const ParticleView& p, int i, Vec3 cp, Vec3 vw, Vec3 ww,
                           const PairConstants& c, double dt, Vec3& shear, Vec3& roll,
                           ContactResult& out, double& delta) {
  const Vec3 x{p.px[i], p.py[i], p.pz[i]};
  const double ri = p.radius[i];
  const double d2 = norm2(x - cp);
  if (d2 >= ri * ri || !(d2 > 0.0)) return false;
  const double d = std::sqrt(d2);
  delta = ri - d;
  const Vec3 n = (-1.0 / d) * (x - cp);  // particle -> wall
  Vec3 vrel = Vec3{p.vx[i], p.vy[i], p.vz[i]} - vw;
  Vec3 wrel{0, 0, 0};
  if constexpr (Friction) {
    const Vec3 w{p.wx[i], p.wy[i], p.wz[i]};
    vrel = vrel + ri * cross(w, n);
    wrel = w - ww;  // rolling relative to the wall (a rotating wall carries a resting sphere)
  }
  // wall: infinite radius and mass, R* = r_i, m* = m_i
  // scalar code: pairs without rolling resistance skip the rolling spring
  if (c.rolling > 0.0)
    out = hertz_mindlin<Friction, true>(c, n, delta, ri, p.mass[i], vrel, wrel, shear, roll, dt);
  else
    out = hertz_mindlin<Friction, false>(c, n, delta, ri, p.mass[i], vrel, wrel, shear, roll, dt);
  return true;
}

}  // namespace demfem::dem::phys
