#pragma once
// fem.backend = "external" and dem.backend = "external": an outside program (a Python backend
// on the Python SDK, a C++ one on the installed protocol package) started, watched and
// restarted by the launcher as it does fem_server and dem_server (docs/backends.md,
// docs/protocol.md "Attaching a code"). One mechanism for both roles: the role only chooses
// the scene key (fem.command or dem.command) and the words of the messages.

#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "demfem/coupling/coupling_settings.hpp"
#include "demfem/protocol/protocol.hpp"
#include "launch/supervisor.hpp"

namespace demfem::coupling {

/// @brief The program of fem.command or dem.command, ready to start.
struct ExternalCommand {
  protocol::Role role = protocol::Role::fem;
  std::filesystem::path program;            ///< absolute
  std::vector<std::string> arguments;       ///< command[1..], as written
  std::filesystem::path working_directory;  ///< the scene's folder
  std::string text;                         ///< the command joined, for messages
  /// "external FEM backend '{python} spring_plate.py'": how messages name the process.
  std::string label() const;
};

/// @brief Resolves the command of `role` (fem.command or dem.command): "{python}" as the first
/// entry is the Python 3 that demfem's Python module was built for (DEMFEM_PYTHON,
/// /usr/bin/python3 on Debian); a first entry with a '/' is a path relative to the scene's
/// folder; any other is looked up on PATH. The program runs in the scene's folder, so
/// relative paths among the arguments are relative to the scene. Throws scene::SceneError
/// naming the key when the program is not there or not executable.
ExternalCommand resolve_external_command(const CouplingSettings& settings, protocol::Role role);

/// @brief The folder holding demfem's Python package next to the executables in `bin_dir`:
/// <build>/python in a build tree, <prefix>/lib/python3/dist-packages in an installation.
std::optional<std::filesystem::path> python_module_dir(const std::filesystem::path& bin_dir);

/// @brief The process of an external backend, not yet started: its command's arguments, then
/// `solver_args` (the arguments demfem's own solver of the role gets: --scene, --segment,
/// --set..., --output-dir, --resume) with every path made absolute, and --output-dir `out_dir`
/// when `solver_args` has none (the default run.output_dir is relative to the launcher's
/// folder, not to the scene's). It runs in the scene's folder, with demfem's Python package
/// (next to `bin_dir`) on PYTHONPATH and DEMFEM_ROLE naming its role (serve() refuses a
/// program that serves the other side).
std::unique_ptr<SolverProcess> make_external_process(const ExternalCommand& command,
                                                     const std::vector<std::string>& solver_args,
                                                     const std::filesystem::path& out_dir,
                                                     const std::filesystem::path& bin_dir);

}  // namespace demfem::coupling
