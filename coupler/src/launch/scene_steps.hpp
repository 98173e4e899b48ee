#pragma once
// What `demfem run` does before and after the solvers of a scene:
//   * prepare: a [dem.load] scene = "other.toml" names the run whose end state this scene
//     starts from; when that state is missing or was made by another version of the scene
//     (particle_source.hpp, state_is_current), the other scene is run first, to completion,
//     by a child demfem_run (a lock file keeps two runs from preparing the same state at once);
//   * [[post]]: tools run on the output once the run has ended well (plots, reports, checks;
//     docs/scenes.md). A tool is a script in the repository's tools/ folder (.py files run
//     with Debian's python3) or a program of this build's bin folder; its arguments may name
//     {output} (the run's output folder), {scene} (the scene file) and {bin} (the bin folder).

#include <filesystem>
#include <string>
#include <vector>

#include "demfem/scene/scene_reader.hpp"

namespace demfem::coupling {

/// @brief One [[post]] entry, resolved.
struct PostStep {
  std::string tool;                  ///< as written
  std::filesystem::path executable;  ///< the script or program
  bool python = false;               ///< run with the python interpreter
  std::vector<std::string> args;     ///< with the placeholders still in
  std::string where;                 ///< file:line of the entry
};

/// @brief Folder of the tools/ scripts: $DEMFEM_TOOLS_DIR, else this source tree's tools/.
std::filesystem::path tools_directory();

/// @brief Reads [[post]] of a scene (SceneError naming file, line and key for an unknown
/// tool or key). `bin_dir` is where this build's programs are.
std::vector<PostStep> read_post_steps(const scene::Document& scene,
                                      const std::filesystem::path& bin_dir);

/// @brief Runs the steps in order, each to its end, in the current folder; prints each
/// command. Returns 0, or 1 after the first step that fails (its status is reported).
int run_post_steps(const std::vector<PostStep>& steps, const std::filesystem::path& output_dir,
                   const std::filesystem::path& scene_file, const std::filesystem::path& bin_dir);

/// @brief Makes the state that [dem.load] scene = ... of `scene` needs, when it is missing
/// or stale, by running that scene with `bin_dir`/demfem_run (passing --quiet and
/// --in-process on). Returns 0 when the state is there (made or found), else the exit status
/// to end with (2 for a cycle of prepare scenes, the child's status otherwise). With
/// `check_only` a missing or stale state is not made: the prepare scene is checked
/// (`demfem_run --check` with its overrides, down the chain) and its status returned.
int run_prepare_scenes(const scene::Document& scene, const std::filesystem::path& bin_dir,
                       bool quiet, bool in_process, bool check_only = false);

}  // namespace demfem::coupling
