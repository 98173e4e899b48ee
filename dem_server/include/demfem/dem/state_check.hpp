#pragma once
// A particle state read back from a checkpoint is checked as strictly as one built from a
// scene: a checkpoint whose manifest matches its bytes may still hold NaN positions (a state
// saved just before a blow-up, or a file edited by hand), and continuing from it would give
// garbage with exit status 0.

#include <string>

#include "demfem/dem/dem_system.hpp"

namespace demfem::dem {

/// @brief Throws std::runtime_error naming `where`, the particle and the quantity when the
/// state is not one a scene could produce: arrays of different lengths, a non-finite
/// position, velocity, angular velocity, orientation or force, a radius, mass or moment of
/// inertia that is not finite and > 0, or an orientation that is not a unit quaternion
/// (|q|^2 = 1 within 1e-6).
void check_particle_state(const ParticleState& state, const std::string& where);

}  // namespace demfem::dem
