#pragma once
// The files demfem writes into an output folder, by name, so that a fresh run can clear the
// files of an earlier run (with other output settings they would otherwise stay and look like
// part of the new one), and a run resumed into a new folder can take over the series it
// continues. Only these names are ever removed or copied; anything else in the folder is the
// user's (docs/reliability.md, "Output folder").

#include <filesystem>
#include <string>
#include <vector>

namespace demfem::coupling {

/// @brief True for a file name demfem writes into an output folder: coupling.csv,
/// coupling.h5, coupling.xdmf, coupling_NNNNNN.h5, timing.csv, beam_check.csv, coupling.png,
/// fem.xdmf, fem_series.csv,
/// fem_mesh.h5, fem_NNNNNN.h5, particles.xdmf, particles_NNNNNN.h5, sensor_<name>.csv, and
/// any of these with ".part" appended (a write cut short). Not run.json nor the lock file.
bool is_owned_output(const std::string& file_name);

/// @brief Removes the owned files (not folders) directly in `dir`; returns their names,
/// sorted. Throws std::runtime_error naming a file that cannot be removed.
std::vector<std::string> clear_owned_outputs(const std::filesystem::path& dir);

/// @brief Replaces the owned files in `to` by copies of those in `from` (".part" files
/// excepted); returns the names copied, sorted. Throws naming the file on failure.
std::vector<std::string> copy_owned_outputs(const std::filesystem::path& from,
                                            const std::filesystem::path& to);

}  // namespace demfem::coupling
