#include "launch/external_backend.hpp"

#include <unistd.h>

#include <cstdlib>
#include <sstream>

namespace fs = std::filesystem;

namespace demfem::coupling {

#ifndef DEMFEM_PYTHON
#define DEMFEM_PYTHON "/usr/bin/python3"
#endif

std::string ExternalCommand::label() const {
  return std::string("external ") + (role == protocol::Role::dem ? "DEM" : "FEM") +
         " backend '" + text + "'";
}

ExternalCommand resolve_external_command(const CouplingSettings& s, protocol::Role role) {
  const bool dem = role == protocol::Role::dem;
  const std::vector<std::string>& command = dem ? s.dem_command : s.fem_command;
  const std::string& where = dem ? s.dem_command_where : s.fem_command_where;
  if (command.empty() || command.front().empty())
    throw scene::SceneError(where + ": names no program");
  ExternalCommand c;
  c.role = role;
  c.working_directory = fs::absolute(s.scene_file).parent_path();
  const std::string& first = command.front();
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
      throw scene::SceneError(where + ": program '" + first +
                              "' is not on PATH; give a path (relative to the scene's folder) or "
                              "\"{python}\" for demfem's Python 3");
  }
  if (::access(c.program.c_str(), X_OK) != 0 || fs::is_directory(c.program))
    throw scene::SceneError(where + ": program " + c.program.string() +
                            " is missing or not executable");
  c.arguments.assign(command.begin() + 1, command.end());
  for (const auto& a : command) c.text += (c.text.empty() ? "" : " ") + a;
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

std::unique_ptr<SolverProcess> make_external_process(const ExternalCommand& command,
                                                     const std::vector<std::string>& solver_args,
                                                     const fs::path& out_dir,
                                                     const fs::path& bin_dir) {
  std::vector<std::string> args = command.arguments;
  bool output_dir = false;
  for (std::size_t k = 0; k < solver_args.size(); ++k) {
    const bool path =
        k > 0 && (solver_args[k - 1] == "--scene" || solver_args[k - 1] == "--output-dir");
    output_dir = output_dir || solver_args[k] == "--output-dir";
    args.push_back(path ? fs::absolute(solver_args[k]).string() : solver_args[k]);
  }
  if (!output_dir) args.insert(args.end(), {"--output-dir", fs::absolute(out_dir).string()});
  const bool dem = command.role == protocol::Role::dem;
  auto p = std::make_unique<SolverProcess>(dem ? "DEM solver" : "FEM solver", command.program,
                                           args);
  p->set_working_directory(command.working_directory);
  if (const auto py = python_module_dir(bin_dir)) {
    // appended, not `":" + std::string(old)`: GCC 12 warns falsely (-Wrestrict) on that form
    std::string path = py->string();
    if (const char* old = std::getenv("PYTHONPATH"); old && *old) path.append(":").append(old);
    p->set_environment("PYTHONPATH", path);
  }
  p->set_environment("DEMFEM_ROLE", protocol::role_name(command.role));
  return p;
}

}  // namespace demfem::coupling
