#pragma once
// Consistent checkpoints of a coupled run (docs/reliability.md). A checkpoint is a folder
// <dir>/step-<N>/ holding one HDF5 part per process (dem.h5, fem.h5, coupler.h5), all taken
// at the boundary after N coupling steps, and manifest.json, written last by atomic rename,
// that lists every part with its size and FNV-1a 64 checksum. A folder without a manifest,
// or whose parts do not match it, is not a checkpoint and is never resumed from.

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "demfem/io/file_hash.hpp"

namespace demfem::coupling {

/// @brief FNV-1a 64 over the bytes of a file (demfem/io/file_hash.hpp).
using io::fnv1a64_file;

/// @brief One file of a checkpoint as the manifest lists it.
struct CheckpointPart {
  std::string name;  ///< file name inside the checkpoint folder
  std::uintmax_t size = 0;
  std::uint64_t checksum = 0;  ///< FNV-1a 64
};

/// @brief The committed description of a checkpoint.
struct CheckpointManifest {
  std::int64_t step = 0;  ///< coupling steps done
  double time = 0.0;      ///< simulated time, s
  std::string scheme;
  std::vector<CheckpointPart> parts;
};

/// @brief "step-000042"
std::string checkpoint_folder_name(std::int64_t step);

/// @brief Sizes and checksums of `names` inside `folder`, then manifest.json written
/// atomically (the commit). Throws std::runtime_error naming a missing file.
CheckpointManifest commit_checkpoint(const std::filesystem::path& folder, std::int64_t step,
                                     double time, const std::string& scheme,
                                     const std::vector<std::string>& names);

/// @brief Reads and verifies the checkpoint in `folder`: the manifest parses, every part it
/// lists exists with the listed size and checksum, and `required` parts are listed. Throws
/// std::runtime_error naming the file (and the manifest line or key) and what is wrong.
CheckpointManifest verify_checkpoint(const std::filesystem::path& folder,
                                     const std::vector<std::string>& required);

/// @brief Committed checkpoint folders under `dir` (those with a manifest.json), newest
/// (highest step) first.
std::vector<std::filesystem::path> list_checkpoints(const std::filesystem::path& dir);

/// @brief The newest checkpoint under `dir` that verifies; every newer step folder skipped
/// (uncommitted, incomplete, truncated, bad checksum) is reported
/// through `report` with the reason. nullopt when none verifies.
std::optional<std::filesystem::path> latest_valid_checkpoint(
    const std::filesystem::path& dir, const std::vector<std::string>& required,
    const std::function<void(const std::string&)>& report);

/// @brief Removes all but the newest `keep` committed checkpoints, and uncommitted folders
/// (no manifest) older than the newest committed one.
void prune_checkpoints(const std::filesystem::path& dir, std::int64_t keep);

/// @brief Removes every step folder under `dir` of a step after `step` (-1: all): at the
/// start of a fresh run they belong to an older run, after a resume to the abandoned future
/// of this one; left there, they would count as the newest when pruning.
void discard_checkpoints_after(const std::filesystem::path& dir, std::int64_t step);

}  // namespace demfem::coupling
