#pragma once
// Packing of a granular bed in a control box (the `packing` sensor): solid fraction, mean
// coordination number and the height of the bed's top, as EDEM's and LIGGGHTS's bin
// measurements report them; with `contacts = true` also the contact statistics by which two
// preparations of a bed are compared (docs/cases.md, "Preparing the bed"): coordination
// without rattlers, the contact-force distribution and the vertical stress. A particle
// belongs to the box when its centre lies in it, a contact when its branch vector's midpoint
// does.

#include <array>
#include <cstdint>
#include <span>

#include "demfem/dem/dem_system.hpp"

namespace demfem::dem {

/// @brief What packing_in_box() measures.
struct PackingResult {
  std::int64_t particles = 0;   ///< particles whose centre lies in the box
  double solid_fraction = 0.0;  ///< their volume (spheres 4/3 pi r^3, polyhedra the dilated
                                ///< body's volume times scale^3) over the box's volume
  double coordination = 0.0;    ///< mean number of particle-particle contacts (pairs with a
                                ///< force in the last step) of these particles; wall contacts
                                ///< are not counted. 0 without particles
  double top = 0.0;             ///< highest point of these particles (sphere z + r; polyhedron:
                                ///< highest core vertex + dilation), m; NaN without particles
};

/// @brief Height of particle i's highest surface point, m: z + radius for a sphere; for a
/// polyhedron its highest rotated, scaled core vertex plus the dilation (exact: the dilated
/// body's top is a core vertex's sphere).
double particle_top(const DemSystem& system, std::size_t i);

/// @brief Packing of the particles whose centre lies in the box [lo, hi]. The solid fraction
/// of centre-in-box counting errs at the box faces by about a particle size over the box
/// size: choose a box of several particle sizes, away from walls. In a periodic direction a
/// centre counts at its image nearest the box's middle (a box across the seam holds both
/// sides; a contact across the seam counts, the pair list has it). Throws
/// std::invalid_argument for a box with hi <= lo in some coordinate, or longer than a period.
PackingResult packing_in_box(const DemSystem& system, const std::array<double, 3>& lo,
                             const std::array<double, 3>& hi);

/// @brief The distribution of contact forces f (N), as granular packings report it: the
/// mean <f>, the fraction above 2 <f>, and the decay rate beta of the exponential tail
/// P(f/<f>) ~ exp(-beta f/<f>) above the mean, estimated by maximum likelihood (for x =
/// f/<f> > 1, beta = 1 / mean(x - 1): the exponential's rate, unbiased for an exponential tail).
/// An exponential distribution has 2<f> fraction e^-2 = 0.135 and beta = 1; random packings
/// of frictional grains give beta about 1 to 1.5.
struct ForceDistribution {
  std::int64_t contacts = 0;  ///< forces counted
  double mean = 0.0;          ///< <f>, N; NaN without contacts
  double above_two_mean = 0;  ///< fraction of the contacts with f > 2 <f>; NaN without contacts
  double tail_decay = 0.0;    ///< beta; NaN when no f exceeds <f> (e.g. all forces equal)
};

/// @brief force_distribution of the magnitudes `forces` (N, each >= 0).
ForceDistribution force_distribution(std::span<const double> forces);

/// @brief The contact statistics of a bed in a box (packing sensor, `contacts = true`).
struct ContactStatistics {
  /// Particles whose centre lies in the box with fewer than 2 particle-particle contacts
  /// (wall contacts are not counted; a particle on the floor with one rock neighbour is one).
  std::int64_t rattlers = 0;
  /// Mean coordination of the box's other particles counting only their contacts with other
  /// non-rattlers (rattlers found in one pass, over all particles); 0 without such particles.
  double coordination_no_rattlers = 0.0;
  /// |f| of the particle-particle contacts (normal and tangential force together: with
  /// friction mu, |f| lies within sqrt(1 + mu^2) of the normal force) whose branch vector's
  /// midpoint lies in the box.
  ForceDistribution force;
  /// Vertical stress of those contacts, Pa, compression positive: the Love-Weber mean
  /// stress -(1/V) sum f_z l_z, f the force on i, l = x_j - x_i (nearest image), V the box's
  /// volume (the weight of the bed above a horizontal slab, per area, in a bed at rest).
  double stress_zz = 0.0;
};

/// @brief contact_statistics of the box [lo, hi] from the system's contacts of the last step
/// (DemSystem::contact_forces). The same box rules and errors as packing_in_box().
ContactStatistics contact_statistics_in_box(const DemSystem& system,
                                            const std::array<double, 3>& lo,
                                            const std::array<double, 3>& hi);

}  // namespace demfem::dem
