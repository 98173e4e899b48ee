#pragma once
// Particle output: one HDF5 file per output time (written to "<name>.part" and renamed, so a
// file is whole or absent) and an XDMF 3 index (Polyvertex topology in a temporal
// collection) rewritten atomically after each output, so a crash leaves a valid index that
// ParaView opens (draw the particles with a Glyph filter, scale by "radius").

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "demfem/dem/dem_system.hpp"

namespace demfem::dem {

/// @brief Writes particle snapshots: <dir>/<stem>_NNNNNN.h5 with datasets position (n x 3),
/// velocity (n x 3), angular_velocity (n x 3), radius (n), mass (n), material (n, int64),
/// id (n, int64) and file attributes time (s) and count; index <dir>/<stem>.xdmf.
class ParticleOutput {
 public:
  ParticleOutput(std::filesystem::path dir, std::string stem = "particles");

  /// Writes one snapshot at `time`; `ids` has one stable id per particle.
  void write(const ParticleState& particles, std::span<const std::int64_t> ids, double time);
  /// Snapshots written (or kept) so far.
  std::size_t count() const { return entries_.size(); }
  /// Time of the last snapshot (-infinity before the first).
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
  std::filesystem::path dir_;
  std::string stem_;
  std::vector<Entry> entries_;
};

}  // namespace demfem::dem
