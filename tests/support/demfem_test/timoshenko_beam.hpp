#pragma once
// Natural bending frequencies of a uniform beam clamped at both ends, by Timoshenko beam
// theory (shear deformation and rotary inertia) and by Euler-Bernoulli theory: the
// independent references of the modal analysis tests and of bench/modal_convergence.
//
// Timoshenko: EI psi'' + kGA (w' - psi) + rho I w^2 psi = 0, kGA (w'' - psi') + rho A w^2 w = 0,
// w = psi = 0 at x = 0 and x = L. Below the cut-off frequency sqrt(kGA / (rho I)) the general
// solution is w = C1 cosh(a x) + C2 sinh(a x) + C3 cos(b x) + C4 sin(b x), with a^2 and -b^2
// the roots of EI kGA s^2 + w^2 (kGA rho I + rho A EI) s + rho A w^2 (rho I w^2 - kGA) = 0,
// and psi follows from the second equation. The four end conditions give a 4 x 4 homogeneous
// system whose determinant vanishes at the natural frequencies: the clamped-clamped frequency
// equation of S. M. Han, H. Benaroya, T. Wei, "Dynamics of transversely vibrating beams using
// four engineering theories", J. Sound Vib. 225(5) (1999) 935-988 (their section on the
// Timoshenko model, clamped-clamped end conditions), solved here numerically (sign changes on
// a fine frequency grid, then bisection).

#include <cmath>
#include <stdexcept>
#include <vector>

#include <Eigen/Dense>

namespace demfem::test {

struct BeamSection {
  double length = 1.0;                   ///< L, m
  double youngs_modulus = 0.0;           ///< E, Pa
  double poisson_ratio = 0.0;            ///< nu
  double density = 0.0;                  ///< rho, kg/m^3
  double area = 0.0;                     ///< A, m^2
  double second_moment = 0.0;            ///< I about the bending axis, m^4
  double shear_coefficient = 5.0 / 6.0;  ///< k (5/6 for a rectangle; Cowper: 10(1+nu)/(12+11nu))
};

/// Cowper's (1966) shear coefficient of a rectangular section.
inline double cowper_rectangle(double nu) {
  return 10.0 * (1.0 + nu) / (12.0 + 11.0 * nu);
}

/// Euler-Bernoulli clamped-clamped: omega_n = (beta_n L)^2 sqrt(EI / (rho A L^4)), beta_n L
/// the roots of cos(x) cosh(x) = 1 (found by bisection). rad/s.
inline std::vector<double> euler_bernoulli_clamped(const BeamSection& s, int count) {
  std::vector<double> out;
  auto f = [](double x) { return std::cos(x) * std::cosh(x) - 1.0; };
  for (int n = 1; static_cast<int>(out.size()) < count; ++n) {
    // The n-th root lies in ((n + 0.5) pi - 0.1, (n + 0.5) pi + 0.1) for n >= 1.
    double lo = (n + 0.5) * M_PI - 0.2, hi = (n + 0.5) * M_PI + 0.2;
    for (int it = 0; it < 200; ++it) {
      const double mid = 0.5 * (lo + hi);
      (f(lo) * f(mid) <= 0.0 ? hi : lo) = mid;
    }
    const double bl = 0.5 * (lo + hi);
    out.push_back(bl * bl *
                  std::sqrt(s.youngs_modulus * s.second_moment /
                            (s.density * s.area * std::pow(s.length, 4))));
  }
  return out;
}

/// Determinant of the clamped-clamped end conditions at frequency w (rad/s), Timoshenko.
inline double timoshenko_clamped_determinant(const BeamSection& s, double w) {
  const double g = s.youngs_modulus / (2.0 * (1.0 + s.poisson_ratio));
  const double kga = s.shear_coefficient * g * s.area, ei = s.youngs_modulus * s.second_moment;
  const double ra = s.density * s.area, ri = s.density * s.second_moment;
  const double c2 = ei * kga, c1 = w * w * (kga * ri + ra * ei),
               c0 = ra * w * w * (ri * w * w - kga);
  const double disc = std::sqrt(c1 * c1 - 4.0 * c2 * c0);
  const double a = std::sqrt((-c1 + disc) / (2.0 * c2));  // a^2 > 0 below the cut-off
  const double b = std::sqrt((c1 + disc) / (2.0 * c2));   // -b^2 < 0
  const double q = ra * w * w / kga;
  const double p = (a * a + q) / a, r = (q - b * b) / b;  // psi amplitudes (see above)
  const double l = s.length;
  // Hyperbolic columns scaled by 1 / cosh(aL) (the determinant's sign is unchanged).
  const double ch = 1.0, sh = std::tanh(a * l), e = 1.0 / std::cosh(a * l);
  Eigen::Matrix4d m;
  m << e, 0, 1, 0,                                                // w(0) = 0
      0, p * e, 0, -r,                                            // psi(0) = 0
      ch, sh, std::cos(b * l), std::sin(b * l),                   // w(L) = 0
      p * sh, p * ch, r * std::sin(b * l), -r * std::cos(b * l);  // psi(L) = 0
  return m.determinant();
}

/// The first `count` Timoshenko bending frequencies (rad/s) of the clamped-clamped beam.
inline std::vector<double> timoshenko_clamped(const BeamSection& s, int count) {
  const double g = s.youngs_modulus / (2.0 * (1.0 + s.poisson_ratio));
  const double cutoff = std::sqrt(s.shear_coefficient * g * s.area / (s.density * s.second_moment));
  std::vector<double> out;
  // A grid fine against the first frequency (Euler-Bernoulli bounds it from above) and the
  // spacing of the modes.
  const double dw = std::min(1e-4 * cutoff, 5e-3 * euler_bernoulli_clamped(s, 1)[0]);
  double w0 = dw, d0 = timoshenko_clamped_determinant(s, w0);
  for (double w1 = 2 * dw; w1 < 0.999 * cutoff && static_cast<int>(out.size()) < count; w1 += dw) {
    const double d1 = timoshenko_clamped_determinant(s, w1);
    if (d0 * d1 < 0.0) {
      double lo = w0, hi = w1, dlo = d0;
      for (int it = 0; it < 100; ++it) {
        const double mid = 0.5 * (lo + hi), dm = timoshenko_clamped_determinant(s, mid);
        if (dlo * dm <= 0.0) {
          hi = mid;
        } else {
          lo = mid;
          dlo = dm;
        }
      }
      out.push_back(0.5 * (lo + hi));
    }
    w0 = w1;
    d0 = d1;
  }
  if (static_cast<int>(out.size()) < count)
    throw std::runtime_error("timoshenko_clamped: fewer modes below the shear cut-off");
  return out;
}

}  // namespace demfem::test
