#pragma once
// LiggghtsDomain: one MPI rank's share of a LIGGGHTS simulation coupled to demfem's interface.
//
// Every rank holds one; all of them call the same methods in the same order (LIGGGHTS's
// commands are collective). The interface mesh goes to LIGGGHTS as an STL file that the
// user's deck reads with `fix ID all mesh/surface file ${demfem_mesh} type T` and lists in a
// `fix wall/gran ... store_force_contact_stress yes`; after a step each rank distributes the
// contact forces of its particles onto the interface nodes (barycentric weights of each
// contact point, as dem_server does) and rank 0 receives their sum (MPI_Reduce).

#include <mpi.h>

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "demfem/interface/interface_mesh.hpp"

namespace LAMMPS_NS {
class LAMMPS;
class TriMesh;
class FixContactPropertyAtomWall;
}  // namespace LAMMPS_NS

namespace demfem::liggghts {

class MeshNodeAccess;

/// What a coupling step reports (meaningful on rank 0 after advance()).
struct StepReport {
  std::vector<double> node_forces;  ///< 3 n, N: the particles' forces on the interface nodes
  double kinetic_energy = 0.0;      ///< J, translation and rotation of every particle
  double max_overlap = 0.0;         ///< m, largest overlap of a particle with the interface
};

class LiggghtsDomain {
 public:
  /// `deck`: the user's LIGGGHTS input; `mesh_fix`: the ID of its fix mesh/surface on
  /// the coupling mesh; `dem_timestep`: dem.dt, s (it replaces the deck's); `output_dir`:
  /// where the interface STL and LIGGGHTS's log go.
  LiggghtsDomain(MPI_Comm world, std::filesystem::path deck, std::string mesh_fix,
                 double dem_timestep, std::filesystem::path output_dir);
  ~LiggghtsDomain();
  LiggghtsDomain(const LiggghtsDomain&) = delete;
  LiggghtsDomain& operator=(const LiggghtsDomain&) = delete;

  /// Writes the interface as STL (rank 0), opens LIGGGHTS (again, if it was open), runs the
  /// deck with ${demfem_restart} = `restart` (a checkpoint's LIGGGHTS restart file, or "none"
  /// for a fresh start) and ${demfem_resume} = 1 or 0 (LIGGGHTS 3.8's `if` compares numbers
  /// only), sets the time step and checks that it holds the coupling mesh.
  /// Returns an empty string when it does, else why not (the same text on every rank;
  /// LIGGGHTS's own errors end the process as LIGGGHTS does).
  std::string attach(const InterfaceMesh& mesh, const std::filesystem::path& restart = {});

  /// Writes LIGGGHTS's restart file (particles, contact histories, fix states) to `file`,
  /// whole or not at all.
  void write_restart(const std::filesystem::path& file);

  /// LIGGGHTS's step counter: n_D per coupling step since the start.
  std::int64_t dem_steps() const;

  /// Advances `substeps` LIGGGHTS steps of dt / substeps; with `average` the node forces are
  /// the mean over the substeps, else those of the last one.
  StepReport advance(double dt, std::int64_t substeps, bool average);

  /// Moves LIGGGHTS's coupling mesh to the structure's node `positions` (3 n, m) with the
  /// node `velocities` (3 n, m/s; the contact law's wall velocity at each contact, interpolated
  /// over the triangle), on every rank, for the steps that follow.
  void move_mesh(const std::vector<double>& positions, const std::vector<double>& velocities);

  const InterfaceMesh& mesh() const { return mesh_; }
  bool attached() const { return lammps_ != nullptr; }
  /// LIGGGHTS has read a restart file: the process must then end without running static
  /// destructors (LIGGGHTS 3.8 crashes in them afterwards).
  bool restored() const { return restored_; }
  /// Where LIGGGHTS's mesh nodes are (3 n, m).
  const std::vector<double>& mesh_positions() const { return positions_; }

 private:
  void command(const std::string& line);
  void add_contact_forces(std::vector<double>& node_forces) const;
  double local_kinetic_energy() const;
  double local_max_overlap() const;
  std::string check_coupling_mesh();
  void set_timestep(double timestep);

  MPI_Comm world_;
  int rank_ = 0;
  std::filesystem::path deck_, output_dir_;
  std::string mesh_fix_;
  InterfaceMesh mesh_;
  LAMMPS_NS::LAMMPS* lammps_ = nullptr;
  LAMMPS_NS::TriMesh* tri_mesh_ = nullptr;
  LAMMPS_NS::FixContactPropertyAtomWall* contacts_ = nullptr;
  std::unique_ptr<MeshNodeAccess> node_access_;
  std::vector<double> positions_;  ///< 3 n: the mesh nodes as LIGGGHTS holds them, m
  bool restored_ = false;  ///< LIGGGHTS has read a restart file (see the destructor)
  bool set_up_ = false;  ///< LIGGGHTS has set up a run with the current time step
  double dem_timestep_ = 0.0;
  double timestep_ = 0.0;  ///< LIGGGHTS's time step now, s
};

/// Writes `mesh` as an ASCII STL (one facet per triangle, in the mesh's order, so that
/// LIGGGHTS's element ID i is demfem's triangle i), whole or not at all.
void write_interface_stl(const InterfaceMesh& mesh, const std::filesystem::path& file);

}  // namespace demfem::liggghts
