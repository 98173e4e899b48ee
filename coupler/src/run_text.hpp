#pragma once
// How the coupling run spells numbers and solvers in its messages (errors, reports), so that
// every part of it (schemes, checks, checkpoints, recovery) names them alike. Private to the
// coupling library.

#include <sstream>
#include <string>

#include "demfem/protocol/protocol.hpp"

namespace demfem::coupling {

/// @brief A number in a message: six significant digits ("0.0015", "1e-09").
inline std::string format_number(double v) {
  std::ostringstream s;
  s.precision(6);
  s << v;
  return s.str();
}

/// @brief "DEM" or "FEM".
inline const char* role_label(protocol::Role role) {
  return role == protocol::Role::dem ? "DEM" : "FEM";
}

}  // namespace demfem::coupling
