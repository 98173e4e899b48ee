#pragma once
// Periodic boundaries (docs/dem.md, "Periodic boundaries and tiled beds"): in a periodic
// direction a particle that leaves [lo, lo + L) comes back in at the other side (its image
// counter records how often it went round), and a pair interacts through the image of j
// nearest to i. The period is at least twice the neighbour list's cutoff (2 r_max + skin),
// so that image is unique for every pair that can touch, and the positions of moving
// particles stay in [lo, lo + L) (wrapped each step): the branch vector x_j - x_i then lies
// in (-L, L) and the nearest image is a select, not a rounding (it vectorises). Shared by
// the pair kernels, the neighbour lists (the CPU's and the device's), the wrap of both
// backends' drifts and the sensors.

#include <cmath>

#include "demfem/dem/physics/hd.hpp"

namespace demfem::dem::phys {

/// @brief The periods of a system: per direction L (0 where not periodic), L / 2 (a huge
/// value where not periodic, so that no shift is ever chosen there) and the range's low end.
struct PeriodicBox {
  double period[3] = {0.0, 0.0, 0.0};
  double half[3] = {1e308, 1e308, 1e308};
  double lo[3] = {0.0, 0.0, 0.0};
};

/// The shift (0 or ±L) that takes the component d of a branch vector x_j - x_i, |dx| < L,
/// to the nearest image's: x_j + shift - x_i lies in [-L/2, L/2].
DEMFEM_HD double image_shift(const PeriodicBox& b, int d, double dx) {
  const double L = b.period[d];
  return dx > b.half[d] ? -L : (dx < -b.half[d] ? L : 0.0);
}

/// The branch vector x_j - x_i of a pair to the nearest image of j, per component: the
/// difference plus its image shift (an interior pair's difference is returned as is).
DEMFEM_HD double image_branch(const PeriodicBox& b, int d, double xi, double xj) {
  const double dx = xj - xi;
  return dx + image_shift(b, d, dx);
}

/// How many periods to take off coordinate x of direction d to bring it into [lo, lo + L):
/// +1 above, -1 below, 0 inside (a moving particle crosses the seam once per step at most;
/// callers repeat for larger jumps).
DEMFEM_HD int wrap_count(const PeriodicBox& b, int d, double x) {
  const double L = b.period[d];
  if (!(L > 0.0)) return 0;
  return x >= b.lo[d] + L ? 1 : (x < b.lo[d] ? -1 : 0);
}

/// Brings coordinate x of direction d into [lo, lo + L) after a drift (wrap_count), and the
/// list's build position `x_build` (null: none) by the same period, so that the displacement
/// since the build is unchanged. Returns the periods taken off (the image counter's step).
/// A particle moves less than a period per step: one wrap brings it in, up to the rounding
/// of x -/+ L, which the clamp keeps out of a wrap back in the next step.
DEMFEM_HD int wrap_coordinate(const PeriodicBox& b, int d, double& x, double* x_build) {
  const int k = wrap_count(b, d, x);
  if (k == 0) return 0;
  const double L = b.period[d], lo = b.lo[d], top = std::nextafter(lo + L, lo);
  const double y = x - k * L;
  x = y < lo ? lo : (top < y ? top : y);  // std::clamp(y, lo, top)
  if (x_build != nullptr) *x_build -= k * L;
  return k;
}

}  // namespace demfem::dem::phys
