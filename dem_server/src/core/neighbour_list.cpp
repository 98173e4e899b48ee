// The neighbour list (neighbour_list.hpp): a uniform grid by counting sort builds the
// candidate pairs within r_i + r_j + skin; the list proper, refiltered from them, holds the
// pairs within the inner skin, which adapts to how often the list must be updated.

#include "neighbour_list.hpp"

#include <omp.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include "demfem/dem/physics/step_integrator.hpp"

namespace demfem::dem::detail {

bool NeighbourList::adapt_inner_skin(std::int64_t steps, bool fixed, bool build, double pbuild) {
  const std::int64_t since = steps - steps_at_update;
  const bool first = steps_at_update < 0;
  if (fixed || first) {
    steps_at_update = steps;
    return true;
  }
  if (inner_skin >= skin) {  // one level: updates are builds
    if (since > 100) inner_skin = kInnerSkin * skin;
  } else if (since < 10) {
    const double grown = 1.5 * inner_skin;
    if (build) {
      inner_skin = grown > kInnerSkinMax * skin ? skin : grown;
    } else {
      if (grown > kInnerSkinMax * skin || pbuild > skin - grown) return false;
      inner_skin = grown;
    }
  } else if (since > 40) {
    inner_skin = std::max(kInnerSkin * skin, inner_skin / 1.5);
  }
  steps_at_update = steps;
  return true;
}

NeighbourList::Update NeighbourList::next_update(const ListParticles& p, double disp,
                                                 double wall_disp, std::int64_t steps, bool fixed) {
  // Build when the candidates may miss a pair that comes within inner_skin (d_i + d_j since
  // the build > skin - inner_skin) or a wall; refilter when a pair outside the list may touch
  // (d_i + d_j since the last update > inner_skin). d_i + d_j is bounded by twice the largest
  // displacement, and when that bound calls for an update, by the sum of the two largest
  // (a pass over the particles): a few fast spheres in a resting bed then use the whole
  // skin before they call for a build, instead of half of it.
  const double dbuild = build_disp + disp;  // |x - x_build| <= sum of the refilter intervals
  const phys::ListRule rule{skin, inner_skin, build_pair_disp};
  double pdisp = 2.0 * disp;
  if (!must_build && disp < 1e300 && (rule.build_by_pairs(pdisp) || rule.refilter_by_pairs(pdisp)))
    pdisp = two_largest_displacements(p);
  const double pbuild = build_pair_disp + pdisp;  // d_i + d_j since the build, any pair
  // (one level: no refilter has added to build_disp since the build, so dbuild = disp)
  if (must_build || rule.build_by_pairs(pdisp) || rule.build_by_walls(dbuild, wall_disp))
    return Update::build;
  if (!rule.refilter_by_pairs(pdisp)) return Update::none;
  if (!adapt_inner_skin(steps, fixed, false, pbuild)) return Update::build;
  build_disp += disp;
  build_pair_disp += pdisp;
  return Update::refilter;
}

void NeighbourList::build(const ListParticles& p, double rmax) {
  const auto np = static_cast<std::size_t>(p.n);
  const phys::PeriodicBox& pbox = p.box;
  ++builds;
  double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
  const double* P[3] = {p.x, p.y, p.z};
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
  grid = phys::cell_grid(lo, hi, static_cast<std::int64_t>(np), rmax, skin, pbox.period);
  const std::int64_t ncell = grid.cells();
  cell.resize(np);
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
  const double* R = p.radius;
#pragma omp parallel for num_threads(p.threads) schedule(static)
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
  // One scan: the particles in p.threads contiguous chunks, each chunk's sorted rows appended to
  // its own buffer, then the buffers copied into place (the rows of a scan per particle,
  // for any thread count).
  std::vector<std::int64_t> nrow(np + 1, 0);
  const std::int64_t chunks = p.threads;
  std::vector<std::vector<std::int32_t>> found(static_cast<std::size_t>(chunks));
#pragma omp parallel for num_threads(p.threads) schedule(static, 1)
  for (std::int64_t ch = 0; ch < chunks; ++ch) {
    const std::int64_t b0 = sn * ch / chunks, b1 = sn * (ch + 1) / chunks;
    auto& buf = found[static_cast<std::size_t>(ch)];
    buf.reserve(static_cast<std::size_t>(8 * (b1 - b0)));
    for (std::int64_t i = b0; i < b1; ++i) {
      const std::size_t start = buf.size();
      if (p.periodic)
        scan_periodic(static_cast<std::size_t>(i), [&](std::int32_t j) { buf.push_back(j); });
      else
        scan(static_cast<std::size_t>(i), [&](std::int32_t j) { buf.push_back(j); });
      std::sort(buf.begin() + static_cast<std::ptrdiff_t>(start), buf.end());
      nrow[i + 1] = static_cast<std::int64_t>(buf.size() - start);
    }
  }
  for (std::size_t i = 0; i < np; ++i) nrow[i + 1] += nrow[i];
  std::vector<std::int32_t> nnbr(static_cast<std::size_t>(nrow[np]));
#pragma omp parallel for num_threads(p.threads) schedule(static, 1)
  for (std::int64_t ch = 0; ch < chunks; ++ch) {
    const auto& buf = found[static_cast<std::size_t>(ch)];
    std::copy(buf.begin(), buf.end(), nnbr.begin() + nrow[sn * ch / chunks]);
  }
  candidate_row.swap(nrow);
  candidate_partner.swap(nnbr);
  build_disp = 0.0;
  build_pair_disp = 0.0;
}

void NeighbourList::refilter(const ListParticles& p, PairSlots& slots,
                             const CarriedHistory& carried) {
  const auto np = static_cast<std::size_t>(p.n);
  const std::int64_t sn = p.n;
  const phys::PeriodicBox& pbox = p.box;
  const bool friction = carried.friction, rolling = carried.rolling, poly = carried.poly;
  ++refilters;
  const double* P[3] = {p.x, p.y, p.z};
  const double* R = p.radius;
  std::vector<std::int64_t> nrow(np + 1, 0);
  auto keep = [&](std::int64_t i, std::int32_t j) {
    double dx = P[0][j] - P[0][i], dy = P[1][j] - P[1][i], dz = P[2][j] - P[2][i];
    if (p.periodic) {  // j at its image nearest to i
      dx += phys::image_shift(pbox, 0, dx);
      dy += phys::image_shift(pbox, 1, dy);
      dz += phys::image_shift(pbox, 2, dz);
    }
    const double cut = R[i] + R[j] + inner_skin;
    return dx * dx + dy * dy + dz * dz < cut * cut;
  };
#pragma omp parallel for num_threads(p.threads) schedule(static)
  for (std::int64_t i = 0; i < sn; ++i) {
    std::int64_t c = 0;
    for (std::int64_t k = candidate_row[i]; k < candidate_row[i + 1]; ++k)
      c += keep(i, candidate_partner[k]) ? 1 : 0;
    nrow[i + 1] = c;
  }
  for (std::size_t i = 0; i < np; ++i) nrow[i + 1] += nrow[i];
  std::vector<std::int32_t> nnbr(static_cast<std::size_t>(nrow[np]));
#pragma omp parallel for num_threads(p.threads) schedule(static)
  for (std::int64_t i = 0; i < sn; ++i) {
    std::int64_t c = nrow[i];
    for (std::int64_t k = candidate_row[i]; k < candidate_row[i + 1]; ++k)
      if (keep(i, candidate_partner[k])) nnbr[c++] = candidate_partner[k];
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
    const bool carry_axis = poly && slots.separating_axis.size() == 3 * partner.size() &&
                            slots.closest_features.size() == 6 * partner.size();
#pragma omp parallel for num_threads(p.threads) schedule(static)
    for (std::int64_t i = 0; i < sn; ++i) {
      std::int64_t a = row[i], b = nrow[i];
      while (a < row[i + 1] && b < nrow[i + 1]) {
        if (partner[a] < nnbr[b]) {
          ++a;
        } else if (partner[a] > nnbr[b]) {
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
  partner.swap(nnbr);
  slots.shear.swap(nshear);
  slots.rolling_history.swap(nrhist);
  slots.separating_axis.swap(naxis);
  slots.closest_features.swap(nfeat);
  update_x.resize(np), update_y.resize(np), update_z.resize(np);
#pragma omp parallel for num_threads(p.threads) schedule(static)
  for (std::int64_t i = 0; i < sn; ++i)
    update_x[i] = P[0][i], update_y[i] = P[1][i], update_z[i] = P[2][i];
}

void NeighbourList::index(std::size_t np, int threads) {
  const std::size_t npair = partner.size();
  const std::int64_t sn = static_cast<std::int64_t>(np);
  owner.resize(npair);
#pragma omp parallel for num_threads(threads) schedule(static)
  for (std::int64_t i = 0; i < sn; ++i)
    std::fill(owner.begin() + row[i], owner.begin() + row[i + 1], static_cast<std::int32_t>(i));
  // transposed index: for each j the pairs (i, j), i ascending (counting sort is stable)
  transposed_row.assign(np + 1, 0);
  for (std::size_t p = 0; p < npair; ++p) ++transposed_row[partner[p] + 1];
  for (std::size_t i = 0; i < np; ++i) transposed_row[i + 1] += transposed_row[i];
  transposed_pair.resize(npair);
  transposed_owner.resize(npair);
  {
    std::vector<std::int64_t> fill(transposed_row.begin(), transposed_row.end() - 1);
    for (std::size_t i = 0; i < np; ++i)
      for (std::int64_t p = row[i]; p < row[i + 1]; ++p) {
        const std::int64_t k = fill[partner[p]]++;
        transposed_pair[k] = p;
        transposed_owner[k] = static_cast<std::int32_t>(i);
      }
  }
  // the gather's list: per particle its own row's pairs (sign +1), then its transposed
  // pairs (sign -1), in the order of the two loops it replaces
  // (row and transposed_row are prefix sums, so particle i's entries start at row[i] +
  // transposed_row[i])
  gather_row.resize(np + 1);
  gather_pair.resize(2 * npair);
  gather_sign.resize(2 * npair);
#pragma omp parallel for num_threads(threads) schedule(static)
  for (std::int64_t i = 0; i <= sn; ++i) gather_row[i] = row[i] + transposed_row[i];
#pragma omp parallel for num_threads(threads) schedule(static)
  for (std::int64_t i = 0; i < sn; ++i) {
    std::int64_t g = gather_row[i];
    for (std::int64_t p = row[i]; p < row[i + 1]; ++p) gather_pair[g] = p, gather_sign[g++] = 1.0;
    for (std::int64_t k = transposed_row[i]; k < transposed_row[i + 1]; ++k)
      gather_pair[g] = transposed_pair[k], gather_sign[g++] = -1.0;
  }
}

double NeighbourList::two_largest_displacements(const ListParticles& p) {
  const std::int64_t sn = p.n;
  const int T = p.threads;
  top_two_.assign(static_cast<std::size_t>(T), {0.0, 0.0});
#pragma omp parallel num_threads(T)
  {
    double a = 0.0, b = 0.0;  // a >= b, squared
#pragma omp for schedule(static)
    for (std::int64_t i = 0; i < sn; ++i) {
      const double dx = p.x[i] - update_x[i], dy = p.y[i] - update_y[i], dz = p.z[i] - update_z[i];
      const double d2 = dx * dx + dy * dy + dz * dz;
      if (d2 > a) {
        b = a;
        a = d2;
      } else if (d2 > b) {
        b = d2;
      }
    }
    top_two_[static_cast<std::size_t>(omp_get_thread_num())] = {a, b};
  }
  double a = 0.0, b = 0.0;
  for (const auto& [ta, tb] : top_two_) {
    b = std::max(b, std::min(a, ta));
    a = std::max(a, ta);
    b = std::max(b, tb);
  }
  return std::sqrt(a) + std::sqrt(b);
}

}  // namespace demfem::dem::detail
