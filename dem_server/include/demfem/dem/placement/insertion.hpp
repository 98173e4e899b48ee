#pragma once
// Filling a scene with particles: random non-overlapping insertion in a box up to a count or
// a mass, lattice fill, and removal of particles above a height.

#include <array>
#include <cstdint>
#include <functional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "demfem/dem/dem_system.hpp"
#include "demfem/dem/shapes/geometry/size_distribution.hpp"

namespace demfem::dem::shapes {
class ShapeLibrary;
struct ParticleShape;
}  // namespace demfem::dem::shapes

namespace demfem::dem {

/// @brief An axis-aligned box, m.
struct Box {
  std::array<double, 3> lo{};
  std::array<double, 3> hi{};
  double volume() const { return (hi[0] - lo[0]) * (hi[1] - lo[1]) * (hi[2] - lo[2]); }
  std::string describe() const;
};

/// @brief An insertion that cannot be done; what() says what was asked and what was achieved.
class InsertionError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// @brief Random insertion request: exactly one of count and mass is > 0.
struct RandomInsertion {
  Box region;  ///< particles lie wholly inside it
  SizeDistribution sizes;
  std::int64_t count = 0;  ///< number of particles, or 0
  double mass = 0.0;       ///< kg: insert until the total reaches it, or 0
  double density = 0.0;    ///< kg/m^3 of the particle material
  std::int32_t material = 0;
  std::array<double, 3> velocity{};
  std::uint64_t seed = 1;
  std::int64_t max_attempts = 2000;  ///< random positions tried per particle before giving up
  /// A particle that finds no free place ends the insertion with the particles placed so far
  /// (reported through insert_random's `shortfall`) instead of throwing: a band filled near
  /// its capacity, where a few seeds cannot place the last rocks (scene key shortfall = "warn").
  bool accept_shortfall = false;
  /// Dilated polyhedra instead of spheres: each particle takes a shape of the library
  /// (uniform index) at the size drawn from `sizes` (the library's size definition), a
  /// uniformly random orientation, and the engine shape id shape_base + index (the order in
  /// which add_library_shapes() added them). Bounding spheres do not overlap; `mass` counts
  /// the particles' real masses.
  const shapes::ShapeLibrary* library = nullptr;
  std::int32_t shape_base = 0;
  /// The scene's periods (DemSettings::periodic), m: 0 where a direction is not periodic. In
  /// a periodic direction a particle must not overlap the images of the others either (one
  /// period away across the seam), and a region that spans the whole period [period_lo,
  /// period_lo + L) places centres anywhere in it (a particle may lie across the seam).
  std::array<double, 3> period{};
  std::array<double, 3> period_lo{};
};

/// @brief Solid fraction above which random sequential insertion is refused up front. Random
/// sequential addition of equal spheres jams at about 0.38; polydisperse sets reach a little
/// more, so requests above 0.40 are not attempted.
inline constexpr double kMaxRandomPackingFraction = 0.40;

/// @brief Places particles at random positions (uniform in the box, drawn from
/// Rng(seed)) so that none overlaps another new one or a particle of `existing` (may be
/// nullptr). A uniform cell grid makes each overlap test O(1). The result is ordered by grid
/// cell (z, y, x), so that neighbours in space are neighbours in memory. Deterministic for a given
/// request and existing state. Throws InsertionError when the request exceeds
/// kMaxRandomPackingFraction of the region, when the largest particle does not fit, or when a
/// particle finds no free place in max_attempts tries (the message names the request and
/// how many particles / how much mass were placed) unless `accept_shortfall`: then the particles
/// placed so far are returned and `*shortfall` (when given) gets that message.
/// `blocked(x, y, z, r)`, when given, rejects a position as an overlap does (the scene's walls:
/// a region may reach into a funnel or across a wall, the particles never do).
std::vector<ParticleInit> insert_random(
    const RandomInsertion& request, const ParticleState* existing = nullptr,
    const std::function<bool(double, double, double, double)>& blocked = {},
    std::string* shortfall = nullptr);

/// @brief Lattice fill: spheres on a simple cubic lattice of the given spacing filling the
/// box, lowest layer first; optionally with diameters drawn from a distribution and each sphere
/// displaced at random (jitter), so that a bed poured from it does not settle in columns. With
/// a shape library: dilated polyhedra, the diameter being their size, each with a shape drawn
/// uniformly and a random orientation; the bounding diameter (of the library's largest shape
/// at the size) then plays the diameter's part for the spacing, the jitter and the inset.
struct LatticeFill {
  Box region;
  double diameter = 0.0;  ///< m; with `has_sizes`, the largest diameter of `sizes`
  bool has_sizes = false;
  SizeDistribution sizes;  ///< with has_sizes: the diameter of each sphere, drawn in order
  double spacing = 0.0;    ///< centre distance, m (>= diameter); 0 = 1.001 * diameter
  /// [0, 1): each sphere is displaced along each axis by a uniform random amount of up to
  /// jitter x half its gap (spacing - its diameter) either way. Neighbours are a spacing apart
  /// along some axis, so they stay at least (d_i + d_j) / 2 apart: no overlap; the lattice is
  /// inset by the largest such displacement, so the spheres stay inside the box.
  double jitter = 0.0;
  std::uint64_t seed = 1;  ///< Rng seed of the diameters, displacements, shapes, orientations
  std::int32_t material = 0;
  std::array<double, 3> velocity{};
  std::int64_t max_count = 0;  ///< 0 = as many as fit
  const shapes::ShapeLibrary* library = nullptr;
  std::int32_t shape_base = 0;
  /// The scene's periods (DemSettings::periodic), m: 0 where a direction is not periodic. In
  /// a periodic direction a particle must not overlap the images of the others either (one
  /// period away across the seam), and a region that spans the whole period [period_lo,
  /// period_lo + L) places centres anywhere in it (a particle may lie across the seam).
  std::array<double, 3> period{};
  std::array<double, 3> period_lo{};
};

/// @brief How many spheres a lattice fill places (in double: a typo can ask for more than
/// an integer holds), without placing them.
double lattice_count(const LatticeFill& request);

/// @brief Expected number of particles of one random insertion (the count, or the mass over
/// the mean particle mass).
double expected_count(const RandomInsertion& request);

/// @brief Particles of a lattice fill; throws InsertionError when not one fits or the fill
/// asks for more than kMaxParticles.
std::vector<ParticleInit> lattice_fill(const LatticeFill& request);

/// @brief Most particles a DEM system holds: its neighbour lists index particles with 32-bit
/// integers.
inline constexpr double kMaxParticles = 2147483647.0;

/// @brief Index of the first of `added` that overlaps a particle of `existing` (by more than
/// 1e-9 of the smaller radius), or -1 (a lattice placed over another lattice).
std::int64_t first_overlapping(const std::vector<ParticleInit>& added,
                               const ParticleState& existing);

/// @brief keep[i] = 1 for the particles whose centre is at or below `height` (m); with
/// `tops` (one per particle, e.g. particle_tops()) for those whose top is.
std::vector<std::uint8_t> keep_at_or_below(const ParticleState& particles, double height,
                                           std::span<const double> tops = {});

/// @brief Removes the particles whose centre is above `height`; returns how many.
std::size_t remove_above(DemSystem& system, double height);

/// @brief Mass of a sphere of diameter d and density rho, kg.
double sphere_mass(double diameter, double density);

/// @brief The engine's description of a shape of the shape library (its core, r_d, volume
/// and principal moments at the shape's own size).
PolyhedronShape engine_shape(const shapes::ParticleShape& shape, std::string name);

/// @brief Adds the library's unit shapes to the system's shape table, in order; returns the
/// engine id of the first (RandomInsertion::shape_base).
std::int32_t add_library_shapes(DemSystem& system, const shapes::ShapeLibrary& library,
                                const std::string& name);

/// @brief A uniformly distributed random rotation (unit quaternion w, x, y, z; Shoemake's
/// method, from three uniforms of rng).
std::array<double, 4> random_orientation(Rng& rng);

}  // namespace demfem::dem
