#include "demfem/dem/shapes/particle_shape.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "demfem/dem/shapes/mass_properties.hpp"
#include "demfem/dem/shapes/sieve_size.hpp"
#include "shape_util.hpp"

namespace demfem::dem::shapes {

using detail::format_number;

namespace {

constexpr double kPi = std::numbers::pi;

Mat3 transpose(const Mat3& m) {
  Mat3 t{};
  for (std::size_t i = 0; i < 3; ++i)
    for (std::size_t j = 0; j < 3; ++j) t[i][j] = m[j][i];
  return t;
}

/// describe_dilated with the core's sieve size known (it is invariant under rigid motions).
ParticleShape describe(const ConvexPolyhedron& core, double r, double core_sieve) {
  const MassProperties mp = dilated_mass_properties(core, r);
  const PrincipalFrame frame = principal_frame(mp.inertia);
  const Mat3 rt = transpose(frame.axes);  // input frame -> principal frame
  Vec3 shift{};
  for (std::size_t i = 0; i < 3; ++i) shift[i] = -dot(rt[i], mp.centroid);
  ParticleShape s;
  s.core = core.transformed(rt, shift);
  s.dilation_radius = r;
  s.volume = mp.volume;
  s.principal_moments = frame.moments;
  s.bounding_radius = s.core.radius_about({0, 0, 0}) + r;
  s.sieve_size = core_sieve + 2.0 * r;
  s.volume_equivalent_diameter = std::cbrt(6.0 * mp.volume / kPi);
  for (std::size_t k = 0; k < 3; ++k) {
    Vec3 e{0, 0, 0};
    e[k] = 1.0;
    s.extents[k] = s.core.width(e) + 2.0 * r;
  }
  Vec3 sorted = s.extents;
  std::sort(sorted.begin(), sorted.end(), std::greater<>());
  s.elongation = sorted[1] / sorted[0];
  s.flatness = sorted[2] / sorted[1];
  return s;
}

/// The positive root of lambda^3 V + lambda^2 A r + lambda M r^2 = target (> 0), increasing
/// in lambda: Newton from an upper bound (the cubic term alone), which then decreases
/// monotonically (the function is convex for lambda > 0), guarded by bisection.
double solve_steiner(const SteinerCoefficients& s, double r, double target) {
  auto f = [&](double l) {
    return l * (l * (l * s.volume + s.area * r) + s.edge_term * r * r) - target;
  };
  auto df = [&](double l) {
    return 3 * l * l * s.volume + 2 * l * s.area * r + s.edge_term * r * r;
  };
  double lo = 0.0, hi = std::cbrt(target / s.volume);
  double l = hi;
  for (int it = 0; it < 200; ++it) {
    const double fl = f(l);
    if (fl > 0) {
      hi = l;
    } else {
      lo = l;
    }
    double next = l - fl / df(l);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    if (std::abs(next - l) <= 1e-15 * l) return next;
    l = next;
  }
  return l;
}

/// The core's scale lambda at which core * lambda dilated by r has the bounding diameter `size`
/// (> 2 r): the bounding radius about the dilated body's centroid grows with lambda from r
/// (lambda = 0), so bisection between 0 and a doubled upper bound finds it to rounding.
double bounding_scale(const ConvexPolyhedron& core, double r, double size) {
  auto diameter = [&](double l) {
    const ConvexPolyhedron c = core.scaled(l);
    return 2.0 * (c.radius_about(dilated_mass_properties(c, r).centroid) + r);
  };
  double lo = 0.0, hi = 1.0;
  for (int k = 0; k < 200 && diameter(hi) < size; ++k) hi *= 2.0;
  for (int it = 0; it < 200 && hi - lo > 1e-15 * hi; ++it) {
    const double mid = 0.5 * (lo + hi);
    (diameter(mid) < size ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

}  // namespace

std::string_view to_string(SizeKind kind) {
  switch (kind) {
    case SizeKind::sieve:
      return "sieve";
    case SizeKind::volume_equivalent:
      return "volume_equivalent";
    case SizeKind::bounding:
      return "bounding";
  }
  return "sieve";
}

ParticleShape describe_dilated(const ConvexPolyhedron& core, double dilation_radius) {
  if (!(dilation_radius >= 0) || !std::isfinite(dilation_radius)) {
    throw ShapeError("dilation radius " + format_number(dilation_radius) +
                     " m must be finite and >= 0");
  }
  if (core.is_point() && !(dilation_radius > 0)) {
    throw ShapeError("a point core needs a dilation radius > 0 (it is then a sphere)");
  }
  return describe(core, dilation_radius, sieve_size(core).size);
}

ParticleShape make_particle_shape(const ConvexPolyhedron& core, double size, SizeKind kind,
                                  double dilation_fraction, std::string_view source,
                                  const SieveSearch& sieve) {
  const std::string src(source);
  if (!(size > 0) || !std::isfinite(size)) {
    throw ShapeError(src + ": particle size " + format_number(size) + " m must be > 0");
  }
  if (core.is_point()) return describe(core, 0.5 * size, 0.0);
  const double f = dilation_fraction;
  if (!(f > 0) || !std::isfinite(f)) {
    throw ShapeError(src + ": dilation radius fraction " + format_number(f) +
                     " must be > 0 (r_d = 0 leaves the contact law without a radius)");
  }
  const double r = f * size;
  if (f >= 1.0) {
    throw ShapeError(src + ": dilation radius r_d = " + format_number(f) +
                     " x size = " + format_number(r) + " m is not smaller than the size " +
                     format_number(size) + " m; the fraction must be < 0.5");
  }
  if (f >= 0.5) {
    throw ShapeError(src + ": dilation radius r_d = " + format_number(f) +
                     " x size = " + format_number(r) + " m: the dilation sphere alone (diameter " +
                     format_number(2 * r) + " m) is at least the size " + format_number(size) +
                     " m, so the core would vanish; the fraction must be < 0.5");
  }
  const double core_sieve = sieve_size(core, sieve).size;
  double lambda = 0.0;
  if (kind == SizeKind::sieve) {
    lambda = (1.0 - 2.0 * f) * size / core_sieve;
  } else if (kind == SizeKind::bounding) {
    lambda = bounding_scale(core, r, size);
  } else {
    const double target = kPi * size * size * size / 6.0 - 4.0 / 3.0 * kPi * r * r * r;
    lambda = solve_steiner(steiner_coefficients(core), r, target);
  }
  return describe(core.scaled(lambda), r, lambda * core_sieve);
}

ParticleShape scale(const ParticleShape& shape, double factor) {
  if (!(factor > 0) || !std::isfinite(factor)) {
    throw ShapeError("particle shape scale factor " + format_number(factor) + " must be > 0");
  }
  ParticleShape s = shape;
  s.core = shape.core.is_point() ? shape.core : shape.core.scaled(factor);
  const double f2 = factor * factor;
  s.dilation_radius *= factor;
  s.volume *= f2 * factor;
  for (double& m : s.principal_moments) m *= f2 * f2 * factor;
  s.bounding_radius *= factor;
  s.sieve_size *= factor;
  s.volume_equivalent_diameter *= factor;
  for (double& e : s.extents) e *= factor;
  return s;
}

}  // namespace demfem::dem::shapes
