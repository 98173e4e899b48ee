#pragma once
// The run folder: the output folder (and a checkpoint folder outside it) is this run's alone
// while it runs. Two runs writing one folder corrupt it silently; the folder lock
// (io::FolderLock, .demfem.lock) refuses the second, and run.json of a run still alive refuses
// it when the lock file was removed. The folder keeps the run record (run.json,
// run_record.hpp): written when the run starts and again when it ends. A fresh start removes
// the files an earlier run left (clear_owned_outputs). Solvers restarted by this run are its
// children and take no lock.

#include <chrono>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "demfem/io/folder_lock.hpp"
#include "launch/launch_options.hpp"
#include "launch/preflight.hpp"
#include "launch/run_record.hpp"

namespace demfem::coupling::launch {

/// @brief The output folder of one run, its locks and its run record.
class RunFolder {
 public:
  RunFolder() = default;
  RunFolder(const RunFolder&) = delete;  // check_lock() is called through `this`
  RunFolder& operator=(const RunFolder&) = delete;

  /// Locks the output folder (and the checkpoint folder outside it) and refuses a folder that
  /// a live run still writes; fills the run record. Returns kExitBadInput after a refusal
  /// (the reason on stderr), else nullopt.
  std::optional<int> claim(const LaunchOptions& opt, const CheckedRun& run,
                           const std::vector<std::string>& command_line);
  /// A fresh start: removes the files of an earlier run (with other output settings they
  /// would stay and look like this run's). Returns kExitBadInput when that fails.
  std::optional<int> clear_earlier_outputs();
  /// Writes run.json saying "running". Returns kExitBadInput when that fails.
  std::optional<int> record_start();
  /// Throws OutputFolderLost when a lock file was removed or replaced (checked at most once
  /// a second): a folder deleted under a running run, perhaps made again by another, is no
  /// longer this run's to write.
  void check_lock();

  const std::filesystem::path& output_dir() const { return out_dir_; }
  /// The checkpoint folder; empty without [checkpoint].
  const std::filesystem::path& checkpoint_dir() const { return cp_dir_; }
  RunRecord& record() { return record_; }

 private:
  void describe_run(const LaunchOptions& opt, const CheckedRun& run,
                    const std::vector<std::string>& command_line);
  std::filesystem::path out_dir_;
  std::filesystem::path cp_dir_;
  std::vector<io::FolderLock> locks_;
  RunRecord record_;
  std::chrono::steady_clock::time_point last_lock_check_ = std::chrono::steady_clock::now();
};

}  // namespace demfem::coupling::launch
