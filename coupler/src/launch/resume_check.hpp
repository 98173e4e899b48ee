#pragma once
// demfem run --resume: the checks of a checkpoint against the scene that need no process
// (the launcher's, coupler/src/launch/resume_point.cpp), and the folder tests they use.

#include <filesystem>
#include <optional>

#include "demfem/coupling/coupling_settings.hpp"
#include "demfem/coupling/local_solvers.hpp"
#include "launch/run_record.hpp"

namespace demfem::coupling {

/// @brief Whether `path` is `folder` or lies below it (both made absolute and canonical).
bool inside(const std::filesystem::path& path, const std::filesystem::path& folder);
/// @brief Whether `a` and `b` name the same folder.
bool same_folder(const std::filesystem::path& a, const std::filesystem::path& b);

/// @brief Checks of the checkpoint of --resume against this scene that need no process (exit
/// status 2 on refusal, with the reason on stderr): the particles of the set-up, the DEM and
/// FEM backends that wrote it (docs/backends.md), the FEM mesh; and takes over the series of
/// the checkpoint's run when resuming into another output folder (docs/reliability.md,
/// "Resume"). Returns an exit status, or nullopt to go on.
std::optional<int> prepare_resume(const std::filesystem::path& checkpoint,
                                  const CouplingSettings& settings, const SolverSections& sections,
                                  const std::filesystem::path& out_dir, RunRecord& record);

}  // namespace demfem::coupling
