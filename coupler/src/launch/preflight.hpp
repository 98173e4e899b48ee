#pragma once
// The launcher's first part: everything about a run that can be checked before the output
// folder is touched and before any process starts. The scene (with --set, --fem-backend,
// --dem-backend) is read and its solver sections are built (a [dem.load] prepare scene runs
// first when its state is missing); external programs are resolved; the command line's
// combinations (--in-process, --resume, --debug-kill) and the solver executables are checked.
// A refusal prints its reason on stderr and ends the run with kExitBadInput.

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "demfem/coupling/coupling_settings.hpp"
#include "demfem/coupling/local_solvers.hpp"
#include "demfem/scene/scene_reader.hpp"
#include "launch/debug_kill.hpp"
#include "launch/external_backend.hpp"
#include "launch/launch_options.hpp"
#include "launch/scene_steps.hpp"

namespace demfem::coupling::launch {

/// @brief A scene and command line that passed the checks: what the later parts start from.
struct CheckedRun {
  std::optional<scene::Document> doc;
  CouplingSettings settings;
  SolverSections sections;
  std::vector<PostStep> post_steps;
  std::filesystem::path bin;      ///< the folder of demfem's programs (--bin-dir or ours)
  std::filesystem::path out_dir;  ///< --output-dir, else run.output_dir
  bool remote = true;             ///< solver processes (not --in-process)
  std::optional<ExternalCommand> external_fem;  ///< fem.backend = "external"
  std::optional<ExternalCommand> external_dem;  ///< dem.backend = "external"
  std::optional<DebugKill> debug_kill;
  /// KEY=VALUE overrides the launcher adds after the user's --set (fem.mesh.seat's
  /// fem.mesh.translate), passed to every process like them
  std::vector<std::string> computed_sets;
};

/// @brief Runs the checks into `run`. Returns the exit status to end with (0 after --check of
/// a valid scene, kExitBadInput after a refusal), or nullopt to go on.
std::optional<int> check_before_start(const LaunchOptions& opt, CheckedRun& run);

}  // namespace demfem::coupling::launch
