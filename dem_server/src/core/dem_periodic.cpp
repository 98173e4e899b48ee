// DemSystem::Impl: periodic boundaries (docs/dem.md, "Periodic boundaries and tiled beds"):
// the wrap of the positions after each drift, the least period, and the tiling of a periodic
// block into a larger one with its contact history. The image of a pair is chosen in the
// pair kernels and the neighbour list by physics/periodic_image.hpp.

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <tuple>
#include <vector>

#include "dem_system_impl.hpp"

namespace demfem::dem {

using detail::bad;
using detail::kMaxWallContacts;

bool DemSystem::Impl::wrap_positions() {
  double* X[3] = {st.px.data(), st.py.data(), st.pz.data()};
  double* B[3] = {list.update_x.data(), list.update_y.data(), list.update_z.data()};
  const bool have_build = list.has_update_positions(n());
  const bool any_frozen = !frozen_idx.empty();
  const std::int64_t sn = static_cast<std::int64_t>(n());
  int wrapped = 0;
#pragma omp parallel for num_threads(nt()) schedule(static) reduction(max : wrapped)
  for (std::int64_t i = 0; i < sn; ++i) {
    if (any_frozen && frozen[i] != 0) continue;  // held where it is (hold_frozen)
    for (int d = 0; d < 3; ++d) {
      const int k = phys::wrap_coordinate(pbox, d, X[d][i], have_build ? B[d] + i : nullptr);
      if (k == 0) continue;
      image[3 * i + d] += k;
      wrapped = 1;
    }
  }
  return wrapped != 0;
}

void DemSystem::Impl::check_periods() const {
  const double least = least_period();
  for (int d = 0; d < 3; ++d) {
    if (!(pbox.period[d] > 0.0) || pbox.period[d] >= least) continue;
    bad(std::string("the period in ") + "xyz"[d] + ", " + std::to_string(pbox.period[d]) +
        " m, is shorter than twice the neighbour list's cutoff, 2 (2 r_max + skin) = " +
        std::to_string(least) + " m (r_max = " + std::to_string(rmax) +
        " m, the largest bounding radius; skin = " + std::to_string(list.skin) +
        " m): a pair would meet more than one image of the other. Use a period of at least " +
        std::to_string(least) + " m");
  }
}

std::span<const std::int32_t> DemSystem::images() const {
  return impl_->image;
}

double DemSystem::least_period() const {
  return impl_->least_period();
}

namespace {

// Index of copy c = (a, b, c) of particle i in a tiling of n particles, copies k.
std::int64_t copy_index(const std::array<int, 3>& k, const std::array<int, 3>& c, std::int64_t n,
                        std::int64_t i) {
  return i + n * (c[0] + k[0] * (c[1] + static_cast<std::int64_t>(k[1]) * c[2]));
}

}  // namespace

void DemSystem::tile(const PeriodicRange& block, const std::array<int, 3>& copies,
                     bool keep_velocities) {
  Impl& I = *impl_;
  if (I.gpu != nullptr) bad("tile: the CPU backend tiles a periodic block");
  phys::PeriodicBox bb;  // the block's periods
  for (int d = 0; d < 3; ++d) {
    const std::string dir(1, "xyz"[d]);
    if (copies[d] < 1) bad("tile: copies in " + dir + " = " + std::to_string(copies[d]) + " < 1");
    if (copies[d] > 1 && !block.on[d])
      bad("tile: " + std::to_string(copies[d]) + " copies in " + dir +
          ", in which the block is not periodic (only its periodic directions tile)");
    if (!block.on[d]) continue;
    bb.period[d] = block.period(d), bb.half[d] = 0.5 * bb.period[d], bb.lo[d] = block.lo[d];
    const double want = block.lo[d] + copies[d] * bb.period[d];
    const PeriodicRange& own = I.s.periodic;
    if (own.on[d] && (own.lo[d] != block.lo[d] ||
                      !(std::abs(own.hi[d] - want) <= 1e-12 * std::abs(want) + 1e-300)))
      bad("tile: this system is periodic in " + dir + " over [" + std::to_string(own.lo[d]) +
          ", " + std::to_string(own.hi[d]) + "] m, not over the tiled range [" +
          std::to_string(block.lo[d]) + ", " + std::to_string(want) + "] m");
  }
  const std::int64_t n = static_cast<std::int64_t>(I.n());
  const std::int64_t reps = std::int64_t{copies[0]} * copies[1] * copies[2];
  const std::int64_t total = n * reps;
  if (total > std::numeric_limits<std::int32_t>::max())
    bad("tile: " + std::to_string(total) + " particles are more than a system holds");
  for (int d = 0; d < 3; ++d)
    if (block.on[d] && bb.period[d] < I.least_period())
      bad(std::string("tile: the block's period in ") + "xyz"[d] + " is below least_period()");
  // The block's pairs: j met at image shift s (in periods) from i, with its history.
  struct Entry {
    std::int64_t i, j;
    std::int64_t p;  // block pair
    bool swapped;
  };
  std::vector<Entry> entries;
  const bool have_list = I.list.row.size() == I.n() + 1;
  const double* X[3] = {I.st.px.data(), I.st.py.data(), I.st.pz.data()};
  std::array<int, 3> c{};
  for (std::int64_t i = 0; have_list && i < n; ++i)
    for (std::int64_t p = I.list.row[i]; p < I.list.row[i + 1]; ++p) {
      const std::int64_t j = I.list.partner[p];
      int s[3];
      for (int d = 0; d < 3; ++d)
        s[d] = bb.period[d] > 0.0 ? static_cast<int>(std::lround(
                                        phys::image_shift(bb, d, X[d][j] - X[d][i]) / bb.period[d]))
                                  : 0;
      for (c[2] = 0; c[2] < copies[2]; ++c[2])
        for (c[1] = 0; c[1] < copies[1]; ++c[1])
          for (c[0] = 0; c[0] < copies[0]; ++c[0]) {
            std::array<int, 3> cj{};
            bool dropped = false;  // across the outer face of a tiled bed that is not periodic
            for (int d = 0; d < 3; ++d) {
              cj[d] = c[d] + s[d];
              if (cj[d] < 0 || cj[d] >= copies[d]) {
                dropped = dropped || !I.s.periodic.on[d];
                cj[d] = (cj[d] + copies[d]) % copies[d];
              }
            }
            if (dropped) continue;
            const std::int64_t a = copy_index(copies, c, n, i), b = copy_index(copies, cj, n, j);
            entries.push_back(a < b ? Entry{a, b, p, false} : Entry{b, a, p, true});
          }
    }
  std::sort(entries.begin(), entries.end(),
            [](const Entry& x, const Entry& y) { return std::tie(x.i, x.j) < std::tie(y.i, y.j); });
  // The copies' particles (copy 0 is the block itself, indices 0 .. n - 1).
  std::vector<ParticleInit> init(static_cast<std::size_t>(total - n));
  for (std::int64_t k = n; k < total; ++k) {
    const std::int64_t i = k % n, lin = k / n;
    const std::int64_t cc[3] = {lin % copies[0], (lin / copies[0]) % copies[1],
                                lin / (std::int64_t{copies[0]} * copies[1])};
    ParticleInit& q = init[static_cast<std::size_t>(k - n)];
    for (int d = 0; d < 3; ++d)
      q.position[d] = X[d][i] + static_cast<double>(cc[d]) * bb.period[d];
    q.radius = I.st.radius[i];
    q.material = I.st.material[i];
    q.shape = static_cast<ParticleShape>(I.st.shape[i]);
    q.shape_id = I.st.shape_id[i];
    q.scale = I.st.scale[i];
    q.orientation = {1, 0, 0, 0};  // the block's bits are copied below
  }
  // the block's list, kept apart: add_particles leaves the old rows in place
  std::vector<std::int32_t> bnbr = I.list.partner;
  detail::PairSlots bslots = I.slots;
  if (!init.empty()) add_particles(init);
  // each copy's state as the block's, bit for bit: orientation, velocities (or rest), the
  // last step's forces and torques (the first half kick uses them), wall contact slots
  ParticleState& S = I.st;
  const auto K = static_cast<std::size_t>(kMaxWallContacts);
  detail::WallContactSlots& wc = I.wall_contacts;
  for (std::int64_t k = n; k < total; ++k) {
    const std::int64_t i = k % n;
    S.qw[k] = S.qw[i], S.qx[k] = S.qx[i], S.qy[k] = S.qy[i], S.qz[k] = S.qz[i];
    S.fx[k] = S.fx[i], S.fy[k] = S.fy[i], S.fz[k] = S.fz[i];
    I.tx[k] = I.tx[i], I.ty[k] = I.ty[i], I.tz[k] = I.tz[i];
    S.vx[k] = S.vx[i], S.vy[k] = S.vy[i], S.vz[k] = S.vz[i];
    S.wx[k] = S.wx[i], S.wy[k] = S.wy[i], S.wz[k] = S.wz[i];
    wc.count[k] = wc.count[i];
    std::copy_n(wc.key.begin() + K * i, K, wc.key.begin() + K * k);
    std::copy_n(wc.shear.begin() + 3 * K * i, 3 * K, wc.shear.begin() + 3 * K * k);
    if (!wc.rolling_history.empty())
      std::copy_n(wc.rolling_history.begin() + 3 * K * i, 3 * K,
                  wc.rolling_history.begin() + 3 * K * k);
    if (!I.frozen.empty()) I.frozen[k] = I.frozen[i];
  }
  if (!keep_velocities)
    for (auto* v : {&S.vx, &S.vy, &S.vz, &S.wx, &S.wy, &S.wz}) std::fill(v->begin(), v->end(), 0.0);
  I.refresh_frozen();
  if (I.periodic) I.image.assign(3 * static_cast<std::size_t>(total), 0);
  // the tiled list: each entry under its smaller index; seen from the other body a pair's
  // spring, rolling history and axis change sign, and its closest-feature pairs swap
  const std::size_t np = entries.size();
  const std::size_t bn = bnbr.size();
  const bool shear = bslots.shear.size() == 3 * bn && bn > 0;
  const bool roll = bslots.rolling_history.size() == 3 * bn && bn > 0;
  const bool axis = bslots.separating_axis.size() == 3 * bn &&
                    bslots.closest_features.size() == 6 * bn && bn > 0;
  I.list.row.assign(static_cast<std::size_t>(total) + 1, 0);
  I.list.partner.resize(np);
  I.slots.shear.assign(shear ? 3 * np : 0, 0.0);
  I.slots.rolling_history.assign(roll ? 3 * np : 0, 0.0);
  I.slots.separating_axis.assign(axis ? 3 * np : 0, 0.0);
  I.slots.closest_features.assign(axis ? 6 * np : 0, -1);
  for (std::size_t q = 0; q < np; ++q) {
    const Entry& e = entries[q];
    ++I.list.row[e.i + 1];
    I.list.partner[q] = static_cast<std::int32_t>(e.j);
    const double sign = e.swapped ? -1.0 : 1.0;
    for (int d = 0; d < 3; ++d) {
      if (shear) I.slots.shear[3 * q + d] = sign * bslots.shear[3 * e.p + d];
      if (roll) I.slots.rolling_history[3 * q + d] = sign * bslots.rolling_history[3 * e.p + d];
      if (axis) I.slots.separating_axis[3 * q + d] = sign * bslots.separating_axis[3 * e.p + d];
    }
    if (axis)
      for (int k = 0; k < 6; ++k)
        I.slots.closest_features[6 * q + k] =
            bslots.closest_features[6 * e.p + (e.swapped ? k ^ 1 : k)];
  }
  for (std::int64_t k = 0; k < total; ++k) I.list.row[k + 1] += I.list.row[k];
  I.list.update_x.clear();
  I.list.must_build = true;  // the rebuild's refilter carries the history over (by pair)
}

}  // namespace demfem::dem
