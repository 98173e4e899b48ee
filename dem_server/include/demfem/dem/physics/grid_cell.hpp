#pragma once
// A cell-grid coordinate from a position, for every grid of the DEM (the neighbour list's,
// the loaded bed's overlap check). Positions come from files and from runs that may blow up:
// a coordinate far outside the integer's range, infinite or NaN must not reach the float to
// integer conversion, whose result is undefined there (found by fuzzing forged states).

#include <cmath>
#include <cstdint>

#include "demfem/dem/physics/hd.hpp"

namespace demfem::dem::phys {

/// floor(q) as an integer, saturated to +-2^52 (NaN gives -2^52); callers clamp it into
/// their grid. Equal to static_cast<std::int64_t>(std::floor(q)) wherever that is defined
/// and within the bound.
DEMFEM_HD std::int64_t saturated_cell(double q) {
  constexpr double kLimit = 4503599627370496.0;  // 2^52: every integer up to it is a double
  return static_cast<std::int64_t>(q >= -kLimit ? (q <= kLimit ? std::floor(q) : kLimit) : -kLimit);
}

}  // namespace demfem::dem::phys
