// The CUDA backend's neighbour list built on the device (device_list.hpp): Thrust calls over
// functors that call the shared grid and candidate functions, so that the CPU build
// (neighbour_list.cpp) and this one cannot drift apart. Every step is a sort, a scan, a
// binary search or a map over particles, pairs or triangles; the orders that matter (the
// particles of a cell, the partners of a row, the triangles of a cell, the pairs of a
// transposed row) come from stable sorts and per-row sorts, so the list is the CPU's, pair for
// pair and in the same order, and the step that reads it sums in the CPU's order.

#include "device_list.hpp"

#include <thrust/binary_search.h>
#include <thrust/copy.h>
#include <thrust/device_vector.h>
#include <thrust/execution_policy.h>
#include <thrust/fill.h>
#include <thrust/for_each.h>
#include <thrust/gather.h>
#include <thrust/iterator/counting_iterator.h>
#include <thrust/scan.h>
#include <thrust/sequence.h>
#include <thrust/sort.h>
#include <thrust/transform.h>
#include <thrust/transform_reduce.h>

#include "demfem/dem/physics/grid_cell.hpp"
#include "demfem/dem/physics/triangle_bins.hpp"

namespace demfem::dem {

namespace {

using I64 = std::int64_t;
using I32 = std::int32_t;
template <class T>
using DVec = thrust::device_vector<T>;

template <class T>
T* raw(DVec<T>& v) {
  return thrust::raw_pointer_cast(v.data());
}
thrust::counting_iterator<I64> count_from(I64 k) {
  return thrust::counting_iterator<I64>(k);
}

// The particles' bounding box, as the CPU forms it (min and max in the operand order of
// std::min and std::max).
struct Box {
  double lo[3], hi[3];
};
struct BoxOfParticle {
  const double *px, *py, *pz;
  DEMFEM_HD Box operator()(I64 i) const {
    return Box{{px[i], py[i], pz[i]}, {px[i], py[i], pz[i]}};
  }
};
struct JoinBoxes {
  DEMFEM_HD Box operator()(const Box& a, const Box& b) const {
    Box r;
    for (int d = 0; d < 3; ++d) {
      r.lo[d] = b.lo[d] < a.lo[d] ? b.lo[d] : a.lo[d];
      r.hi[d] = a.hi[d] < b.hi[d] ? b.hi[d] : a.hi[d];
    }
    return r;
  }
};

struct CellOfParticle {
  phys::CellGrid g;
  const double *px, *py, *pz;
  DEMFEM_HD I64 operator()(I64 i) const { return g.cell(px[i], py[i], pz[i]); }
};

// The candidate partners of particle i, in a periodic grid at their nearest images (the
// CPU build's two scans).
struct PartnerScan {
  phys::CellGrid g;
  phys::CellOrder o;
  const double *px, *py, *pz, *r;
  double skin;
  phys::PeriodicBox box;
  bool periodic;
  template <class Emit>
  DEMFEM_HD void operator()(I64 i, Emit&& emit) const {
    if (periodic)
      phys::for_each_periodic_candidate(g, o, box, i, px[i], py[i], pz[i], r[i], skin, emit);
    else
      phys::for_each_candidate(g, o, i, px[i], py[i], pz[i], r[i], skin, emit);
  }
};

struct CountPartners {
  PartnerScan scan;
  DEMFEM_HD I64 operator()(I64 i) const {
    I64 c = 0;
    scan(i, [&](I32) { ++c; });
    return c;
  }
};

// Writes the partners of row i and sorts them (insertion sort: rows hold a few tens; the
// periodic scan emits them out of order, as on the CPU, which sorts each row too).
struct FillPartners {
  PartnerScan scan;
  const I64* row;
  I32* nbr;
  DEMFEM_HD void operator()(I64 i) const {
    I32* out = nbr + row[i];
    I64 c = 0;
    scan(i, [&](I32 j) { out[c++] = j; });
    for (I64 a = 1; a < c; ++a) {
      const I32 v = out[a];
      I64 b = a;
      for (; b > 0 && out[b - 1] > v; --b) out[b] = out[b - 1];
      out[b] = v;
    }
  }
};

// Key of a pair: owner * n + partner, ascending in list order.
struct PairKey {
  const I32* nbr;
  I64 n;
  DEMFEM_HD I64 operator()(I64 owner, I64 p) const { return owner * n + nbr[p]; }
};

// A history of the new pair q: the old pair's values where the key is found, else the fill.
template <class T>
struct CarryHistory {
  const I64 *old_keys, *new_keys, *pos;
  I64 old_n;
  const T* old_values;
  T* new_values;
  int width;
  T fill;
  DEMFEM_HD void operator()(I64 q) const {
    const I64 p = pos[q];
    const bool found = p < old_n && old_keys[p] == new_keys[q];
    for (int c = 0; c < width; ++c)
      new_values[width * q + c] = found ? old_values[width * p + c] : fill;
  }
};

// Walls: the cell box of each triangle and its number of cells (0: outside the grid).
struct BoxTriangle {
  phys::CellGrid g;
  const double* vpos;
  const I32* tri_v;
  double grow;
  I64* box;
  DEMFEM_HD I64 operator()(I64 k) const {
    I64* b = box + 6 * k;
    if (!phys::triangle_cell_box(g, vpos, tri_v + 3 * k, grow, b)) return 0;
    return phys::box_cells(b);
  }
};
// The (cell, triangle) entries of triangle k, cells in the CPU's order (z, y, x).
struct BinTriangle {
  phys::CellGrid g;
  const I64 *box, *offset, *ncells;
  I64* cell;
  I32* tri;
  DEMFEM_HD void operator()(I64 k) const {
    if (ncells[k] == 0) return;
    const I64* b = box + 6 * k;
    I64 e = offset[k];
    for (I64 z = b[2]; z <= b[5]; ++z)
      for (I64 y = b[1]; y <= b[4]; ++y)
        for (I64 x = b[0]; x <= b[3]; ++x) {
          cell[e] = (z * g.dim[1] + y) * g.dim[0] + x;
          tri[e++] = static_cast<I32>(k);
        }
  }
};
// The candidate triangles of particle i (those of its cell near it): counted, or written
// from out + row[i] when out is set.
struct NearTriangles {
  const I64 *pcell, *tstart;
  const I32 *tbin, *tri_v;
  const double *px, *py, *pz, *r, *vpos;
  double skin;
  const I64* row;
  I32* out;
  DEMFEM_HD I64 operator()(I64 i) const {
    const I64 c = pcell[i];
    I64 m = 0;
    const phys::Vec3 p{px[i], py[i], pz[i]};
    for (I64 k = tstart[c]; k < tstart[c + 1]; ++k)
      if (phys::near_triangle(p, r[i], skin, vpos, tri_v + 3 * tbin[k])) {
        if (out) out[row[i] + m] = tbin[k];
        ++m;
      }
    return m;
  }
};

}  // namespace

struct DeviceNeighbourList::Work {
  phys::CellGrid grid{};
  I64 n = 0, old_np = 0, np = 0, nptri = 0, ncell = 0;
  DVec<I64> cell, skey, cstart, row, owner, old_keys, keys, pos, tkey, prow, tstart, tcell;
  DVec<I64> tbox, tcount, toff;
  DVec<I32> sorted, nbr, tbin, ibuf;
  DVec<double> sx, sy, sz, sr, dbuf;
};

namespace {
PartnerScan partner_scan(const phys::CellGrid& g, const phys::CellOrder& order,
                         const DeviceListInput& in) {
  return PartnerScan{g, order, in.px, in.py, in.pz, in.radius, in.skin, in.box, in.periodic};
}
}  // namespace

DeviceNeighbourList::DeviceNeighbourList() : w_(std::make_unique<Work>()) {}
DeviceNeighbourList::~DeviceNeighbourList() = default;

DeviceListCounts DeviceNeighbourList::count(const DeviceListInput& in) {
  Work& w = *w_;
  const auto pol = thrust::device;
  const I64 n = static_cast<I64>(in.n);
  w.n = n;
  // the old list's keys, before the caller may reuse its arrays
  w.old_np = in.old_row != nullptr ? static_cast<I64>(in.old_npairs) : 0;
  w.old_keys.resize(static_cast<std::size_t>(w.old_np));
  if (w.old_np > 0) {
    w.owner.resize(static_cast<std::size_t>(w.old_np));
    thrust::upper_bound(pol, in.old_row + 1, in.old_row + n + 1, count_from(0),
                        count_from(w.old_np), w.owner.begin());
    thrust::transform(pol, w.owner.begin(), w.owner.end(), count_from(0), w.old_keys.begin(),
                      PairKey{in.old_nbr, n});
  }
  // the grid over the particles' box (the host forms it, as the CPU build does)
  Box box{{1e300, 1e300, 1e300}, {-1e300, -1e300, -1e300}};
  if (n > 0)
    box = thrust::transform_reduce(pol, count_from(0), count_from(n),
                                   BoxOfParticle{in.px, in.py, in.pz}, box, JoinBoxes{});
  else
    for (int d = 0; d < 3; ++d) box.lo[d] = box.hi[d] = 0.0;
  // a periodic direction's grid spans its period (the positions lie in [lo, lo + L))
  for (int d = 0; d < 3; ++d)
    if (in.box.period[d] > 0.0)
      box.lo[d] = in.box.lo[d], box.hi[d] = in.box.lo[d] + in.box.period[d];
  w.grid = phys::cell_grid(box.lo, box.hi, n, in.rmax, in.skin, in.box.period);
  w.ncell = w.grid.cells();
  // particles in cell order: a stable sort keeps them in index order within a cell
  const std::size_t un = in.n;
  w.cell.resize(un), w.skey.resize(un), w.sorted.resize(un);
  thrust::transform(pol, count_from(0), count_from(n), w.cell.begin(),
                    CellOfParticle{w.grid, in.px, in.py, in.pz});
  thrust::copy(pol, w.cell.begin(), w.cell.end(), w.skey.begin());
  thrust::sequence(pol, w.sorted.begin(), w.sorted.end());
  thrust::stable_sort_by_key(pol, w.skey.begin(), w.skey.end(), w.sorted.begin());
  w.cstart.resize(static_cast<std::size_t>(w.ncell + 1));
  thrust::lower_bound(pol, w.skey.begin(), w.skey.end(), count_from(0), count_from(w.ncell + 1),
                      w.cstart.begin());
  w.sx.resize(un), w.sy.resize(un), w.sz.resize(un), w.sr.resize(un);
  thrust::gather(pol, w.sorted.begin(), w.sorted.end(), in.px, w.sx.begin());
  thrust::gather(pol, w.sorted.begin(), w.sorted.end(), in.py, w.sy.begin());
  thrust::gather(pol, w.sorted.begin(), w.sorted.end(), in.pz, w.sz.begin());
  thrust::gather(pol, w.sorted.begin(), w.sorted.end(), in.radius, w.sr.begin());
  const phys::CellOrder order{raw(w.cstart), raw(w.sorted), raw(w.sx),
                              raw(w.sy),     raw(w.sz),     raw(w.sr)};
  // rows: partners counted per particle, then a prefix sum
  w.row.assign(un + 1, 0);
  thrust::transform(pol, count_from(0), count_from(n), w.row.begin() + 1,
                    CountPartners{partner_scan(w.grid, order, in)});
  thrust::inclusive_scan(pol, w.row.begin() + 1, w.row.end(), w.row.begin() + 1);
  w.np = w.row[un];  // a read of the device
  // walls: each triangle's cells, its (cell, triangle) entries sorted by cell (stable: the
  // triangles of a cell ascending), each particle's candidates in its own cell
  w.nptri = 0;
  w.prow.assign(un + 1, 0);
  const I64 ntri = static_cast<I64>(in.ntris);
  if (ntri > 0 && n > 0) {
    w.tbox.resize(static_cast<std::size_t>(6 * ntri));
    w.tcount.resize(static_cast<std::size_t>(ntri));
    w.toff.resize(static_cast<std::size_t>(ntri));
    thrust::transform(pol, count_from(0), count_from(ntri), w.tcount.begin(),
                      BoxTriangle{w.grid, in.vpos, in.tri_v, in.rmax + in.skin, raw(w.tbox)});
    thrust::exclusive_scan(pol, w.tcount.begin(), w.tcount.end(), w.toff.begin());
    const I64 entries = w.toff[ntri - 1] + w.tcount[ntri - 1];
    w.tcell.resize(static_cast<std::size_t>(entries));
    w.tbin.resize(static_cast<std::size_t>(entries));
    thrust::for_each(
        pol, count_from(0), count_from(ntri),
        BinTriangle{w.grid, raw(w.tbox), raw(w.toff), raw(w.tcount), raw(w.tcell), raw(w.tbin)});
    thrust::stable_sort_by_key(pol, w.tcell.begin(), w.tcell.end(), w.tbin.begin());
    w.tstart.resize(static_cast<std::size_t>(w.ncell + 1));
    thrust::lower_bound(pol, w.tcell.begin(), w.tcell.end(), count_from(0), count_from(w.ncell + 1),
                        w.tstart.begin());
    thrust::transform(pol, count_from(0), count_from(n), w.prow.begin() + 1,
                      NearTriangles{raw(w.cell), raw(w.tstart), raw(w.tbin), in.tri_v, in.px, in.py,
                                    in.pz, in.radius, in.vpos, in.skin, nullptr, nullptr});
    thrust::inclusive_scan(pol, w.prow.begin() + 1, w.prow.end(), w.prow.begin() + 1);
    w.nptri = w.prow[un];  // a read of the device
  }
  return DeviceListCounts{static_cast<std::size_t>(w.np), static_cast<std::size_t>(w.nptri)};
}

void DeviceNeighbourList::fill(const DeviceListInput& in, const DeviceListOutput& out) {
  Work& w = *w_;
  const auto pol = thrust::device;
  const I64 n = w.n, np = w.np;
  const std::size_t un = static_cast<std::size_t>(n), unp = static_cast<std::size_t>(np);
  const phys::CellOrder order{raw(w.cstart), raw(w.sorted), raw(w.sx),
                              raw(w.sy),     raw(w.sz),     raw(w.sr)};
  thrust::copy(pol, w.row.begin(), w.row.end(), out.row);
  thrust::for_each(
      pol, count_from(0), count_from(n),
      FillPartners{partner_scan(w.grid, order, in), out.row, out.nbr});
  // histories: each new pair's key looked up among the old keys (both ascending)
  w.owner.resize(unp), w.keys.resize(unp), w.pos.resize(unp);
  thrust::upper_bound(pol, out.row + 1, out.row + n + 1, count_from(0), count_from(np),
                      w.owner.begin());
  thrust::transform(pol, w.owner.begin(), w.owner.end(), count_from(0), w.keys.begin(),
                    PairKey{out.nbr, n});
  thrust::lower_bound(pol, w.old_keys.begin(), w.old_keys.end(), w.keys.begin(), w.keys.end(),
                      w.pos.begin());
  for (const PairHistory& h : out.hist) {
    if (h.values == nullptr) continue;
    w.dbuf.resize(unp * static_cast<std::size_t>(h.width));
    thrust::for_each(pol, count_from(0), count_from(np),
                     CarryHistory<double>{raw(w.old_keys), raw(w.keys), raw(w.pos), w.old_np,
                                          h.values, raw(w.dbuf), h.width, h.fill});
    thrust::copy(pol, w.dbuf.begin(), w.dbuf.end(), h.values);
  }
  if (out.feat.values != nullptr) {
    w.ibuf.resize(unp * static_cast<std::size_t>(out.feat.width));
    thrust::for_each(
        pol, count_from(0), count_from(np),
        CarryHistory<I32>{raw(w.old_keys), raw(w.keys), raw(w.pos), w.old_np, out.feat.values,
                          raw(w.ibuf), out.feat.width, out.feat.fill});
    thrust::copy(pol, w.ibuf.begin(), w.ibuf.end(), out.feat.values);
  }
  // the transpose: pairs by partner, owners ascending within (stable)
  w.tkey.resize(unp);
  thrust::copy(pol, out.nbr, out.nbr + np, w.tkey.begin());
  thrust::sequence(pol, out.tpair, out.tpair + np);
  thrust::stable_sort_by_key(pol, w.tkey.begin(), w.tkey.end(), out.tpair);
  thrust::lower_bound(pol, w.tkey.begin(), w.tkey.end(), count_from(0), count_from(n + 1),
                      out.trow);
  thrust::copy(pol, in.px, in.px + n, out.bx);
  thrust::copy(pol, in.py, in.py + n, out.by);
  thrust::copy(pol, in.pz, in.pz + n, out.bz);
  if (out.prow != nullptr) {
    thrust::copy(pol, w.prow.begin(), w.prow.end(), out.prow);
    if (w.nptri > 0)
      thrust::for_each(
          pol, count_from(0), count_from(n),
          NearTriangles{raw(w.cell), raw(w.tstart), raw(w.tbin), in.tri_v, in.px, in.py, in.pz,
                        in.radius, in.vpos, in.skin, out.prow, out.ptri});
  }
  (void)un;
}

}  // namespace demfem::dem
