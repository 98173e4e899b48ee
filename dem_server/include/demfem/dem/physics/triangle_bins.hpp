#pragma once
// Wall triangles binned into the neighbour list's cell grid, for both backends' builds: the
// cells a triangle's box (grown by the largest radius and the skin) covers, and whether a
// particle is near enough a binned triangle to keep it as a candidate.

#include <cstdint>

#include "demfem/dem/physics/geometry.hpp"
#include "demfem/dem/physics/grid_cell.hpp"

namespace demfem::dem::phys {

/// The cells of triangle tv (vertex indices into vpos, 3 per vertex) grown by `grow`:
/// box = {x0, y0, z0, x1, y1, z1}, inclusive. False (box untouched) when the grown box
/// misses the grid [lo, lo + dim h] on some axis.
DEMFEM_HD bool triangle_cell_box(const CellGrid& g, const double* vpos, const std::int32_t* tv,
                                 double grow, std::int64_t box[6]) {
  double tl[3] = {1e300, 1e300, 1e300}, th[3] = {-1e300, -1e300, -1e300};
  for (int e = 0; e < 3; ++e)
    for (int d = 0; d < 3; ++d) {
      const double x = vpos[3 * tv[e] + d];
      tl[d] = x - grow < tl[d] ? x - grow : tl[d];  // std::min's order
      th[d] = th[d] < x + grow ? x + grow : th[d];  // std::max's order
    }
  bool out = false;
  std::int64_t b[6];
  for (int d = 0; d < 3; ++d) {
    if (th[d] < g.lo[d] || tl[d] > g.lo[d] + static_cast<double>(g.dim[d]) * g.h[d]) out = true;
    b[d] = g.coord(tl[d], d);
    b[3 + d] = g.coord(th[d], d);
  }
  if (out) return false;
  for (int k = 0; k < 6; ++k) box[k] = b[k];
  return true;
}

/// Number of cells in a box of triangle_cell_box().
DEMFEM_HD std::int64_t box_cells(const std::int64_t box[6]) {
  return (box[3] - box[0] + 1) * (box[4] - box[1] + 1) * (box[5] - box[2] + 1);
}

/// Whether the particle at p (radius r) is within r + skin of triangle tv: a candidate.
DEMFEM_HD bool near_triangle(Vec3 p, double r, double skin, const double* vpos,
                             const std::int32_t* tv) {
  const double* v = vpos;
  const auto cp = closest_point_triangle(p, Vec3{v[3 * tv[0]], v[3 * tv[0] + 1], v[3 * tv[0] + 2]},
                                         Vec3{v[3 * tv[1]], v[3 * tv[1] + 1], v[3 * tv[1] + 2]},
                                         Vec3{v[3 * tv[2]], v[3 * tv[2] + 1], v[3 * tv[2] + 2]});
  const double cut = r + skin;
  return norm2(p - cp.point) < cut * cut;
}

}  // namespace demfem::dem::phys
