#pragma once
// A cell-grid coordinate from a position, for every grid of the DEM (the neighbour list's,
// the loaded bed's overlap check). Positions come from files and from runs that may blow up:
// a coordinate far outside the integer's range, infinite or NaN must not reach the float to
// integer conversion, whose result is undefined there (found by fuzzing forged states).

#include <cmath>
#include <cstdint>

#include "demfem/dem/physics/hd.hpp"
#include "demfem/dem/physics/periodic_image.hpp"

namespace demfem::dem::phys {

/// floor(q) as an integer, saturated to +-2^52 (NaN gives -2^52); callers clamp it into
/// their grid. Equal to static_cast<std::int64_t>(std::floor(q)) wherever that is defined
/// and within the bound.
DEMFEM_HD std::int64_t saturated_cell(double q) {
  constexpr double kLimit = 4503599627370496.0;  // 2^52: every integer up to it is a double
  return static_cast<std::int64_t>(q >= -kLimit ? (q <= kLimit ? std::floor(q) : kLimit) : -kLimit);
}

}  // namespace demfem::dem::phys

namespace demfem::dem::phys {

/// The grid of a neighbour-list build (both backends): dim[0] x dim[1] x dim[2] cells from
/// `lo`, of edge h[d] along axis d, numbered x fastest. The edge is the same along every axis
/// except a periodic one, whose cells divide its period exactly.
struct CellGrid {
  double lo[3];
  double h[3], inv_h[3];
  std::int64_t dim[3];

  /// The cell coordinate of x along axis d, clamped into the grid (floor, not truncation:
  /// the same cell after the clamp; below 0 both give 0).
  DEMFEM_HD std::int64_t coord(double x, int d) const {
    const std::int64_t c = saturated_cell((x - lo[d]) * inv_h[d]);
    return c < 0 ? 0 : (c > dim[d] - 1 ? dim[d] - 1 : c);
  }
  DEMFEM_HD std::int64_t cell(double x, double y, double z) const {
    return (coord(z, 2) * dim[1] + coord(y, 1)) * dim[0] + coord(x, 0);
  }
  DEMFEM_HD std::int64_t cells() const { return dim[0] * dim[1] * dim[2]; }
};

/// The grid of a build over particles in the box [lo, hi] (np of them, largest radius rmax):
/// cells of 2 rmax + skin, at most 4 np + 4096 of them. A sparse cloud (a particle far from
/// the rest) gets coarser cells instead of a grid over its whole extent. The count is formed
/// in double: in integers the product of three axes of 10^6 or more cells (a particle 450 m
/// from a bed of 0.2 mm cells) wrapped around, passed the bound, and the grid's allocation
/// failed. An infinite extent (a particle gone to inf, which the blow-up guard reports after
/// the advance) counts as none: its cell coordinate is clamped into the grid.
/// `period` (null: none): an axis with period[d] > 0 is periodic, [lo, hi) is then its whole
/// period, divided into the most cells of at least that edge (at least one).
DEMFEM_HD CellGrid cell_grid(const double lo[3], const double hi[3], std::int64_t np, double rmax,
                             double skin, const double* period = nullptr) {
  CellGrid g{};
  double h = 2.0 * rmax + skin < 1e-12 ? 1e-12 : 2.0 * rmax + skin;  // std::max's order
  const double bound = static_cast<double>(4 * np + 4096);
  double edge[3];
  for (;;) {
    double tot = 1.0;
    for (int d = 0; d < 3; ++d) {
      const double L = period != nullptr ? period[d] : 0.0;
      const double ext = std::isfinite(hi[d] - lo[d]) ? hi[d] - lo[d] : 0.0;
      const double q = std::floor(L / h);
      const double cells = L > 0.0 ? (q < 1.0 ? 1.0 : q) : std::floor(ext / h) + 1.0;
      edge[d] = L > 0.0 ? L / cells : h;
      g.dim[d] = cells <= 4.0 * static_cast<double>(np) + 4096.0 ? static_cast<std::int64_t>(cells)
                                                                 : std::int64_t{1} << 62;
      tot *= cells;
    }
    if (tot <= bound) break;
    h *= 1.26;  // a sparse cloud: coarser cells keep the grid small
  }
  for (int d = 0; d < 3; ++d) {
    g.lo[d] = lo[d];
    g.h[d] = edge[d];
    g.inv_h[d] = 1.0 / edge[d];
  }
  return g;
}

/// Particles in cell order: cell c holds sorted[cstart[c] .. cstart[c + 1]), and sx, sy, sz,
/// sr are their positions and radii in that order (contiguous per cell).
struct CellOrder {
  const std::int64_t* cstart;
  const std::int32_t* sorted;
  const double *sx, *sy, *sz, *sr;
};

/// The candidate partners j > i of particle i (at xi, yi, zi, radius ri) in the 27 cells
/// around it: emit(j) for each j within ri + rj + skin, cell by cell (z, then y, then the
/// three consecutive x cells of a row), in cell order within a cell. Both backends' builds.
template <class Emit>
DEMFEM_HD void for_each_candidate(const CellGrid& g, const CellOrder& o, std::int64_t i, double xi,
                                  double yi, double zi, double ri, double skin, Emit&& emit) {
  const std::int64_t cx = g.coord(xi, 0), cy = g.coord(yi, 1), cz = g.coord(zi, 2);
  const std::int64_t z0 = cz > 0 ? cz - 1 : 0, z1 = cz + 1 < g.dim[2] ? cz + 1 : g.dim[2] - 1;
  const std::int64_t y0 = cy > 0 ? cy - 1 : 0, y1 = cy + 1 < g.dim[1] ? cy + 1 : g.dim[1] - 1;
  const std::int64_t x0 = cx > 0 ? cx - 1 : 0, x1 = cx + 1 < g.dim[0] ? cx + 1 : g.dim[0] - 1;
  for (std::int64_t z = z0; z <= z1; ++z)
    for (std::int64_t y = y0; y <= y1; ++y) {
      const std::int64_t c0 = (z * g.dim[1] + y) * g.dim[0];
      const std::int64_t k1 = o.cstart[c0 + x1 + 1];
      for (std::int64_t k = o.cstart[c0 + x0]; k < k1; ++k) {
        const std::int32_t j = o.sorted[k];
        if (j <= i) continue;
        const double dx = o.sx[k] - xi, dy = o.sy[k] - yi, dz = o.sz[k] - zi;
        const double cut = ri + o.sr[k] + skin;
        if (dx * dx + dy * dy + dz * dz < cut * cut) emit(j);
      }
    }
}

/// for_each_candidate in a grid with periodic axes (b.period[d] > 0): the neighbour cells wrap
/// there (each cell once where the period holds fewer than three), and each candidate is taken
/// at its image nearest to i. The emission order differs from for_each_candidate's; callers
/// sort each row.
template <class Emit>
DEMFEM_HD void for_each_periodic_candidate(const CellGrid& g, const CellOrder& o,
                                           const PeriodicBox& b, std::int64_t i, double xi,
                                           double yi, double zi, double ri, double skin,
                                           Emit&& emit) {
  const double x[3] = {xi, yi, zi};
  std::int64_t near[3][3];
  int count[3];
  for (int d = 0; d < 3; ++d) {
    const std::int64_t c = g.coord(x[d], d);
    count[d] = 0;
    for (std::int64_t off = -1; off <= 1; ++off) {
      std::int64_t q = c + off;
      if (b.period[d] > 0.0)
        q = (q + g.dim[d]) % g.dim[d];
      else if (q < 0 || q >= g.dim[d])
        continue;
      bool seen = false;
      for (int e = 0; e < count[d]; ++e) seen = seen || near[d][e] == q;
      if (!seen) near[d][count[d]++] = q;
    }
  }
  for (int a = 0; a < count[2]; ++a)
    for (int bb = 0; bb < count[1]; ++bb)
      for (int e = 0; e < count[0]; ++e) {
        const std::int64_t c = (near[2][a] * g.dim[1] + near[1][bb]) * g.dim[0] + near[0][e];
        for (std::int64_t k = o.cstart[c]; k < o.cstart[c + 1]; ++k) {
          const std::int32_t j = o.sorted[k];
          if (j <= i) continue;
          const double dx = image_branch(b, 0, xi, o.sx[k]);
          const double dy = image_branch(b, 1, yi, o.sy[k]);
          const double dz = image_branch(b, 2, zi, o.sz[k]);
          const double cut = ri + o.sr[k] + skin;
          if (dx * dx + dy * dy + dz * dz < cut * cut) emit(j);
        }
      }
}

}  // namespace demfem::dem::phys
