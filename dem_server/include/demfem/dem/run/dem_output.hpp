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
#include "demfem/io/h5_file.hpp"

namespace demfem::dem {

/// @brief Writes particle snapshots: <dir>/<stem>_NNNNNN.h5 (NNNNNN = 0 for the first, the
/// initial state) with datasets position (n x 3), velocity (n x 3), angular_velocity (n x 3),
/// radius (n), mass (n), material (n, int64), id (n, int64), vertex (n, int64: 0 .. n-1, the
/// Polyvertex connectivity) and file attributes time (s, the nominal output time),
/// state_time (s, the time of the state written; see io::OutputSchedule) and count; index
/// <dir>/<stem>.xdmf. With polyhedra (set_shapes): also surface_points (m x 3),
/// surface_velocity (m x 3: the rigid-body velocity at each point), surface_triangles
/// (t x 3, int64), the rock's fields on each triangle: surface_id, surface_material (t,
/// int64), surface_radius, surface_mass (t), surface_centre_velocity and
/// surface_angular_velocity (t x 3), and on each point: surface_point_id, _material, _radius,
/// _mass (m) and surface_point_angular_velocity (m x 3); attributes surface_points and
/// surface_triangles; the snapshot's index entry is then a spatial collection of the
/// particles' points and the "polyhedra" surfaces. ParaView's default reader (Xdmf3ReaderS)
/// merges the two into pieces of one data set, so every field is on both with both
/// associations (the spheres' point fields are their cell fields too): colouring by any of
/// them colours every piece.
class ParticleOutput {
 public:
  ParticleOutput(std::filesystem::path dir, std::string stem = "particles");

  /// The system's shape table (DemSystem::shape(k), k < shape_count()): the dilated
  /// polyhedra of a snapshot are then also written as triangle surfaces. Each is its core's
  /// hull with every vertex moved outwards by r_d along the mean normal of its triangles,
  /// scaled and placed by the particle's pose: an approximation of the dilated surface (its
  /// faces lie between r_d cos φ and r_d off the core's, φ the angle between a vertex's mean
  /// normal and its triangles' normals; edges and corners are cut flat where the true surface
  /// is round).
  void set_shapes(const std::vector<PolyhedronShape>& shapes);

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
    std::size_t points = 0, triangles = 0;  ///< of the polyhedron surfaces
  };
  /// A shape's display surface at scale 1, body frame: vertices (3 each), triangles.
  struct Surface {
    std::vector<double> vertices;
    std::vector<std::int64_t> triangles;
  };
  std::vector<Surface> surfaces_;
  /// The <Grid> of the polyhedron surfaces of snapshot k (triangles).
  /// A rock's fields, repeated on each of its cells or points.
  struct PerRock {
    std::vector<std::int64_t> id, material;
    std::vector<double> radius, mass, angular_velocity;
  };
  /// The polyhedra as triangle surfaces in world coordinates, with their fields: each
  /// point's own velocity, each triangle's its rock centre's.
  struct SurfaceData {
    std::vector<double> points, point_velocity, centre_velocity;
    std::vector<std::int64_t> triangles;
    PerRock cell, point;
  };
  SurfaceData surfaces(const ParticleState& p, std::span<const std::int64_t> ids) const;
  static void write_surfaces(io::H5File& f, const SurfaceData& sd);
  void write_polyhedron_grid(std::ostream& x, std::size_t k, const std::string& indent) const;
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
