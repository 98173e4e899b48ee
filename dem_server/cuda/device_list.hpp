#pragma once
// The CUDA backend's neighbour list, built on the device: a cell grid by sorting (a cell key
// per particle, a stable sort by key, cell starts by a binary search), the pairs i < j within
// r_i + r_j + skin in each row ascending, their transpose, the pair histories carried over from
// the list it replaces (old and new pairs matched by a sorted key and a binary search), and each
// particle's candidate wall triangles (the triangles binned into the same grid). The list and
// its order equal the CPU build's (neighbour_list.cpp, one level): both call the same grid and
// candidate functions (physics/grid_cell.hpp, physics/triangle_bins.hpp). A periodic system's
// grid spans its periods and the candidates are taken at their nearest images, as on the CPU.
//
// Written with Thrust, so that the same sort, scan and search calls compile for CUDA (nvcc)
// and, in the host emulation of the backend (tests/dem/cuda_emu), for Thrust's CPP backend.
// This header holds no Thrust type: dem_cuda.cu includes it.

#include <cstddef>
#include <cstdint>
#include <memory>

#include "demfem/dem/physics/periodic_image.hpp"

namespace demfem::dem {

/// What a build reads (device pointers) and the list it replaces.
struct DeviceListInput {
  std::size_t n = 0;
  const double *px = nullptr, *py = nullptr, *pz = nullptr, *radius = nullptr;
  double rmax = 0.0;  ///< largest radius, m
  double skin = 0.0;  ///< m
  phys::PeriodicBox box;  ///< the periods (none: period 0 in every direction)
  bool periodic = false;  ///< some direction is periodic
  // the list being replaced: rows (n + 1) and partners; its histories are carried
  std::size_t old_npairs = 0;
  const std::int64_t* old_row = nullptr;
  const std::int32_t* old_nbr = nullptr;
  // walls: vertex positions (3 per vertex) and triangles (3 vertex indices each)
  std::size_t ntris = 0;
  const double* vpos = nullptr;
  const std::int32_t* tri_v = nullptr;
};

/// A per-pair history carried across a build: `width` values per pair, `fill` for a new pair.
/// The device array is read from (old list) and written to (new list) in place.
struct PairHistory {
  double* values = nullptr;
  int width = 3;
  double fill = 0.0;
};
struct PairHistoryInt {
  std::int32_t* values = nullptr;
  int width = 6;
  std::int32_t fill = -1;
};

/// Where a build writes (device pointers sized by the caller from count()).
struct DeviceListOutput {
  std::int64_t *row = nullptr, *trow = nullptr, *tpair = nullptr;  // n + 1, n + 1, pairs
  std::int32_t* nbr = nullptr;                                     // pairs
  double *bx = nullptr, *by = nullptr, *bz = nullptr;              // build positions, n
  std::int64_t* prow = nullptr;                                    // n + 1 (walls)
  std::int32_t* ptri = nullptr;                                    // candidates (walls)
  PairHistory hist[3];  // shear, rolling history, separating axis (values null: none)
  PairHistoryInt feat;  // closest features of polyhedra (values null: none)
};

/// Pair and triangle-candidate counts of a build.
struct DeviceListCounts {
  std::size_t npairs = 0, nptri = 0;
};

/// @brief The device's list builder; holds its work arrays from one build to the next.
class DeviceNeighbourList {
 public:
  DeviceNeighbourList();
  ~DeviceNeighbourList();
  DeviceNeighbourList(const DeviceNeighbourList&) = delete;
  DeviceNeighbourList& operator=(const DeviceNeighbourList&) = delete;

  /// First half of a build: the keys of the old list's pairs (in.old_*), the grid (the host
  /// reads the particles' bounding box, 48 bytes), the cell sort, the rows and the wall
  /// candidates counted. Returns the counts (read from the device: the build's only other
  /// synchronisation). The caller may then resize the list's arrays (the old rows and
  /// partners are no longer read; the histories must keep their old values).
  DeviceListCounts count(const DeviceListInput& in);
  /// Second half: the pairs, their transpose and build positions, the histories carried from
  /// the old list (out.hist[*].values hold the old pairs' values on entry, the new ones on
  /// return; sized for both), the wall candidates. `out` arrays are sized from count().
  void fill(const DeviceListInput& in, const DeviceListOutput& out);

 private:
  struct Work;
  std::unique_ptr<Work> w_;
};

}  // namespace demfem::dem
