#pragma once
// A library of K distinct unit particle shapes (size 1 m, r_d = f x 1 m), scaled per particle.
//
// Building a shape (hull, mass properties, sieve size) costs milliseconds; a ballast bed has
// 10^5 particles. As in EDEM and Chrono, a bed uses K shapes (100-1000) and each particle
// stores a shape index and a scale s (= its size in m). Scaling is exact because r_d is a
// fixed fraction of the size, so the whole dilated body scales: lengths (core vertices, r_d,
// bounding radius, sizes) times s, volume times s^3, principal moments times s^5; the
// principal frame and the centroid (the origin) do not change.
//
// Sampling a population: a shape index uniform in [0, K) and a size from a
// SizeDistribution, drawn independently. Then a particle's mass is rho V_k s^3 with V_k and
// s independent, so a gradation's mass fractions, which SizeDistribution reproduces for
// d^3-weighted masses, hold for the rocks too (the factor E[V_k] cancels).

#include <cstdint>
#include <span>
#include <vector>

#include "demfem/dem/shapes/geometry/size_distribution.hpp"
#include "demfem/dem/shapes/particle_shape.hpp"
#include "demfem/dem/shapes/random_rock.hpp"

namespace demfem::dem::shapes {

/// @brief One particle's shape: library index and scale, with the scaled properties.
struct ScaledShape {
  std::uint32_t shape = 0;       ///< index into the library
  double scale = 1.0;            ///< = the particle's size, m (the unit shape has size 1 m)
  double dilation_radius = 0.0;  ///< m
  double volume = 0.0;           ///< m^3
  Vec3 principal_moments{};      ///< per unit density, m^5, about the body axes
  double bounding_radius = 0.0;  ///< m
};

class ShapeLibrary {
 public:
  /// Unit shapes from given cores (STL hulls, simple solids), each scaled to size 1 m of
  /// `kind` with r_d = dilation_fraction. Throws ShapeError (see make_particle_shape).
  /// `sieve`: the sieve-size search of every core (its progress hook for large cores).
  ShapeLibrary(std::span<const ConvexPolyhedron> cores, SizeKind kind, double dilation_fraction,
               const SieveSearch& sieve = {});

  /// `count` random rocks; rock k uses the seed derived from (seed, k) by SplitMix64, so the
  /// first k shapes do not depend on `count`. Built in parallel (OpenMP), deterministic.
  static ShapeLibrary random_rocks(const RockParams& params, std::size_t count, std::uint64_t seed,
                                   SizeKind kind, double dilation_fraction);

  std::size_t size() const { return shapes_.size(); }
  SizeKind size_kind() const { return kind_; }
  double dilation_fraction() const { return fraction_; }
  /// Shape k at size 1 m.
  const ParticleShape& unit(std::size_t k) const { return shapes_[k]; }
  /// Shape k at size `size` (m), exact; cheap (no geometry).
  ScaledShape scaled(std::size_t k, double size) const;
  /// Shape k at size `size` with its core (a copy of the vertices times size).
  ParticleShape particle(std::size_t k, double size) const { return scale(shapes_[k], size); }
  /// A uniform index in [0, size()).
  std::uint32_t pick(Rng& rng) const;
  /// pick(rng), then dist.sample(rng), scaled.
  ScaledShape sample(Rng& rng, const SizeDistribution& dist) const;

 private:
  ShapeLibrary() = default;
  std::vector<ParticleShape> shapes_;
  SizeKind kind_ = SizeKind::sieve;
  double fraction_ = 0.1;
};

/// SplitMix64 of (seed + k * golden gamma): independent seeds for a family of generators.
std::uint64_t derived_seed(std::uint64_t seed, std::uint64_t k);

}  // namespace demfem::dem::shapes
