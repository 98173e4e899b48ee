// DemSystem::Impl: the neighbour list. A uniform grid by counting sort builds the candidate
// pairs within r_i + r_j + skin (and each particle's candidate wall triangles); the list
// proper, refiltered from them, holds the pairs within the inner skin, which adapts to
// how often the list must be updated (dem_system_impl.hpp).

#include "dem_system_impl.hpp"
#include "demfem/dem/physics/grid_cell.hpp"
#include "demfem/dem/physics/triangle_bins.hpp"

#include <omp.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

namespace demfem::dem {

using phys::Vec3;

bool DemSystem::Impl::adapt_inner_skin(bool build, double pbuild) {
  const std::int64_t since = steps - steps_at_update;
  const bool first = steps_at_update < 0;
  if (gpu != nullptr || s.list_skin > 0.0 || first) {  // fixed; one level on the device
    steps_at_update = steps;
    return true;
  }
  if (skin_in >= skin) {  // one level: updates are builds
    if (since > 100) skin_in = kInnerSkin * skin;
  } else if (since < 10) {
    const double grown = 1.5 * skin_in;
    if (build) {
      skin_in = grown > kInnerSkinMax * skin ? skin : grown;
    } else {
      if (grown > kInnerSkinMax * skin || pbuild > skin - grown) return false;
      skin_in = grown;
    }
  } else if (since > 40) {
    skin_in = std::max(kInnerSkin * skin, skin_in / 1.5);
  }
  steps_at_update = steps;
  return true;
}

void DemSystem::Impl::rebuild() {
  const std::size_t np = n();
  ++rebuilds;
  double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
  const double* P[3] = {st.px.data(), st.py.data(), st.pz.data()};
  for (std::size_t i = 0; i < np; ++i)
    for (int d = 0; d < 3; ++d) {
      lo[d] = std::min(lo[d], P[d][i]);
      hi[d] = std::max(hi[d], P[d][i]);
    }
  if (np == 0)
    for (int d = 0; d < 3; ++d) lo[d] = hi[d] = 0.0;
  // a periodic direction's grid spans its period, in cells of at least 2 rmax + skin (its
  // positions lie in [lo, lo + L): wrap_positions; a frozen particle outside is clamped into
  // the edge cell)
  for (int d = 0; d < 3; ++d)
    if (pbox.period[d] > 0.0) lo[d] = pbox.lo[d], hi[d] = pbox.lo[d] + pbox.period[d];
  const phys::CellGrid grid =
      phys::cell_grid(lo, hi, static_cast<std::int64_t>(np), rmax, skin, pbox.period);
  const std::int64_t ncell = grid.cells();
  std::vector<std::int32_t> cell(np);
  for (std::size_t i = 0; i < np; ++i)
    cell[i] = static_cast<std::int32_t>(grid.cell(P[0][i], P[1][i], P[2][i]));
  std::vector<std::int64_t> cstart(ncell + 1, 0);
  for (std::size_t i = 0; i < np; ++i) ++cstart[cell[i] + 1];
  for (std::int64_t c = 0; c < ncell; ++c) cstart[c + 1] += cstart[c];
  std::vector<std::int32_t> sorted(np);
  {
    std::vector<std::int64_t> fill(cstart.begin(), cstart.end() - 1);
    for (std::size_t i = 0; i < np; ++i) sorted[fill[cell[i]]++] = static_cast<std::int32_t>(i);
  }
  // Positions and radii in cell order: the scan reads each neighbour cell's spheres from
  // contiguous memory (in particle order they are scattered once a bed has flowed).
  const std::int64_t sn = static_cast<std::int64_t>(np);
  std::vector<double> sx(np), sy(np), sz(np), sr(np);
  const double* R = st.radius.data();
#pragma omp parallel for num_threads(nt()) schedule(static)
  for (std::int64_t k = 0; k < sn; ++k) {
    const std::int32_t i = sorted[k];
    sx[k] = P[0][i], sy[k] = P[1][i], sz[k] = P[2][i], sr[k] = R[i];
  }
  const phys::CellOrder order{cstart.data(), sorted.data(), sx.data(),
                              sy.data(),     sz.data(),     sr.data()};
  auto scan = [&](std::size_t i, auto&& emit) {
    phys::for_each_candidate(grid, order, static_cast<std::int64_t>(i), P[0][i], P[1][i], P[2][i],
                             R[i], skin, emit);
  };
  auto scan_periodic = [&](std::size_t i, auto&& emit) {
    phys::for_each_periodic_candidate(grid, order, pbox, static_cast<std::int64_t>(i), P[0][i],
                                      P[1][i], P[2][i], R[i], skin, emit);
  };
  // One scan: the particles in nt() contiguous chunks, each chunk's sorted rows appended to
  // its own buffer, then the buffers copied into place (the rows of a scan per particle,
  // for any thread count).
  std::vector<std::int64_t> nrow(np + 1, 0);
  const std::int64_t chunks = nt();
  std::vector<std::vector<std::int32_t>> found(static_cast<std::size_t>(chunks));
#pragma omp parallel for num_threads(nt()) schedule(static, 1)
  for (std::int64_t ch = 0; ch < chunks; ++ch) {
    const std::int64_t b0 = sn * ch / chunks, b1 = sn * (ch + 1) / chunks;
    auto& buf = found[static_cast<std::size_t>(ch)];
    buf.reserve(static_cast<std::size_t>(8 * (b1 - b0)));
    for (std::int64_t i = b0; i < b1; ++i) {
      const std::size_t start = buf.size();
      if (periodic)
        scan_periodic(static_cast<std::size_t>(i), [&](std::int32_t j) { buf.push_back(j); });
      else
        scan(static_cast<std::size_t>(i), [&](std::int32_t j) { buf.push_back(j); });
      std::sort(buf.begin() + static_cast<std::ptrdiff_t>(start), buf.end());
      nrow[i + 1] = static_cast<std::int64_t>(buf.size() - start);
    }
  }
  for (std::size_t i = 0; i < np; ++i) nrow[i + 1] += nrow[i];
  std::vector<std::int32_t> nnbr(static_cast<std::size_t>(nrow[np]));
#pragma omp parallel for num_threads(nt()) schedule(static, 1)
  for (std::int64_t ch = 0; ch < chunks; ++ch) {
    const auto& buf = found[static_cast<std::size_t>(ch)];
    std::copy(buf.begin(), buf.end(), nnbr.begin() + nrow[sn * ch / chunks]);
  }
  orow.swap(nrow);
  onbr.swap(nnbr);
  out_disp = 0.0;
  out_pair = 0.0;
  adapt_inner_skin(true);
  // triangles: binned into the particle cells their AABB (grown by rmax + skin) touches
  bin_wall_triangles(grid, cell);
  vbuild = vpos;
  need_rebuild = false;
  refilter();
}

void DemSystem::Impl::bin_wall_triangles(const phys::CellGrid& grid,
                                          const std::vector<std::int32_t>& cell) {
  const std::size_t np = n();
  const std::int64_t sn = static_cast<std::int64_t>(np);
  const double* P[3] = {st.px.data(), st.py.data(), st.pz.data()};
  const double* R = st.radius.data();
  const std::int64_t* dim = grid.dim;
  const std::int64_t ncell = grid.cells();
  prow.assign(np + 1, 0);
  ptri.clear();
  const std::size_t ntri = tri_v.size() / 3;
  if (ntri > 0 && np > 0) {
    const double grow = rmax + skin;
    std::vector<std::int64_t> tcount(ncell + 1, 0);
    std::vector<std::array<std::int64_t, 6>> box(ntri);
    for (std::size_t k = 0; k < ntri; ++k) {
      if (!phys::triangle_cell_box(grid, vpos.data(), tri_v.data() + 3 * k, grow, box[k].data()))
        box[k][0] = -1;
      else
        for (std::int64_t z = box[k][2]; z <= box[k][5]; ++z)
          for (std::int64_t y = box[k][1]; y <= box[k][4]; ++y)
            for (std::int64_t x = box[k][0]; x <= box[k][3]; ++x)
              ++tcount[(z * dim[1] + y) * dim[0] + x + 1];
    }
    for (std::int64_t c = 0; c < ncell; ++c) tcount[c + 1] += tcount[c];
    std::vector<std::int32_t> tbin(static_cast<std::size_t>(tcount[ncell]));
    {
      std::vector<std::int64_t> fill(tcount.begin(), tcount.end() - 1);
      for (std::size_t k = 0; k < ntri; ++k) {
        if (box[k][0] < 0) continue;
        for (std::int64_t z = box[k][2]; z <= box[k][5]; ++z)
          for (std::int64_t y = box[k][1]; y <= box[k][4]; ++y)
            for (std::int64_t x = box[k][0]; x <= box[k][3]; ++x)
              tbin[fill[(z * dim[1] + y) * dim[0] + x]++] = static_cast<std::int32_t>(k);
      }
    }
    auto near = [&](std::size_t i, std::int32_t k) {
      return phys::near_triangle(Vec3{P[0][i], P[1][i], P[2][i]}, R[i], skin, vpos.data(),
                                 tri_v.data() + 3 * k);
    };
#pragma omp parallel for num_threads(nt()) schedule(static)
    for (std::int64_t i = 0; i < sn; ++i) {
      const std::int32_t c = cell[i];
      std::int64_t cnt = 0;
      for (std::int64_t k = tcount[c]; k < tcount[c + 1]; ++k)
        if (near(static_cast<std::size_t>(i), tbin[k])) ++cnt;
      prow[i + 1] = cnt;
    }
    for (std::size_t i = 0; i < np; ++i) prow[i + 1] += prow[i];
    ptri.resize(static_cast<std::size_t>(prow[np]));
#pragma omp parallel for num_threads(nt()) schedule(static)
    for (std::int64_t i = 0; i < sn; ++i) {
      const std::int32_t c = cell[i];
      std::int64_t o = prow[i];
      for (std::int64_t k = tcount[c]; k < tcount[c + 1]; ++k)
        if (near(static_cast<std::size_t>(i), tbin[k])) ptri[o++] = tbin[k];
    }
  }
}

void DemSystem::Impl::refilter() {
  const std::size_t np = n();
  const std::int64_t sn = static_cast<std::int64_t>(np);
  ++refilters;
  const double* P[3] = {st.px.data(), st.py.data(), st.pz.data()};
  const double* R = st.radius.data();
  std::vector<std::int64_t> nrow(np + 1, 0);
  auto keep = [&](std::int64_t i, std::int32_t j) {
    double dx = P[0][j] - P[0][i], dy = P[1][j] - P[1][i], dz = P[2][j] - P[2][i];
    if (periodic) {  // j at its image nearest to i
      dx += phys::image_shift(pbox, 0, dx);
      dy += phys::image_shift(pbox, 1, dy);
      dz += phys::image_shift(pbox, 2, dz);
    }
    const double cut = R[i] + R[j] + skin_in;
    return dx * dx + dy * dy + dz * dz < cut * cut;
  };
#pragma omp parallel for num_threads(nt()) schedule(static)
  for (std::int64_t i = 0; i < sn; ++i) {
    std::int64_t c = 0;
    for (std::int64_t k = orow[i]; k < orow[i + 1]; ++k) c += keep(i, onbr[k]) ? 1 : 0;
    nrow[i + 1] = c;
  }
  for (std::size_t i = 0; i < np; ++i) nrow[i + 1] += nrow[i];
  std::vector<std::int32_t> nnbr(static_cast<std::size_t>(nrow[np]));
#pragma omp parallel for num_threads(nt()) schedule(static)
  for (std::int64_t i = 0; i < sn; ++i) {
    std::int64_t c = nrow[i];
    for (std::int64_t k = orow[i]; k < orow[i + 1]; ++k)
      if (keep(i, onbr[k])) nnbr[c++] = onbr[k];
  }
  // carry the tangential springs over (merge of the sorted old and new rows)
  const std::size_t npair = nnbr.size();
  std::vector<double> nshear, nrhist, naxis;
  std::vector<std::int32_t> nfeat;
  if (rolling) nrhist.assign(3 * npair, 0.0);  // carried with the springs
  if (poly) naxis.assign(3 * npair, 0.0);      // and the narrow phase's caches
  if (poly) nfeat.assign(6 * npair, -1);
  if (friction) nshear.assign(3 * npair, 0.0);
  if ((friction || poly) && row.size() == np + 1) {
    const bool carry_axis = poly && slots.separating_axis.size() == 3 * nbr.size() &&
                            slots.closest_features.size() == 6 * nbr.size();
#pragma omp parallel for num_threads(nt()) schedule(static)
    for (std::int64_t i = 0; i < sn; ++i) {
      std::int64_t a = row[i], b = nrow[i];
      while (a < row[i + 1] && b < nrow[i + 1]) {
        if (nbr[a] < nnbr[b]) {
          ++a;
        } else if (nbr[a] > nnbr[b]) {
          ++b;
        } else {
          if (friction)
            for (int d = 0; d < 3; ++d) nshear[3 * b + d] = slots.shear[3 * a + d];
          if (friction && rolling && slots.rolling_history.size() == slots.shear.size())
            for (int d = 0; d < 3; ++d) nrhist[3 * b + d] = slots.rolling_history[3 * a + d];
          if (carry_axis) {
            for (int d = 0; d < 3; ++d) naxis[3 * b + d] = slots.separating_axis[3 * a + d];
            for (int d = 0; d < 6; ++d) nfeat[6 * b + d] = slots.closest_features[6 * a + d];
          }
          ++a, ++b;
        }
      }
    }
  }
  row.swap(nrow);
  nbr.swap(nnbr);
  slots.shear.swap(nshear);
  slots.rolling_history.swap(nrhist);
  slots.separating_axis.swap(naxis);
  slots.closest_features.swap(nfeat);
  index_list();
  bx.resize(np), by.resize(np), bz.resize(np);
#pragma omp parallel for num_threads(nt()) schedule(static)
  for (std::int64_t i = 0; i < sn; ++i) bx[i] = st.px[i], by[i] = st.py[i], bz[i] = st.pz[i];
}

void DemSystem::Impl::index_list() {
  const std::size_t np = n(), npair = nbr.size();
  const std::int64_t sn = static_cast<std::int64_t>(np);
  pown.resize(npair);
#pragma omp parallel for num_threads(nt()) schedule(static)
  for (std::int64_t i = 0; i < sn; ++i)
    std::fill(pown.begin() + row[i], pown.begin() + row[i + 1], static_cast<std::int32_t>(i));
  uniform_mat = np > 0 ? st.material[0] : -1;
  for (std::size_t i = 0; i < np && uniform_mat >= 0; ++i)
    if (st.material[i] != uniform_mat) uniform_mat = -1;
  slots.force.assign(3 * npair, 0.0);
  if (friction || poly)
    slots.torque.assign(3 * npair, 0.0);
  else
    slots.torque.clear();
  if (poly)
    slots.torque_j.assign(3 * npair, 0.0);
  else
    slots.torque_j.clear();
  if (rolling)
    slots.rolling_torque.assign(3 * npair, 0.0);
  else
    slots.rolling_torque.clear();
  // transposed index: for each j the pairs (i, j), i ascending (counting sort is stable)
  trow.assign(np + 1, 0);
  for (std::size_t p = 0; p < npair; ++p) ++trow[nbr[p] + 1];
  for (std::size_t i = 0; i < np; ++i) trow[i + 1] += trow[i];
  tpair.resize(npair);
  tsrc.resize(npair);
  {
    std::vector<std::int64_t> fill(trow.begin(), trow.end() - 1);
    for (std::size_t i = 0; i < np; ++i)
      for (std::int64_t p = row[i]; p < row[i + 1]; ++p) {
        const std::int64_t k = fill[nbr[p]]++;
        tpair[k] = p;
        tsrc[k] = static_cast<std::int32_t>(i);
      }
  }
  // the gather's list: per particle its own row's pairs (sign +1), then its transposed
  // pairs (sign -1), in the order of the two loops it replaces
  // (row and trow are prefix sums, so particle i's entries start at row[i] + trow[i])
  gather_row.resize(np + 1);
  gather_pair.resize(2 * npair);
  gather_sign.resize(2 * npair);
#pragma omp parallel for num_threads(nt()) schedule(static)
  for (std::int64_t i = 0; i <= sn; ++i) gather_row[i] = row[i] + trow[i];
#pragma omp parallel for num_threads(nt()) schedule(static)
  for (std::int64_t i = 0; i < sn; ++i) {
    std::int64_t g = gather_row[i];
    for (std::int64_t p = row[i]; p < row[i + 1]; ++p) gather_pair[g] = p, gather_sign[g++] = 1.0;
    for (std::int64_t k = trow[i]; k < trow[i + 1]; ++k)
      gather_pair[g] = tpair[k], gather_sign[g++] = -1.0;
  }
}

double DemSystem::Impl::two_largest_displacements() {
  const std::int64_t sn = static_cast<std::int64_t>(n());
  const int T = nt();
  top_two.assign(static_cast<std::size_t>(T), {0.0, 0.0});
#pragma omp parallel num_threads(T)
  {
    double a = 0.0, b = 0.0;  // a >= b, squared
#pragma omp for schedule(static)
    for (std::int64_t i = 0; i < sn; ++i) {
      const double dx = st.px[i] - bx[i], dy = st.py[i] - by[i], dz = st.pz[i] - bz[i];
      const double d2 = dx * dx + dy * dy + dz * dz;
      if (d2 > a) {
        b = a;
        a = d2;
      } else if (d2 > b) {
        b = d2;
      }
    }
    top_two[static_cast<std::size_t>(omp_get_thread_num())] = {a, b};
  }
  double a = 0.0, b = 0.0;
  for (const auto& [ta, tb] : top_two) {
    b = std::max(b, std::min(a, ta));
    a = std::max(a, ta);
    b = std::max(b, tb);
  }
  return std::sqrt(a) + std::sqrt(b);
}

}  // namespace demfem::dem
