#pragma once
// The command line and scene loading that every solver process shares (dem_server,
// fem_server, and any other engine that attaches through the protocol):
//   <solver> --scene FILE [--set KEY=VALUE]... [--segment NAME] [--output-dir DIR] [--quiet]
// with the exit codes 0 ok, 1 failure while running, 2 bad command line or scene
// (demfem/interface/exit_status.hpp).
// Header-only; the program links CLI11 and demfem::scene.

#include <CLI/CLI.hpp>

#include <csignal>
#include <filesystem>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include "demfem/interface/exit_status.hpp"
#include "demfem/scene/scene_reader.hpp"

namespace demfem::scene {

/// @brief The options every solver process takes.
struct SolverCommandLine {
  std::string scene_file;
  std::string segment;     ///< empty: run the scene alone
  std::string output_dir;  ///< empty: run.output_dir
  bool quiet = false;
  std::vector<std::string> overrides;  ///< --set KEY=VALUE, in order (Document::load)

  /// Adds --scene, --segment, --output-dir and --quiet; `section` is the scene table the
  /// solver reads ("dem", "fem"), `engine` how the help names it ("the DEM").
  void add_to(CLI::App& app, const std::string& section, const std::string& engine) {
    app.add_option("--scene", scene_file, "Scene file (TOML) with [run] and [" + section + "]")
        ->required();
    app.add_option("--segment", segment,
                   "Shared-memory segment of the coupler to serve (e.g. /demfem-1a2b); omit "
                   "to run " +
                       engine + " alone");
    app.add_option("--output-dir", output_dir, "Output folder (default: run.output_dir)");
    app.add_flag("--quiet", quiet, "No progress lines");
    app.add_option("--set", overrides,
                   "KEY=VALUE: set a scene key (dotted, with array indices, e.g. "
                   "dem.pairs[0].friction=0.3; VALUE in TOML) after reading the scene; "
                   "repeatable")
        ->allow_extra_args(false);
  }

  /// The output folder: --output-dir, else run.output_dir of the scene.
  std::filesystem::path output_folder(const RunSettings& run) const {
    return output_dir.empty() ? run.output_dir : std::filesystem::path(output_dir);
  }
};

/// Parses the command line: nullopt to go on, else the exit code (0 after --help, 2 after
/// a mistake, with CLI11's message). Also makes the solver ignore SIGUSR1/SIGUSR2, demfem_run's
/// checkpoint requests: a request sent to the whole job (Slurm's --signal without B:) must not
/// end a solver by the default action, also not while dem.settle_time runs before serve().
inline std::optional<int> parse_solver_command_line(CLI::App& app, int argc, char** argv) {
  std::signal(SIGUSR1, SIG_IGN);
  std::signal(SIGUSR2, SIG_IGN);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return kExitBadInput;
  }
  return std::nullopt;
}

/// Loads the scene file with the --set overrides: its [run] settings into `run`, then
/// `read(table)` on its [`section`] (which may throw SceneError). nullopt on success, else
/// kExitBadInput after printing the reason (a missing section, or the SceneError naming file,
/// line and key) to stderr; `solver` names the program in the message.
template <class Read>
std::optional<int> load_solver_scene(const SolverCommandLine& cl, const std::string& section,
                                     const std::string& solver, RunSettings& run, Read&& read) {
  const std::string& scene_file = cl.scene_file;
  try {
    std::vector<Override> overrides;
    for (const auto& o : cl.overrides) overrides.push_back(Override::parse(o));
    const auto doc = Document::load(scene_file, overrides);
    run = read_run_settings(doc);
    const auto root = doc.root();
    auto table = root.table(section);
    if (!table) {
      std::cerr << scene_file << ": the scene has no [" << section << "] section, nothing for "
                << solver << "\n";
      return kExitBadInput;
    }
    read(*table);
  } catch (const SceneError& e) {
    std::cerr << e.what() << "\n";
    return kExitBadInput;
  }
  return std::nullopt;
}

}  // namespace demfem::scene
