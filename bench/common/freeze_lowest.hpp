#pragma once
// Freezes the lowest `fraction` of a bed's particles by centre height (DemSystem::freeze): the
// deep bed a load case does not need to move, for the benches that measure what that saves
// (poly_throughput --frozen, sleeper_cost).

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "demfem/dem/dem_system.hpp"

namespace demfem::bench {

inline void freeze_lowest(dem::DemSystem& sys, double fraction) {
  if (fraction <= 0.0) return;
  const std::vector<double>& z = sys.particles().pz;
  std::vector<double> sorted = z;
  const auto k = static_cast<std::size_t>(fraction * static_cast<double>(z.size()));
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(k), sorted.end());
  const double cut = k < sorted.size() ? sorted[k] : 1e300;
  std::vector<std::uint8_t> mask(z.size());
  for (std::size_t i = 0; i < z.size(); ++i) mask[i] = z[i] < cut ? 1 : 0;
  sys.freeze(mask);
}

}  // namespace demfem::bench
