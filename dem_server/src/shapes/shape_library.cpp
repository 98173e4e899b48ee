#include "demfem/dem/shapes/shape_library.hpp"

#include <algorithm>
#include <cmath>
#include <exception>
#include <string>

#include "shape_util.hpp"

namespace demfem::dem::shapes {

std::uint64_t derived_seed(std::uint64_t seed, std::uint64_t k) {
  std::uint64_t z = seed + (k + 1) * 0x9e3779b97f4a7c15ull;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}

ShapeLibrary::ShapeLibrary(std::span<const ConvexPolyhedron> cores, SizeKind kind,
                           double dilation_fraction, const SieveSearch& sieve)
    : kind_(kind), fraction_(dilation_fraction) {
  if (cores.empty()) throw ShapeError("shape library: no shapes given");
  shapes_.reserve(cores.size());
  for (std::size_t k = 0; k < cores.size(); ++k) {
    shapes_.push_back(make_particle_shape(cores[k], 1.0, kind, dilation_fraction,
                                          "shape library entry " + std::to_string(k), sieve));
  }
}

ShapeLibrary ShapeLibrary::random_rocks(const RockParams& params, std::size_t count,
                                        std::uint64_t seed, SizeKind kind,
                                        double dilation_fraction) {
  validate(params);
  if (count == 0) throw ShapeError("shape library: the number of random rocks must be >= 1");
  ShapeLibrary lib;
  lib.kind_ = kind;
  lib.fraction_ = dilation_fraction;
  // Each rock depends on its own seed only, so the parallel build is deterministic.
  std::vector<ParticleShape> shapes(count);
  std::exception_ptr error;
  const auto n = static_cast<std::int64_t>(count);
#pragma omp parallel for schedule(dynamic, 4)
  for (std::int64_t k = 0; k < n; ++k) {
    try {
      const ConvexPolyhedron core = random_rock(params, derived_seed(seed, std::uint64_t(k)));
      shapes[std::size_t(k)] = make_particle_shape(core, 1.0, kind, dilation_fraction,
                                                   "random rock " + std::to_string(k));
    } catch (...) {
#pragma omp critical(demfem_shape_library_error)
      if (!error) error = std::current_exception();
    }
  }
  if (error) std::rethrow_exception(error);
  lib.shapes_ = std::move(shapes);
  return lib;
}

ScaledShape ShapeLibrary::scaled(std::size_t k, double size) const {
  if (k >= shapes_.size()) {
    throw ShapeError("shape library: shape " + std::to_string(k) + " of " +
                     std::to_string(shapes_.size()));
  }
  if (!(size > 0) || !std::isfinite(size)) {
    throw ShapeError("shape library: particle size " + detail::format_number(size) +
                     " m must be > 0");
  }
  const ParticleShape& u = shapes_[k];
  const double s2 = size * size;
  ScaledShape out;
  out.shape = static_cast<std::uint32_t>(k);
  out.scale = size;
  out.dilation_radius = u.dilation_radius * size;
  out.volume = u.volume * s2 * size;
  for (std::size_t i = 0; i < 3; ++i)
    out.principal_moments[i] = u.principal_moments[i] * s2 * s2 * size;
  out.bounding_radius = u.bounding_radius * size;
  return out;
}

std::uint32_t ShapeLibrary::pick(Rng& rng) const {
  const auto k = static_cast<std::uint32_t>(rng.uniform() * double(shapes_.size()));
  return std::min<std::uint32_t>(k, static_cast<std::uint32_t>(shapes_.size() - 1));
}

ScaledShape ShapeLibrary::sample(Rng& rng, const SizeDistribution& dist) const {
  const std::uint32_t k = pick(rng);
  return scaled(k, dist.sample(rng));
}

}  // namespace demfem::dem::shapes
