#pragma once
// --resume: the checkpoint a run continues from (the one named, or the latest valid one in the
// checkpoint folder), verified against the scene before any process starts (resume_check.hpp):
// a checkpoint that cannot be continued ends the run with kExitBadInput and its reason.

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>

#include "launch/launch_options.hpp"
#include "launch/preflight.hpp"
#include "launch/run_folder.hpp"

namespace demfem::coupling::launch {

/// @brief The checkpoint of a resumed run.
struct ResumePoint {
  std::filesystem::path checkpoint;  ///< <checkpoint directory>/step-NNNNNN
  /// The interface size the checkpoint's FEM had (coupler.h5 node_count); nullopt without a
  /// FEM, or when coupler.h5 cannot be read (the restore then names the file and the reason).
  std::optional<std::int64_t> fem_interface_nodes;
};

/// @brief Chooses and checks the checkpoint of `opt.resume_from` (or the latest valid one in
/// the run's checkpoint folder) into `point`, and notes it in the run record. `report`
/// receives the notes about checkpoints passed over. Returns kExitBadInput after a refusal
/// (the reason on stderr), else nullopt.
std::optional<int> find_resume_point(const LaunchOptions& opt, const CheckedRun& run,
                                     RunFolder& folder,
                                     const std::function<void(const std::string&)>& report,
                                     std::optional<ResumePoint>& point);

}  // namespace demfem::coupling::launch
