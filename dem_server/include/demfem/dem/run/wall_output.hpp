#pragma once
// Wall output: the walls' triangle meshes where they are at each particle snapshot, so that
// ParaView shows the rig, the moving flaps and plates and the rigid bodies (pressure cells)
// together with the particles. Same file rules as ParticleOutput: one HDF5 file per output
// (<dir>/walls_NNNNNN.h5, written under a temporary name and renamed) and an XDMF 3 index
// (<dir>/walls.xdmf) rewritten atomically after each, a temporal collection whose every time
// is a spatial collection of one triangle grid per wall, named by the wall. ParaView's default
// reader (Xdmf3ReaderS) merges a spatial collection into unnamed pieces of one data set, so
// each wall also has its own index, <dir>/walls_<name>.xdmf (the name with characters other
// than letters, digits, '-', '_' and '.' replaced by '_'; a repeated name gets "_<w>"): opened
// beside the others, each wall is a source of its own, shown, hidden or coloured by name.
// Every triangle carries the cell field `wall` (the wall's index in the scene's order), so a
// Threshold picks walls out of walls.xdmf too.

#include <array>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <span>
#include <string>
#include <vector>

namespace demfem::dem {

class WallOutput {
 public:
  /// The fixed part of a wall: its name and triangles (3 vertex indices each).
  struct Wall {
    std::string name;
    std::vector<std::int32_t> triangles;
  };
  /// What a snapshot holds of one wall: its vertex positions now (3 per vertex, m), the
  /// particles' total force on it (N) and the force that a wall_force sensor of it reads (N:
  /// with `face`, that face's only, e.g. a pressure cell's top; else the total force).
  struct Pose {
    std::span<const double> vertices;
    std::array<double, 3> force{};
    std::array<double, 3> sensor_force{};
  };

  WallOutput(std::filesystem::path dir, std::vector<Wall> walls, std::string stem = "walls");

  /// Writes one snapshot labelled `time` of the state at `state_time` (NaN: = time); `poses`
  /// has one entry per wall, in the order of the constructor's. File k holds per wall w the
  /// group wall_<w> with datasets points (n x 3), triangles (t x 3, int64), force and
  /// sensor_force (t x 3: the wall's total force and its sensor's, repeated on each of its
  /// triangles so ParaView colours by them) and wall (t, int64: w), and the attribute name; on
  /// "/" the attributes time, state_time and walls.
  void write(std::span<const Pose> poses, double time,
             double state_time = std::numeric_limits<double>::quiet_NaN());
  std::size_t count() const { return entries_.size(); }
  /// After a restore: keeps the first `keep` snapshots (their times re-read from the files),
  /// forgets later ones, rewrites the index.
  void resume(std::size_t keep);
  std::filesystem::path index_path() const;
  /// The index of wall w alone (<dir>/<stem>_<name>.xdmf).
  std::filesystem::path wall_index_path(std::size_t w) const;
  std::filesystem::path snapshot_path(std::size_t k) const;

 private:
  struct Entry {
    double time;
    std::vector<std::size_t> points;  ///< vertex count per wall
    bool wall_field = true;  ///< has wall_<w>/wall and sensor_force (files before issue 34 do not)
  };
  void write_index() const;
  /// The Uniform grid of wall w in snapshot k (empty when the wall has no triangles).
  std::string wall_grid(std::size_t k, std::size_t w, const std::string& indent) const;
  std::filesystem::path dir_;
  std::string stem_;
  std::vector<Wall> walls_;
  std::vector<Entry> entries_;
  std::vector<std::string> file_names_;  ///< per wall: its own index's file name
};

}  // namespace demfem::dem
