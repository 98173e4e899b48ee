#pragma once
// FEM results on disk: HDF5 field files with an XDMF index that ParaView opens, and a CSV of
// scalar series. Written so that a crash at any moment leaves valid files for every output
// step so far:
//   <dir>/<name>_mesh.h5        the mesh, once: /nodes (n x 3), /topology/<type> (k x npe,
//                               0-based node indices, Abaqus = VTK node order),
//                               /elements/<type> (k, index of each cell in Mesh::elements),
//                               /node_labels, /element_labels
//   <dir>/<name>_NNNNNN.h5      one file per output step, NNNNNN = 0 for the first (the
//                               initial state), as the particle snapshots: attributes "time"
//                               (the nominal output time) and "state_time" (the time of the
//                               state written, see io::OutputSchedule) on "/", node fields
//                               /displacement, /velocity, /acceleration, /reaction_force
//                               (n x 3) and cell fields per element type /<type>/von_mises (k),
//                               /<type>/strain (k x 9: the strain tensor, row by row, shear
//                               components = half the engineering shear), and
//                               /<type>/max_principal_strain (k)
//   <dir>/<name>.xdmf           Xdmf 3 temporal collection referencing the above; one grid per
//                               element type when the mesh is mixed
//   <dir>/<name>_series.csv     time, max_displacement (m, largest nodal |u|), max_von_mises
//                               (Pa), max_principal_strain (largest over all elements, the
//                               thesis' "maximal strain of all sleeper elements", fig. 6.8),
//                               reaction_x/y/z (N, sum of the reaction forces)
// Each step file is written under a temporary name and renamed when complete; the XDMF is
// rewritten atomically after it, so it only ever names complete files.

#include <cstdint>
#include <filesystem>
#include <iosfwd>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "demfem/fem/fem_problem.hpp"
#include "demfem/fem/fem_scene.hpp"
#include "demfem/fem/fem_solver.hpp"

namespace demfem::io {
class CsvWriter;
}

namespace demfem::fem {

/// @brief The fields of one output step (sizes: 3 per node, or per element as in
/// ElementResults); empty vectors are not written.
struct FemFields {
  double time = 0.0;  ///< the output's time label, s
  /// Time of the state, s, when it differs from the label (NaN: the same); see
  /// io::OutputSchedule.
  double state_time = std::numeric_limits<double>::quiet_NaN();
  std::vector<double> displacement;
  std::vector<double> velocity;
  std::vector<double> acceleration;
  std::vector<double> reaction_force;
  ElementResults elements;
  /// Further point arrays (name, 3 per node), written as they are (the mode shapes of a
  /// modal analysis); their names must differ from the fields above.
  std::vector<std::pair<std::string, std::vector<double>>> node_vectors;
};

/// @brief The solver's current fields.
FemFields gather_fields(const FemSolver& solver);
/// @brief The modal-reduced solver's fields reconstructed from its modes (displacement,
/// velocity, acceleration and the element fields; no reaction forces).
FemFields gather_fields(const ModalSolver& solver);
/// @brief The rigid body's motion of every node (displacement, velocity, acceleration).
FemFields gather_fields(const RigidSolver& solver);

/// @brief Scalar summary of a step (the CSV row).
struct FemScalars {
  double time = 0.0;
  double max_displacement = 0.0;
  double max_von_mises = 0.0;
  double max_principal_strain = 0.0;
  std::array<double, 3> reaction{0.0, 0.0, 0.0};
};
FemScalars summarize(const FemFields& fields);

/// @brief replace: start a new series (an earlier run's files of the same name are
/// replaced); resume: continue the series found in the folder (a restarted solver).
enum class OutputMode : std::uint8_t { replace, resume };

/// @brief Writer of the files above.
class FemOutput {
 public:
  /// Creates `dir` if needed. replace: writes the mesh file and an empty index. resume:
  /// keeps the mesh file (it must have this mesh's node count) and the step files
  /// 0, 1, ... that exist, and continues the CSV after their rows.
  FemOutput(std::filesystem::path dir, std::string name, const Mesh& mesh,
            FemOutputSettings settings = {}, OutputMode mode = OutputMode::replace);
  ~FemOutput();
  FemOutput(const FemOutput&) = delete;
  FemOutput& operator=(const FemOutput&) = delete;

  /// Writes one output step (the fields in settings.fields) and the CSV row.
  void write(const FemFields& fields);
  void write(const FemSolver& solver) { write(gather_fields(solver)); }

  /// Drops the output steps of states later than `time` (a rollback to a checkpoint): their
  /// files are deleted, the index rewritten and the CSV cut back, so the continuation writes
  /// anew.
  void rollback(double time);
  /// Time of the state of the last output in the series (nullopt: none).
  std::optional<double> last_state_time() const {
    return state_times_.empty() ? std::nullopt : std::optional<double>(state_times_.back());
  }

  std::size_t steps() const { return times_.size(); }
  /// Time of the last step written (0 before any).
  double last_time() const { return times_.empty() ? 0.0 : times_.back(); }
  std::filesystem::path xdmf_path() const;
  std::filesystem::path csv_path() const;
  std::filesystem::path mesh_path() const;
  std::filesystem::path step_path(std::size_t step) const;  ///< 0-based

 private:
  void write_mesh(const Mesh& mesh) const;
  void scan_existing();
  void write_xdmf() const;
  bool wants(const std::string& field) const;
  std::vector<std::string> present_fields(const FemFields& fields) const;

  std::filesystem::path dir_;
  std::string name_;
  FemOutputSettings settings_;
  std::size_t node_count_ = 0;
  struct TypeGroup {
    ElementType type;
    std::vector<std::int64_t> elements;  // indices into Mesh::elements
  };
  std::vector<TypeGroup> groups_;
  std::vector<double> times_;                      // labels
  std::vector<double> state_times_;                // times of the states written
  std::vector<std::vector<std::string>> written_;  // fields present in each step file
  std::unique_ptr<io::CsvWriter> csv_;
};

/// @brief What a standalone run did.
struct FemRunSummary {
  std::int64_t steps = 0;         ///< dynamic steps taken (0 for a static analysis)
  double end_time = 0.0;          ///< solver time at the end, s
  std::size_t outputs = 0;        ///< output steps written
  double max_displacement = 0.0;  ///< largest nodal |u| at the end, m
  double wall_seconds = 0.0;
};

/// @brief Runs a scene's FEM alone (no coupling): one static solve, or ceil(end_time / dt)
/// Bossak steps of scene.dt, writing FemOutput files "<name>..." into `dir` at t = 0, every
/// `output_interval` (scene.output.interval when > 0, else this argument; 0 = only the
/// start and end states) and at the end. Progress lines (simulated time, rate, ETA) go to
/// `progress` every two seconds when it is not null. Throws scene::SceneError when a dynamic
/// run has no dt.
FemRunSummary run_fem_standalone(const FemScene& scene, double end_time, double output_interval,
                                 const std::filesystem::path& dir, const std::string& name,
                                 std::ostream* progress);

}  // namespace demfem::fem
