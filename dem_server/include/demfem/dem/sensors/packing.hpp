#pragma once
// Packing of a granular bed in a control box (the `packing` sensor): solid fraction, mean
// coordination number and the height of the bed's top, as EDEM's and LIGGGHTS's bin
// measurements report them. A particle belongs to the box when its centre lies in it.

#include <array>
#include <cstdint>

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

}  // namespace demfem::dem
