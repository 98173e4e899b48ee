#pragma once
// A particle state read back from a checkpoint is checked as strictly as one built from a
// scene: a checkpoint whose manifest matches its bytes may still hold NaN positions (a state
// saved just before a blow-up, or a file edited by hand), and continuing from it would give
// garbage with exit status 0.

#include <cstdint>
#include <string>
#include <vector>

#include "demfem/dem/dem_system.hpp"

namespace demfem::dem {

/// @brief Throws std::runtime_error naming `where`, the particle and the quantity when the
/// state is not one a scene could produce: arrays of different lengths, a non-finite
/// position, velocity, angular velocity, orientation or force, a radius, mass or moment of
/// inertia that is not finite and > 0, or an orientation that is not a unit quaternion
/// (|q|^2 = 1 within 1e-6). `remedy` ends the message (what the user can do).
void check_particle_state(
    const ParticleState& state, const std::string& where,
    const std::string& remedy = "the state cannot be continued: resume from an earlier checkpoint");

/// The margin of the DEM's domain around the walls' bounding box, m: the larger of
/// kDomainMarginMin and the box's largest side.
inline constexpr double kDomainMarginMin = 1.0;

/// @brief A message naming the particle's id (`ids[i]`, or its
/// index when `ids` is shorter), its position and the time when a particle's centre lies
/// outside the domain (empty when none is): the bounding box of the walls' vertices now, grown on
/// every side by the margin (kDomainMarginMin, or the box's largest side when larger). A particle
/// that far from every wall has been shot away (a blow-up) or falls without end; its cell would
/// stretch the neighbour grid over the whole flight. A system without walls has no domain.
std::string outside_domain(const DemSystem& system, const std::vector<std::int64_t>& ids);

}  // namespace demfem::dem
