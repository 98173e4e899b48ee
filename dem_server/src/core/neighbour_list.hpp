#pragma once
// The CPU backend's neighbour list (DemSystem::Impl::list): the pairs (i, j > i) that may
// touch, as CSR rows, with the indices the force pass walks (the owner of each pair, the
// transpose, the gather list), the positions the list was last updated at, and the rule of
// when it is refiltered or rebuilt.
//
// Two levels: a build from the cell grid keeps the candidate pairs within r_i + r_j + skin
// (candidate_row, candidate_partner: same layout as row, partner); the list proper holds
// those within r_i + r_j + inner_skin and is refiltered from them when some particle has moved
// inner_skin / 2. A settled bed's particles jitter, so a list with a thin skin would need a
// grid build every few tens of steps; the refilter is a pass over the candidates.
//
// The wall triangles near each particle are binned into the build's grid by the wall store
// (wall_store.hpp), which reads `grid` and `cell`. The CUDA backend builds its list on the
// device (cuda/device_list.hpp) and hands it back (DemSystem::Impl::adopt_device_list).

#include <array>
#include <cstdint>
#include <vector>

#include "demfem/dem/physics/grid_cell.hpp"
#include "demfem/dem/physics/periodic_image.hpp"
#include "pair_slots.hpp"

namespace demfem::dem::detail {

// The particles as the list reads them: positions and bounding radii (m), n of them, the
// periods (all zero unless `periodic`) and the threads of its loops.
struct ListParticles {
  const double* x;
  const double* y;
  const double* z;
  const double* radius;
  std::int64_t n;
  const phys::PeriodicBox& box;
  bool periodic;
  int threads;
};

// Which histories of the pair slots the refilter carries from the old list to the new.
struct CarriedHistory {
  bool friction;  // tangential springs (and with `rolling` the rolling-torque history)
  bool rolling;
  bool poly;  // the narrow phase's caches
};

class NeighbourList {
 public:
  // Skin of the list proper as a fraction of the build skin, and its range when it adapts.
  // On the settled 20,000-sphere bed (dem_throughput) 0.1 keeps 2.6 list pairs per particle
  // (the whole skin: 3.6) and refilters every ~25 steps: +15 % particle-steps per second
  // (best of 8 runs; 0.05: 2.5 pairs, no further gain). In a fast flow a thin skin would
  // refilter every step or two, so the skin grows there (adapt_inner_skin()).
  static constexpr double kInnerSkin = 0.1, kInnerSkinMax = 0.5;

  // ---- the list proper: CSR rows of pairs (i, j > i), j ascending within a row
  std::vector<std::int64_t> row;      // n + 1: particle i's pairs are [row[i], row[i + 1])
  std::vector<std::int32_t> partner;  // j of each pair
  std::vector<std::int32_t> owner;    // i of each pair (the flat pair loop)
  // the transpose: for each j the pairs (i, j), i ascending
  std::vector<std::int64_t> transposed_row;    // n + 1
  std::vector<std::int64_t> transposed_pair;   // pair index of each entry
  std::vector<std::int32_t> transposed_owner;  // i of each entry
  // One loop per particle in the gather instead of two (own row, transposed): the exit of a
  // short loop of varying length is mispredicted about once per particle. Particle i's
  // entries start at row[i] + transposed_row[i].
  std::vector<std::int64_t> gather_row;   // n + 1
  std::vector<std::int64_t> gather_pair;  // pair of each entry
  std::vector<double> gather_sign;        // +1 own row (force on i), -1 transposed (force on j)
  // positions at the last update (build or refilter), m; empty: no list yet
  std::vector<double> update_x, update_y, update_z;

  // ---- the build's candidates and its grid
  std::vector<std::int64_t> candidate_row;      // n + 1
  std::vector<std::int32_t> candidate_partner;  // j of each candidate pair
  phys::CellGrid grid{};                        // the cell grid of the last build
  std::vector<std::int32_t> cell;               // each particle's cell in it

  // ---- the skins and the update rule
  double skin = 0.0;        // of the build, m (the candidates: r_i + r_j + skin)
  double inner_skin = 0.0;  // of the list proper, m
  double build_disp = 0.0;  // bound of the largest displacement since the build, refilters summed
  double build_pair_disp = 0.0;  // bound of d_i + d_j of any pair since the build, refilters summed
  bool must_build = true;        // the candidates are stale (particles or walls changed, a restore)
  std::int64_t builds = 0;
  std::int64_t refilters = 0;
  std::int64_t steps_at_update = -1;  // step of the last build or refilter

  std::size_t pairs() const { return partner.size(); }
  bool has_update_positions(std::size_t n) const { return update_x.size() == n; }

  // The candidate pairs within r_i + r_j + skin from a uniform grid by counting sort (cells
  // of at least 2 rmax + skin; a periodic direction's grid spans its period). Leaves the grid
  // and each particle's cell for the wall binning; resets the build's displacement bounds.
  void build(const ListParticles& p, double rmax);

  // The list proper: the candidates closer than r_i + r_j + inner_skin now. The histories
  // of the pair slots are carried over from the previous list (merge of sorted rows); the
  // indices (owner, transpose, gather) are left to index().
  void refilter(const ListParticles& p, PairSlots& slots, const CarriedHistory& carried);

  // The indices derived from the rows (row, partner): the owner of each pair, the transpose,
  // the gather list.
  void index(std::size_t n, int threads);

  // The list's inner skin adapts at each list update (build or refilter) to the steps since
  // the previous one, u:
  //  * u < 10 (a flow): inner_skin grows by 1.5; beyond kInnerSkinMax x skin the list goes to
  //    one level (inner_skin = skin). In a flow the build budget skin - inner_skin (for
  //    d_i + d_j), checked against the summed refilter intervals, runs out about twice as
  //    fast as the whole skin (measured with the rule of twice the largest displacement: 96
  //    builds and 31 refilters against 53 builds in 1500 steps of 4096 falling spheres, 10 %
  //    slower). A refilter that may not grow the skin (the build budget) asks for a build;
  //  * u > 40 (a settled bed): inner_skin shrinks by 1.5, to kInnerSkin x skin at least;
  //  * one level: a build more than 100 steps after the last goes back to two levels.
  // `fixed`: the skin does not adapt (settings.list_skin, or the device's one level). It
  // depends on step counts only, and the list's non-touching pairs do not change the result,
  // so it keeps the bits. Returns false when a refilter must be a build instead.
  bool adapt_inner_skin(std::int64_t steps, bool fixed, bool build, double pbuild = 0.0);

  // What the step does with the list after the drift, by phys::ListRule: `disp` the largest
  // displacement since the last update (1e300: no update positions), `wall_disp` the walls'
  // since the build. A refilter's inner skin is adapted here (adapt_inner_skin).
  enum class Update { none, build, refilter };
  Update next_update(const ListParticles& p, double disp, double wall_disp, std::int64_t steps,
                     bool fixed);

  // Sum of the two largest displacements since the last update: bounds d_i + d_j of every
  // pair. Per-thread top two, combined in thread order (max is exact: any order gives the
  // same value).
  double two_largest_displacements(const ListParticles& p);

 private:
  std::vector<std::array<double, 2>> top_two_;  // per thread (member: no allocation per call)
};

}  // namespace demfem::dem::detail
