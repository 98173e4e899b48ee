#pragma once
// Particle output: one HDF5 file per output time (written to "<name>.part" and renamed, so a
// file is whole or absent) and an XDMF 3 index (a temporal collection of grids) rewritten
// atomically after each output, so a crash leaves a valid index that ParaView opens with its
// default (Xdmf3) reader. Each sphere is a vertex cell (an explicit Polyvertex connectivity:
// ParaView builds no cells from a Polyvertex without one), so the particles show as points
// at once; a Glyph filter scaled by "radius" draws them as spheres.

#include <cstdint>
#include <filesystem>
#include <iosfwd>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include "demfem/dem/dem_system.hpp"

namespace demfem::dem {

/// @brief Writes particle snapshots: <dir>/<stem>_NNNNNN.h5 (NNNNNN = 0 for the first, the
/// initial state) with datasets position (n x 3), velocity (n x 3), angular_velocity (n x 3),
/// radius (n), mass (n), material (n, int64), id (n, int64), vertex (n, int64: 0 .. n-1, the
/// Polyvertex connectivity) and file attributes time (s, the nominal output time),
/// state_time (s, the time of the state written; see io::OutputSchedule) and count; index
/// <dir>/<stem>.xdmf.
class ParticleOutput {
 public:
  ParticleOutput(std::filesystem::path dir, std::string stem = "particles");

  /// Writes one snapshot labelled `time`, of the state at `state_time` (NaN: = time); `ids`
  /// has one stable id per particle.
  void write(const ParticleState& particles, std::span<const std::int64_t> ids, double time,
             double state_time = std::numeric_limits<double>::quiet_NaN());
  /// Snapshots written (or kept) so far.
  std::size_t count() const { return entries_.size(); }
  /// Time (label) of the last snapshot (-infinity before the first).
  double last_time() const { return entries_.empty() ? -1e300 : entries_.back().time; }
  /// After a restore: keeps the first `keep` snapshots (re-reading their times from the
  /// files), forgets later ones, rewrites the index.
  void resume(std::size_t keep);
  std::filesystem::path index_path() const;
  std::filesystem::path snapshot_path(std::size_t k) const;

 private:
  struct Entry {
    double time;
    std::size_t count;
  };
  void write_index() const;
  /// One <Grid> of spheres (vertex cells) of snapshot k: the place where another particle
  /// kind (polyhedra) adds its own grid function, the snapshot then becoming a spatial
  /// collection of the kinds' grids, as FemOutput does for mixed element types.
  void write_sphere_grid(std::ostream& x, std::size_t k, const std::string& indent) const;
  std::filesystem::path dir_;
  std::string stem_;
  std::vector<Entry> entries_;
};

}  // namespace demfem::dem
