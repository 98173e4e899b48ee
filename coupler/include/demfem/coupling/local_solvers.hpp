#pragma once
// The solvers of a scene built in this process, through the same SolverBackend adapters the
// servers use (for the in-process link, and to check a whole scene before any process is
// started).

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "demfem/coupling/coupling_settings.hpp"
#include "demfem/protocol/protocol.hpp"
#include "demfem/scene/scene_reader.hpp"

namespace demfem::coupling {

/// @brief What check_solver_sections() found out about the solvers of a scene.
struct SolverSections {
  std::string dem_backend;              ///< "" without [dem]
  int dem_threads = 0;                  ///< the DEM's CPU threads (dem.threads or OpenMP's)
  std::size_t dem_setup_particles = 0;  ///< particles of the DEM's set-up (DemRun)
  /// The DEM's clock when its set-up is done, s: 0, or the loaded state's time with
  /// [dem.load] keep_time (then dem_start_where names that key; the run's clock starts there).
  double dem_start_time = 0.0;
  std::string dem_start_where;
  std::size_t fem_nodes = 0;  ///< nodes and elements of the FEM mesh
  std::size_t fem_elements = 0;
  /// Interface nodes of demfem's own FEM backends (fem, modal, rigid: one interface
  /// definition); 0 when not known (an external program's interface is its own).
  std::size_t fem_interface_nodes = 0;
  /// dem.backend = "external": the keys of [dem] that demfem does not read (those of
  /// dem_server: particles, materials, output, sensors), left to the external program.
  std::vector<std::string> dem_unapplied_keys;
};

/// @brief Reads [dem] and [fem] with the solvers' own readers and makes the checks the solvers
/// make when they start (the DEM's backend, STL walls, lattices, insertions at t = 0 and the
/// Rayleigh time step: dem::DemRun::check_setup), so that bad input anywhere in the scene is
/// reported (file, line, key; exit status 2) before any process starts. `seed`: run.seed.
/// Throws SceneError.
SolverSections check_solver_sections(const scene::Document& scene, std::uint64_t seed);

/// @brief The DEM engine of the scene's [dem] behind its DemBackend adapter, set up as
/// dem_server sets it up (nullptr without [dem]). Output goes to `output_dir`; the end
/// state is written when the object is destroyed.
std::unique_ptr<protocol::SolverBackend> make_local_dem(const scene::Document& scene,
                                                        const CouplingSettings& settings,
                                                        const std::filesystem::path& output_dir);
/// @brief The FEM engine of the scene's [fem] behind its FemBackend adapter, as fem_server
/// sets it up (nullptr without [fem]). `resume`: continue the output series in
/// `output_dir` (a run resumed from a checkpoint) instead of replacing them.
std::unique_ptr<protocol::SolverBackend> make_local_fem(const scene::Document& scene,
                                                        const CouplingSettings& settings,
                                                        const std::filesystem::path& output_dir,
                                                        bool resume = false);

/// @brief A backend made by make_local_dem / make_local_fem writes no end state when it is
/// destroyed: its output folder is no longer the run's (OutputFolderLost). No effect on other
/// backends or nullptr.
void drop_end_state(protocol::SolverBackend* backend);

}  // namespace demfem::coupling
