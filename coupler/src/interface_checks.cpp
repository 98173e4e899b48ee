#include "interface_checks.hpp"

#include <cmath>
#include <initializer_list>
#include <sstream>
#include <tuple>

namespace demfem::coupling {

std::ptrdiff_t first_non_finite(std::span<const double> v) {
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (!std::isfinite(v[i])) return static_cast<std::ptrdiff_t>(i);
  }
  return -1;
}

namespace {

// The first entry of `arrays` (what, unit, values) that is not finite, with its node: "the
// force it wrote for interface node 7 is not finite: (0, 0, nan) N", or "" when all are.
using NamedArray = std::tuple<const char*, const char*, std::span<const double>>;
std::string first_non_finite_node(std::initializer_list<NamedArray> arrays) {
  for (const auto& [what, unit, v] : arrays) {
    const std::ptrdiff_t k = first_non_finite(v);
    if (k < 0) continue;
    const double* node = &v[static_cast<std::size_t>(k - k % 3)];
    std::ostringstream m;
    m.precision(6);
    m << "the " << what << " it wrote for interface node " << k / 3 << " is not finite: ("
      << node[0] << ", " << node[1] << ", " << node[2] << ") " << unit;
    return m.str();
  }
  return {};
}

}  // namespace

// Checked after every FEM step: another process would otherwise be blamed for it (the DEM,
// moving its mesh with them).
std::string non_finite_fem_kinematics(protocol::InterfaceBuffers& buf, std::uint32_t b) {
  return first_non_finite_node({{"position", "m", buf.positions(b)},
                                {"velocity", "m/s", buf.velocities(b)},
                                {"acceleration", "m/s^2", buf.accelerations(b)}});
}

// Checked after every DEM step, before the FEM is given the forces (it would be blamed for the
// motion they cause) (issue 36: an external DEM; dem_server checks its own forces too).
std::string non_finite_dem_output(protocol::InterfaceBuffers& buf, std::uint32_t b) {
  return first_non_finite_node(
      {{"force", "N", buf.forces(b)}, {"mesh position", "m", buf.dem_positions(b)}});
}

}  // namespace demfem::coupling
