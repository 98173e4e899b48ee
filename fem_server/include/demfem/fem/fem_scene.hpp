#pragma once
// The [fem] section of a scene: the structure (mesh, materials, sections, clamps, loads) as a
// FemProblem, plus the analysis settings a standalone run or the server needs. Every key is
// documented in docs/scene_fem.md; every error names the scene file, the line and the key.

#include <string>
#include <vector>

#include "demfem/fem/fem_monitor.hpp"
#include "demfem/fem/fem_problem.hpp"
#include "demfem/fem/modal_solver.hpp"
#include "demfem/fem/rigid_solver.hpp"
#include "demfem/scene/scene_reader.hpp"

namespace demfem::fem {

/// @brief fem.analysis: one static solve, Bossak-Newmark time steps, or natural frequencies.
enum class Analysis : std::uint8_t { static_analysis, dynamic, modal };
/// @brief "static", "dynamic", "modal".
const char* analysis_name(Analysis analysis);

/// @brief fem.backend: which program models the structure in a run (docs/backends.md).
enum class FemBackendKind : std::uint8_t {
  fem,       ///< FemSolver, the full FEM (fem_server)
  modal,     ///< ModalSolver, the first N modes plus a static correction (fem_server)
  rigid,     ///< RigidSolver, one rigid body on springs (fem_server)
  external,  ///< an outside program started with fem.command (Python or C++ SDK)
};
/// @brief "fem", "modal", "rigid", "external".
const char* backend_kind_name(FemBackendKind kind);

/// @brief [fem.output]: what FemOutput writes and how often.
struct FemOutputSettings {
  bool enabled = true;              ///< write = true
  double interval = 0.0;            ///< s; 0 = every run.output_interval (or only the end state)
  std::vector<std::string> fields;  ///< subset of kFemOutputFields; default all
  bool csv = true;                  ///< the scalar series CSV
};

/// @brief Field names accepted in fem.output.fields.
inline constexpr const char* kFemOutputFields[] = {
    "displacement", "velocity", "acceleration",        "reaction_force",
    "von_mises",    "strain",   "max_principal_strain"};

/// @brief Everything [fem] defines.
struct FemScene {
  FemProblem problem;
  Analysis analysis = Analysis::dynamic;
  double dt = 0.0;          ///< s; 0 = not given (a coupled run takes it from the coupler)
  std::string dt_location;  ///< "file:line: key 'fem.dt'", for messages about dt
  FemOutputSettings output;
  FemBackendKind backend = FemBackendKind::fem;
  ModalSettings modal;  ///< [fem.modal]: the modal analysis and the modal backend
  RigidSettings rigid;  ///< [fem.rigid]: the rigid-body backend
  /// fem.command (backend = "external"): program and arguments, as written in the scene.
  std::vector<std::string> command;
  FemMonitorSettings monitor;  ///< [fem.monitor] (fem_monitor.hpp)
  /// What the reader wants the user to know but does not refuse: orphan nodes left out, the
  /// element formulation each .inp type maps to, .inp keywords accepted with a caveat. Each
  /// names the file (and line); fem_server prints them before it starts.
  std::vector<std::string> notes;
};

/// @brief Accepted material ranges (docs/scene_fem.md): typo guards around every real solid.
inline constexpr double kMinYoungsModulus = 1e-3;  ///< Pa
inline constexpr double kMaxYoungsModulus = 1e14;  ///< Pa, 100 x diamond
inline constexpr double kMaxDensity = 1e6;         ///< kg/m^3, 40 x osmium

/// @brief Reads and checks [fem]. Throws scene::SceneError naming file, line and key for
/// any bad value, unknown key, missing or malformed mesh file, or selector that selects
/// nothing.
FemScene read_fem_scene(const scene::Table& fem);

/// @brief Reads a load amplitude table ({ type = "table" | "constant" | "sine" | "sleeper",
/// ... }) as documented in docs/scene_fem.md.
TimeFunction read_time_function(const scene::Table& amplitude);

}  // namespace demfem::fem
