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

#include <array>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <utility>
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

/// Where a rank's coupling steps spend their wall time, s, summed over the run (rank 0's are
/// what the adapter reports: docs/liggghts.md, "Cost"). LIGGGHTS's own work is `loop` (its
/// time-step loop, LIGGGHTS's TIME_LOOP timer), `run_fixed` (the rest of each `run ... pre
/// no` command: parsing, its output set-up and end-of-run line, the fixes' post_run) and
/// `set_up` (the runs that set up in full: the first after a new time step); the adapter's
/// own work is `mesh_update` (writing the nodes into LIGGGHTS's mesh and recomputing its
/// geometry), `gather` (the contact distribution, kinetic energy, overlap and the reduction
/// onto rank 0), and, measured by the backend, `broadcast` and `protocol_io`.
struct StepTimes {
  double loop = 0.0, run_fixed = 0.0, set_up = 0.0;
  double mesh_update = 0.0, gather = 0.0;
  double broadcast = 0.0, protocol_io = 0.0;
  std::int64_t steps = 0, runs = 0, set_ups = 0;

  double liggghts() const { return loop + run_fixed + set_up; }
  double adapter() const { return mesh_update + gather + broadcast + protocol_io; }
  /// The parts by name, LIGGGHTS's first.
  std::array<std::pair<const char*, double>, 7> parts() const {
    return {{{"loop", loop},
             {"run_fixed", run_fixed},
             {"set_up", set_up},
             {"mesh_update", mesh_update},
             {"gather", gather},
             {"broadcast", broadcast},
             {"protocol_io", protocol_io}}};
  }
  /// The times between two readings (`earlier` first).
  StepTimes operator-(const StepTimes& earlier) const {
    return {loop - earlier.loop,
            run_fixed - earlier.run_fixed,
            set_up - earlier.set_up,
            mesh_update - earlier.mesh_update,
            gather - earlier.gather,
            broadcast - earlier.broadcast,
            protocol_io - earlier.protocol_io,
            steps - earlier.steps,
            runs - earlier.runs,
            set_ups - earlier.set_ups};
  }
};

class LiggghtsDomain {
 public:
  /// `deck`: the user's LIGGGHTS input; `mesh_fix`: the ID of its fix mesh/surface on
  /// the coupling mesh; `dem_timestep`: dem.dt, s (it replaces the deck's); `output_dir`:
  /// where the interface STL and LIGGGHTS's log go; `seed`: run.seed (the deck's
  /// ${demfem_seed} is liggghts_seed(seed)).
  LiggghtsDomain(MPI_Comm world, std::filesystem::path deck, std::string mesh_fix,
                 double dem_timestep, std::filesystem::path output_dir, std::uint64_t seed);
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

  /// Moves LIGGGHTS's coupling mesh to the structure's node positions (the first 3 n values
  /// of `kinematics`, m) with the node velocities (the next 3 n, m/s; the contact law's wall
  /// velocity at each contact, interpolated over the triangle), on every rank, for the steps
  /// that follow, and recomputes the forces at the moved mesh.
  void move_mesh(const std::vector<double>& kinematics);

  const InterfaceMesh& mesh() const { return mesh_; }
  bool attached() const { return lammps_ != nullptr; }
  /// LIGGGHTS has read a restart file: the process must then end without running static
  /// destructors (LIGGGHTS 3.8 crashes in them afterwards).
  bool restored() const { return restored_; }
  /// Where LIGGGHTS's mesh nodes are (3 n, m).
  const std::vector<double>& mesh_positions() const { return positions_; }
  StepTimes& times() { return times_; }

 private:
  void command(const std::string& line);
  void run(std::int64_t steps);
  /// Adds each contact's force to `sums` (3 n node forces first), and returns the largest
  /// overlap of a particle with the interface (0 without contacts).
  double add_contact_forces(std::vector<double>& sums) const;
  double local_kinetic_energy() const;
  std::string check_coupling_mesh();
  // Checkpoints (liggghts_domain_checkpoint.cpp): beside LIGGGHTS's restart file, the
  // adapter's state, which the restart file lacks and a continuation needs.
  void write_adapter_state(const std::filesystem::path& file);
  std::string restore_adapter_state(const std::filesystem::path& restart);
  void set_timestep(double timestep);
  void reduce_onto_rank0(StepReport& report, double overlap);

  MPI_Comm world_;
  int rank_ = 0;
  std::filesystem::path deck_, output_dir_;
  std::string mesh_fix_;
  std::uint64_t seed_ = 1;
  InterfaceMesh mesh_;
  LAMMPS_NS::LAMMPS* lammps_ = nullptr;
  LAMMPS_NS::TriMesh* tri_mesh_ = nullptr;
  LAMMPS_NS::FixContactPropertyAtomWall* contacts_ = nullptr;
  std::unique_ptr<MeshNodeAccess> node_access_;
  std::vector<double> positions_;  ///< 3 n: the mesh nodes as LIGGGHTS holds them, m
  std::vector<double> held_velocities_;  ///< 3 n: the mesh's node velocities, m/s
  std::vector<double> sums_;             ///< 3 n node forces, then the kinetic energy and overlap
  MPI_Datatype reduction_type_ = MPI_DATATYPE_NULL;
  MPI_Op reduction_op_ = MPI_OP_NULL;
  StepTimes times_;
  bool restored_ = false;  ///< LIGGGHTS has read a restart file (see the destructor)
  bool set_up_ = false;  ///< LIGGGHTS has set up a run with the current time step
  double dem_timestep_ = 0.0;
  double timestep_ = 0.0;  ///< LIGGGHTS's time step now, s
};

/// The deck's ${demfem_seed} for run.seed `run_seed`: a prime above 10000, as LIGGGHTS's
/// random commands require, different for each run.seed below 10^9.
std::uint64_t liggghts_seed(std::uint64_t run_seed);

/// The adapter's part of a checkpoint, beside LIGGGHTS's restart file `restart`.
std::filesystem::path adapter_state_file(const std::filesystem::path& restart);

/// Writes `mesh` as an ASCII STL (one facet per triangle, in the mesh's order, so that
/// LIGGGHTS's element ID i is demfem's triangle i), whole or not at all.
void write_interface_stl(const InterfaceMesh& mesh, const std::filesystem::path& file);

}  // namespace demfem::liggghts
