#pragma once
// Packed fill: particles drawn as a random insertion draws them (shape, size, then a random
// orientation), placed densely by their bounding spheres in a box, so that a bed starts about
// as tall as it settles instead of tens of times taller ([[dem.pack]], the benches' beds).

#include <array>
#include <cstdint>
#include <vector>

#include "demfem/dem/placement/insertion.hpp"

namespace demfem::dem {

/// @brief A packed fill request. The particles' bounding spheres lie wholly inside `region`
/// and do not overlap; the region's x and y extents are filled edge to edge (so that a
/// periodic block whose period is that extent can be filled without overlap across the seam).
struct PackedFill {
  /// How the bounding spheres are arranged. `rows`: sorted largest first, placed along x in
  /// rows, rows along y in a layer, layers along z; a row is as deep as its largest sphere and
  /// a layer as tall as its largest (the benches' make_bed, whose bits this method keeps); the
  /// bed starts graded, the largest at the bottom. `mixed`: the same rows and layers in the
  /// order drawn, so that each depth holds the whole distribution, as a poured bed does (rows
  /// sized for their largest: a lower bounding-sphere fraction). `layers`: the order drawn,
  /// sorted largest first within each run of about one layer's worth (the region's x-y area
  /// over the mean step squared): rows of like sizes, graded within a layer, not the bed.
  enum class Method { rows, mixed, layers };
  Box region;
  SizeDistribution sizes;
  std::int64_t count = 0;     ///< particles, > 0
  double gap_factor = 1.001;  ///< centre step = gap_factor x bounding diameter, >= 1
  std::uint64_t seed = 1;     ///< Rng seed of the shapes, sizes and orientations
  std::int32_t material = 0;
  std::array<double, 3> velocity{};
  Method method = Method::rows;
  /// Dilated polyhedra instead of spheres: shape and size from library->sample(rng, sizes),
  /// as insert_random draws them; engine shape id shape_base + index.
  const shapes::ShapeLibrary* library = nullptr;
  std::int32_t shape_base = 0;
};

/// @brief What a packed fill placed.
struct PackedBed {
  std::vector<ParticleInit> particles;  ///< lowest layer first
  double height = 0.0;  ///< m: the top of the last layer above region.lo z (step sizes included)
  /// Sum of the bounding-sphere volumes over the box region.lo .. (hi x, hi y, lo z + height).
  double bounding_fraction = 0.0;
};

/// @brief Draws `count` particles from Rng(seed) (all shapes and sizes first, in order; then
/// the orientations in placement order) and packs them by `method`. Deterministic: the same
/// request gives the same bits. Throws InsertionError when the count is not > 0, when a
/// particle's bounding diameter exceeds the region's x or y extent, or when the layers do
/// not fit below region.hi z (the message names the height needed and the count that fits).
PackedBed packed_fill(const PackedFill& request);

}  // namespace demfem::dem
