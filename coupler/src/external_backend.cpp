#include "demfem/coupling/external_backend.hpp"

#include <unistd.h>

#include <cstdlib>
#include <sstream>

namespace fs = std::filesystem;

namespace demfem::coupling {

#ifndef DEMFEM_PYTHON
#define DEMFEM_PYTHON "/usr/bin/python3"
#endif

ExternalCommand resolve_external_command(const CouplingSettings& s) {
  if (s.fem_command.empty() || s.fem_command.front().empty())
    throw scene::SceneError(s.fem_command_where + ": names no program");
  ExternalCommand c;
  c.working_directory = fs::absolute(s.scene_file).parent_path();
  const std::string& first = s.fem_command.front();
  if (first == "{python}") {
    c.program = DEMFEM_PYTHON;
  } else if (first.find('/') != std::string::npos) {
    const fs::path p = first;
    c.program = p.is_absolute() ? p : c.working_directory / p;
  } else {
    const char* path = std::getenv("PATH");
    std::istringstream dirs(path ? path : "");
    for (std::string d; std::getline(dirs, d, ':');) {
      const fs::path candidate = fs::path(d.empty() ? "." : d) / first;
      if (::access(candidate.c_str(), X_OK) == 0 && !fs::is_directory(candidate)) {
        c.program = fs::absolute(candidate);
        break;
      }
    }
    if (c.program.empty())
      throw scene::SceneError(s.fem_command_where + ": program '" + first +
                              "' is not on PATH; give a path (relative to the scene's folder) or "
                              "\"{python}\" for demfem's Python 3");
  }
  if (::access(c.program.c_str(), X_OK) != 0 || fs::is_directory(c.program))
    throw scene::SceneError(s.fem_command_where + ": program " + c.program.string() +
                            " is missing or not executable");
  c.arguments.assign(s.fem_command.begin() + 1, s.fem_command.end());
  for (const auto& a : s.fem_command) c.text += (c.text.empty() ? "" : " ") + a;
  return c;
}

std::optional<fs::path> python_module_dir(const fs::path& bin_dir) {
  for (const fs::path& candidate :
       {bin_dir / ".." / "python", bin_dir / ".." / "lib" / "python3" / "dist-packages"}) {
    std::error_code ec;
    if (fs::is_directory(candidate / "demfem", ec)) return fs::weakly_canonical(candidate, ec);
  }
  return std::nullopt;
}

}  // namespace demfem::coupling
