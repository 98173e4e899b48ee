#pragma once
// Particle size distributions (constant, uniform, truncated normal, sieve gradation), drawn
// from the portable random stream of rng.hpp: the same seed gives the same sizes with any
// compiler.

#include <string>
#include <vector>

#include "demfem/dem/shapes/geometry/rng.hpp"

namespace demfem::dem {

/// @brief A distribution of particle diameters (m).
struct SizeDistribution {
  enum class Kind { constant, uniform, normal, gradation };
  Kind kind = Kind::constant;
  double d_min = 0.0;   ///< constant: the diameter; uniform/normal: lower bound
  double d_max = 0.0;   ///< uniform/normal: upper bound
  double mean = 0.0;    ///< normal: mean of the untruncated normal
  double stddev = 0.0;  ///< normal: standard deviation of the untruncated normal
  /// gradation: sieve sizes d_0 < d_1 < ... < d_k (m) and the mass fraction of each of the k
  /// classes [d_i, d_{i+1}) (sum 1 within 1e-9). Within a class diameters are uniform by
  /// number. For polyhedra "diameter" is the particle size (shapes::SizeKind): see
  /// shapes/shape_library.hpp.
  std::vector<double> sieves;
  std::vector<double> mass_fractions;

  static SizeDistribution constant(double d);
  static SizeDistribution uniform(double d_min, double d_max);
  static SizeDistribution normal(double mean, double stddev, double d_min, double d_max);
  static SizeDistribution gradation(std::vector<double> sieves, std::vector<double> mass_fractions);

  /// Throws std::invalid_argument with the reason when the parameters are inconsistent
  /// (d_min > d_max, non-positive sizes, fractions not summing to 1, a normal with almost no
  /// probability inside its bounds, ...).
  void validate() const;
  /// One diameter, in [smallest(), largest()].
  double sample(Rng& rng) const;
  double smallest() const;
  double largest() const;
  /// Expected d^3 of one sampled particle, m^3 (by numerical integration for the normal).
  double mean_cube() const;
  std::string describe() const;
};

}  // namespace demfem::dem
