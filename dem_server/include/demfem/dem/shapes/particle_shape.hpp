#pragma once
// A particle shape ready for the DEM: the convex core in the dilated body's principal frame
// (the dilated body's centroid at the origin), the dilation radius, and the properties the
// dynamics and the broad phase need.
//
// Sizes (of the dilated particle, m):
//   sieve size: the side of the smallest square aperture the particle passes through
//     (sieve_size.hpp): the core's plus 2 r_d.
//   volume-equivalent diameter: (6 V / pi)^(1/3), V the dilated volume (Steiner).
// Shape ratios: L >= I >= S are the particle's extents along its principal axes of inertia
// (the edges of the principal-axes bounding box); elongation = I / L, flatness = S / I
// (Zingg's ratios, as in aggregate shape practice; 1 = equant).
//
// Scaling to a size: r_d = f * size (the thesis: f = 0.1 of the "characteristic length") and
// the core is shrunk by lambda so that core + dilation has the requested size:
//   sieve:  lambda * sieve(K) + 2 f size = size        -> lambda = (1 - 2 f) size / sieve(K)
//   volume: lambda^3 V + lambda^2 A r + lambda M r^2 + 4/3 pi r^3 = pi size^3 / 6 (Steiner;
//           one positive root, found by safeguarded Newton to round-off).
// Both need f < 1/2: at f = 1/2 the dilation sphere alone has the requested size and the core
// vanishes. The point core is the sphere of diameter `size` whatever f (r_d = size / 2).

#include <string>
#include <string_view>

#include "demfem/dem/shapes/convex_polyhedron.hpp"
#include "demfem/dem/shapes/sieve_size.hpp"

namespace demfem::dem::shapes {

/// What a particle's size means: its sieve size (the smallest square aperture it passes), the
/// diameter of the sphere of its volume, or its bounding diameter (twice the largest distance
/// of the dilated body's surface from its centroid: a template scaled to a length, as DEM
/// codes that scale one shape by a "characteristic length" do).
enum class SizeKind { sieve, volume_equivalent, bounding };

/// "sieve", "volume_equivalent" or "bounding".
std::string_view to_string(SizeKind kind);

/// @brief A dilated convex polyhedron in its own principal frame.
struct ParticleShape {
  /// The core; body frame = the dilated body's principal axes, its centroid at the origin.
  ConvexPolyhedron core;
  double dilation_radius = 0.0;  ///< r_d, m
  double volume = 0.0;           ///< of the dilated body, m^3 (mass = rho volume)
  /// Principal moments of the dilated body per unit density (m^5; times rho: kg m^2),
  /// ascending, about the body x, y, z axes.
  Vec3 principal_moments{};
  /// Largest vertex distance from the origin + r_d (m): the broad phase's bounding sphere.
  double bounding_radius = 0.0;
  double sieve_size = 0.0;                  ///< m
  double volume_equivalent_diameter = 0.0;  ///< m
  Vec3 extents{};                           ///< widths of the dilated body along x, y, z, m
  double elongation = 1.0;                  ///< I / L
  double flatness = 1.0;                    ///< S / I

  double size(SizeKind kind) const {
    switch (kind) {
      case SizeKind::sieve:
        return sieve_size;
      case SizeKind::volume_equivalent:
        return volume_equivalent_diameter;
      case SizeKind::bounding:
        return 2.0 * bounding_radius;
    }
    return sieve_size;
  }
};

/// The dilated body core + r_d as given (no scaling), moved into its principal frame.
/// r_d >= 0 (> 0 for the point core).
ParticleShape describe_dilated(const ConvexPolyhedron& core, double dilation_radius);

/// The core scaled so that the dilated particle, with r_d = dilation_fraction * size, has the
/// requested size. Throws ShapeError naming `source` for size <= 0, dilation_fraction <= 0,
/// r_d >= size (fraction >= 1), or r_d >= size / 2 (the core would vanish). `sieve` sets the
/// sieve-size search (its progress hook for large cores).
ParticleShape make_particle_shape(const ConvexPolyhedron& core, double size, SizeKind kind,
                                  double dilation_fraction, std::string_view source,
                                  const SieveSearch& sieve = {});

/// The similar shape with every length times `factor` (> 0): exact (volume factor^3,
/// moments factor^5).
ParticleShape scale(const ParticleShape& shape, double factor);

}  // namespace demfem::dem::shapes
