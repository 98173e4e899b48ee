#pragma once
// What a solver wrote into the interface buffers that is not finite, found by the coupler
// after every step and blamed on that solver by name (its blow-up, exit status 3), before
// the other solver is given it: the FEM's kinematics, the DEM's forces and mesh positions
// (an outside program on either side, docs/backends.md).

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

#include "demfem/protocol/protocol.hpp"

namespace demfem::coupling {

/// @brief Index of the first entry that is not finite, or -1.
std::ptrdiff_t first_non_finite(std::span<const double> v);

/// @brief The first position, velocity or acceleration the FEM wrote into buffer `b` that is
/// not finite: "the velocity it wrote for interface node 7 is not finite: (0, 0, inf) m/s",
/// or "" when all are.
std::string non_finite_fem_kinematics(protocol::InterfaceBuffers& buf, std::uint32_t b);

/// @brief The same for what the DEM wrote: its forces (N) and its mesh positions (m).
std::string non_finite_dem_output(protocol::InterfaceBuffers& buf, std::uint32_t b);

}  // namespace demfem::coupling
