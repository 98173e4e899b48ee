#pragma once
// Hertz–Mindlin contact law with history (thesis eq. 2.6–2.19), in the LIGGGHTS form:
//   normal:      F_n = k_n δ n + γ_n v_n,   k_n = 4/3 E* sqrt(R δ)            (eq. 2.6)
//                S_n = 2 E* sqrt(R δ) (the tangent stiffness dF/dδ, eq. 2.12)
//                γ_n = -2 sqrt(5/6) β sqrt(S_n m*),  β = ln e / sqrt(ln² e + π²) (eq. 2.10)
//   tangential:  S_t = 8 G* sqrt(R δ)                                         (eq. 2.16)
//                s  ← s rotated into the current contact plane + v_t Δt      (history)
//                F_t = -S_t s - γ_t v_t,   γ_t = -2 sqrt(5/6) β sqrt(S_t m*)  (eq. 2.15/2.18)
//                |F_t| ≤ μ |F_n|: on sliding F_t is scaled to μ|F_n| and s is reset so
//                that -S_t s - γ_t v_t = F_t (Coulomb limit, eq. 2.18)
// Because F_t = S_t(δ) s uses the current stiffness, the spring force follows the change of
// stiffness under unloading (the k_t^n / k_t^{n-1} factor of eq. 2.15).
//   rolling:     elastic-plastic spring (EPSD without its dashpot, the form LIGGGHTS calls
//                epsd2; Ai, Chen, Rotter & Ooi 2011, Powder Technol. 206:269):
//                M_r ← M_r rotated into the current contact plane - k_r ω_r Δt  (history)
//                |M_r| ≤ μ_r R F_n: beyond it M_r is scaled to the limit (full rolling)
//                k_r = 2.25 μ_r² R² S_n  (Ai et al.'s k_r = 2.25 k_n μ_r² R², k_n := S_n)
//                ω_r = ω_rel without its twist part (ω_rel - (ω_rel·n) n).
//                A constant directional torque M_r = -μ_r R F_n ω̂_rel (CDT, used before) has
//                no static state: at ω ≈ 0 its full-size torque flips with the sign of ω, so
//                a sphere on an incline creeps down by rolling at ~g sinθ Δt. The spring
//                holds it at rest while |M_r| < μ_r R F_n and gives CDT's torque once
//                saturated.
// The head-on restitution of this law equals e to < 1e-5 (checked by the tests).
// Every function here is shared by the CPU and CUDA backends; no other file holds a formula.

#include "demfem/dem/physics/hd.hpp"

namespace demfem::dem::phys {

/// Per-material-pair constants, precomputed on the host (pair_constants()).
struct PairConstants {
  double e_star;    ///< effective Young's modulus E*, Pa (eq. 2.7)
  double g_star;    ///< effective shear modulus G*, Pa (eq. 2.17)
  double beta;      ///< ln e / sqrt(ln² e + π²) (≤ 0)
  double friction;  ///< μ
  double rolling;   ///< μ_r (0 = off)
  double t_over_n;  ///< sqrt(S_t / S_n) = sqrt(4 G* / E*): γ_t = γ_n sqrt(S_t / S_n)
  /// ζ_r: damping of a polyhedron face contact's rocking mode as a ratio to critical
  /// (poly_contact.hpp, dilated_law; 0 = off; spheres and point contacts ignore it).
  double rocking;
  /// The contact law of polyhedra: kLawPressureCentre or kLawSmooth (poly_contact.hpp,
  /// smooth_contact.hpp; spheres ignore it).
  int law;
};

constexpr int kLawPressureCentre = 0;
constexpr int kLawSmooth = 1;

/// E*, G*, β of a pair from the two materials and the restitution coefficient e ∈ (0, 1].
inline PairConstants pair_constants(double e1, double nu1, double e2, double nu2,
                                    double restitution, double friction, double rolling,
                                    double rocking = 1.0, int law = kLawPressureCentre) {
  PairConstants c{};
  c.e_star = 1.0 / ((1.0 - nu1 * nu1) / e1 + (1.0 - nu2 * nu2) / e2);
  // 1/G* = (2 - ν1)/G1 + (2 - ν2)/G2 with G = E / (2(1 + ν)) (Mindlin; the form used by
  // LIGGGHTS/EDEM; eq. 2.17 of the thesis writes the same sum with 1 - ν² in the numerator).
  c.g_star = 1.0 / (2.0 * (2.0 - nu1) * (1.0 + nu1) / e1 + 2.0 * (2.0 - nu2) * (1.0 + nu2) / e2);
  const double pi = 3.14159265358979323846;
  if (restitution >= 1.0) {
    c.beta = 0.0;
  } else {
    const double l = std::log(restitution);
    c.beta = l / std::sqrt(l * l + pi * pi);
  }
  c.friction = friction;
  c.rolling = rolling;
  c.t_over_n = std::sqrt(4.0 * c.g_star / c.e_star);
  c.rocking = rocking;
  c.law = law;
  return c;
}

/// A stored tangential vector (spring, rolling torque) turned into the current tangent plane
/// of normal n: projected, then its length restored to second order in the small rotation
/// angle per step (θ² ≈ (v·n)²/|v|²), which avoids a square root: relative length error
/// O(θ⁴). No branch (the CPU pair loop runs it in SIMD lanes).
DEMFEM_HD Vec3 rotate_into_tangent_plane(Vec3 v, Vec3 n) {
  const double vn = dot(v, n);
  const Vec3 p = v - vn * n;
  const double p2 = norm2(p);
  // p2 = 0 divides by zero in the unused operand of the select only
  const double grow_any = 1.0 + 0.5 * vn * vn / p2;
  const double grow = p2 > 0.0 ? grow_any : 1.0;
  return grow * p;
}

/// Result of one contact evaluation: the force on body i (the other body gets -force).
struct ContactResult {
  Vec3 force;      ///< total contact force on i, N
  Vec3 torque;     ///< n × F_t: torque on i is a_i (n × F_t) with lever a_i (n points i → j)
  Vec3 roll;       ///< rolling-resistance torque on i (j gets -roll), N m
  double fn;       ///< magnitude of the normal force (≥ 0 or damped), N
  double gamma_n;  ///< normal damping coefficient γ_n of this contact, N s/m
  double gamma_t;  ///< tangential damping coefficient γ_t (Friction only), N s/m
  double sn;       ///< tangent normal stiffness S_n = dF_n/dδ, N/m
};

/// Evaluates the contact law.
/// @param n        unit normal from i towards j (for walls: from the particle to the wall)
/// @param delta    overlap > 0, m (0 gives zero force and leaves a finite spring)
/// @param r_eff    effective radius R (eq. 2.8), m
/// @param m_eff    effective mass m* (eq. 2.11), kg
/// @param vrel     velocity of i relative to j at the contact point, m/s
/// @param wrel     angular velocity of i relative to j (rolling resistance), rad/s
/// @param shear    tangential spring (history), updated in place; untouched when frictionless
/// @param roll_hist rolling-resistance torque on i (history), N m, updated in place when
///                 Friction and Rolling; untouched otherwise
/// The body has no data-dependent branches (only selects), so that the CPU pair loop can
/// run it in SIMD lanes; Rolling = false leaves the rolling torque out at compile time (for
/// tables where no pair has μ_r > 0), Rolling = true evaluates the rolling spring for every
/// pair (exactly zero torque where μ_r = 0).
template <bool Friction, bool Rolling = true>
DEMFEM_HD ContactResult hertz_mindlin(const PairConstants& c, Vec3 n, double delta, double r_eff,
                                      double m_eff, Vec3 vrel, Vec3 wrel, Vec3& shear,
                                      Vec3& roll_hist, double dt) {
  ContactResult out{};
  const double sqrt_rd = std::sqrt(r_eff * delta);
  const double kn = (4.0 / 3.0) * c.e_star * sqrt_rd;
  const double sn = 2.0 * c.e_star * sqrt_rd;
  const double damp = -2.0 * 0.91287092917527685576 * c.beta;  // 2 sqrt(5/6) |β|
  const double vn = dot(vrel, n);  // > 0: approaching (i moves towards j)
  // Force on i along n: elastic repulsion pushes i away from j (-n), damping opposes vn.
  // Every operand below is evaluated unconditionally and then selected: the compiler may
  // not speculate a division or square root that sits inside a condition (it could raise
  // an FP flag), and a branch would keep the CPU pair loop from vectorising.
  const double gamma_any = damp * std::sqrt(sn * m_eff);
  const double gamma_n = damp == 0.0 ? 0.0 : gamma_any;
  const double fn = kn * delta + gamma_n * vn;  // magnitude pushing i along -n
  out.fn = fn;
  out.gamma_n = gamma_n;
  out.sn = sn;
  out.force = (-fn) * n;
  out.torque = Vec3{0, 0, 0};
  out.roll = Vec3{0, 0, 0};
  if constexpr (Friction) {
    const Vec3 vt = vrel - vn * n;
    Vec3 s = rotate_into_tangent_plane(shear, n);
    s = s + dt * vt;
    const double st = 8.0 * c.g_star * sqrt_rd;
    const double gamma_t = gamma_n * c.t_over_n;
    out.gamma_t = gamma_t;
    Vec3 ft = (-st) * s - gamma_t * vt;
    const double ft2 = norm2(ft);
    const double fmax = c.friction * (fn > 0.0 ? fn : -fn);
    // Sliding: scale to the Coulomb limit and make the spring consistent with it. Without
    // sliding the scale is exactly 1 and the spring is kept (selects, no branch).
    // fmax/|F_t| and 1/S_t from one division (only used when sliding, so |F_t| > 0, S_t > 0)
    const bool slide = ft2 > fmax * fmax;
    const double ft_norm = std::sqrt(ft2);
    const double inv_fs = 1.0 / (ft_norm * st);
    const double scale_any = fmax * st * inv_fs;
    const double scale = slide ? scale_any : 1.0;
    ft = scale * ft;
    const Vec3 s_slide = (-(ft_norm * inv_fs)) * (ft + gamma_t * vt);
    s = Vec3{slide ? s_slide.x : s.x, slide ? s_slide.y : s.y, slide ? s_slide.z : s.z};
    shear = s;
    out.force = out.force + ft;
    out.torque = cross(n, ft);
    if constexpr (Rolling) {
      // Elastic-plastic spring (epsd2, see the file comment), branch-free like the spring
      // above. With μ_r = 0 both k_r and the limit are 0 and the torque stays exactly 0.
      // The dashpot of the full EPSD model is left out: it needs a further material
      // parameter (the damping ratio η_r), and the rolling mode is damped through its
      // coupling to the tangential dashpot (measured: a sphere at rest on an incline settles
      // within 0.05 s, tests/dem/core/test_contact_law.cpp).
      const Vec3 wr = wrel - dot(wrel, n) * n;            // rolling part only (no twist)
      Vec3 mr = rotate_into_tangent_plane(roll_hist, n);  // as the tangential spring
      // k_r = 2.25 k_n μ_r² R² (Ai et al. 2011) with k_n taken as the tangent stiffness
      // S_n = dF_n/dδ of the Hertz contact, the stiffness a small rolling rocks the contact
      // with. (LIGGGHTS' epsd takes its secant k_n = 4/3 E* sqrt(Rδ), its epsd2 k_t R².)
      // With this k_r the torque saturates after the rolling angle
      // μ_r R F_n / k_r = 2δ / (6.75 μ_r R) (F_n = 2/3 S_n δ), whatever the stiffness.
      const double kr = 2.25 * c.rolling * c.rolling * r_eff * r_eff * sn;
      mr = mr - (kr * dt) * wr;
      const double mmax = c.rolling * r_eff * (fn > 0.0 ? fn : 0.0);
      const double mr2 = norm2(mr);
      const bool full = mr2 > mmax * mmax;  // rolling beyond the elastic limit: plastic
      const double rscale_any = mmax / std::sqrt(mr2);
      mr = (full ? rscale_any : 1.0) * mr;
      roll_hist = mr;
      out.roll = mr;
    }
  }
  return out;
}

/// The depth of a contact against its own scale: the overlap over the smaller contact radius
/// of the two bodies (a sphere's radius, a polyhedron's dilation; a wall: the particle's).
/// A run's stability guard compares it with dem.guard_overlap (kMaxStableOverlap): a contact
/// is judged by its own bodies, not by the smallest particle in the bed.
DEMFEM_HD double relative_overlap(double delta, double ri, double rj) {
  return delta / (ri < rj ? ri : rj);
}

/// Rayleigh time step (thesis eq. 2.27) of a sphere of radius r, density rho, shear modulus
/// G, Poisson ratio nu.
DEMFEM_HD double rayleigh_time_step(double r, double rho, double shear_modulus, double nu) {
  const double pi = 3.14159265358979323846;
  return pi * r / (0.1631 * nu + 0.8766) * std::sqrt(rho / shear_modulus);
}

}  // namespace demfem::dem::phys
