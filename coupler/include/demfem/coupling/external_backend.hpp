#pragma once
// fem.backend = "external": an outside program (a Python backend on the Python SDK, a C++
// one on the installed protocol package) started, watched and restarted by the launcher as it
// does fem_server (docs/backends.md, docs/protocol.md "Attaching a code").

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "demfem/coupling/coupling_settings.hpp"

namespace demfem::coupling {

/// @brief The program of fem.command, ready to start.
struct ExternalCommand {
  std::filesystem::path program;            ///< absolute
  std::vector<std::string> arguments;       ///< fem.command[1..], as written
  std::filesystem::path working_directory;  ///< the scene's folder
  std::string text;                         ///< fem.command joined, for messages
};

/// @brief Resolves fem.command: "{python}" as the first entry is the Python 3 that demfem's
/// Python module was built for (DEMFEM_PYTHON, /usr/bin/python3 on Debian); a first entry with
/// a '/' is a path relative to the scene's folder; any other is looked up on PATH. The
/// program runs in the scene's folder, so relative paths among the arguments are relative to
/// the scene. Throws scene::SceneError naming fem.command when the program is not there or
/// not executable.
ExternalCommand resolve_external_command(const CouplingSettings& settings);

/// @brief The folder holding demfem's Python package next to the executables in `bin_dir`:
/// <build>/python in a build tree, <prefix>/lib/python3/dist-packages in an installation.
std::optional<std::filesystem::path> python_module_dir(const std::filesystem::path& bin_dir);

}  // namespace demfem::coupling
