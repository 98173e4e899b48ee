#include "launch/run_folder.hpp"

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <thread>

#include "demfem/coupling/coupling_run.hpp"
#include "demfem/coupling/output_folder.hpp"
#include "demfem/interface/exit_status.hpp"
#include "launch/resume_check.hpp"

namespace fs = std::filesystem;

namespace demfem::coupling::launch {

std::optional<int> RunFolder::claim(const LaunchOptions& opt, const CheckedRun& run,
                                    const std::vector<std::string>& command_line) {
  out_dir_ = run.out_dir;
  cp_dir_ =
      run.settings.checkpoint.enabled ? checkpoint_directory(run.settings, out_dir_) : fs::path();
  try {
    const std::string what = "demfem run " + opt.scene + " (started " + utc_now() + ")";
    locks_.emplace_back(out_dir_, what);
    if (!cp_dir_.empty()) {
      if (inside(cp_dir_, out_dir_)) {
        fs::create_directories(cp_dir_);
      } else {
        locks_.emplace_back(cp_dir_, what);
      }
    }
  } catch (const io::FolderBusy& e) {
    std::fprintf(stderr,
                 "demfem run: %s; two runs in one folder would corrupt each other's files: wait "
                 "for it to end, or give this run another folder (--output-dir, run.output_dir, "
                 "checkpoint.directory)\n",
                 e.what());
    return kExitBadInput;
  } catch (const std::exception& e) {
    std::fprintf(stderr,
                 "demfem run: %s; choose a writable folder (--output-dir, run.output_dir, "
                 "checkpoint.directory)\n",
                 e.what());
    return kExitBadInput;
  }
  if (const auto prev = read_run_status(out_dir_); prev && recorded_run_alive(*prev)) {
    // Its lock file was removed (the folder deleted and made again, a clean-up of dot files):
    // the lock above is a new one, but the run is still writing here.
    std::fprintf(stderr,
                 "demfem run: %s is in use by process %d (run.json: running since %s, and the "
                 "process is alive; its lock file %s was removed or replaced while it runs); two "
                 "runs in one folder would corrupt each other's files: wait for it to end (or "
                 "stop it), or give this run another folder (--output-dir, run.output_dir)\n",
                 out_dir_.c_str(), static_cast<int>(prev->pid), prev->start_time.c_str(),
                 (out_dir_ / io::FolderLock::kFileName).c_str());
    return kExitBadInput;
  } else if (prev && prev->status == "running") {
    std::fprintf(stderr,
                 "demfem run: note: the previous run in %s (pid %d, started %s) ended without "
                 "writing its end to run.json: it was killed or crashed\n",
                 out_dir_.c_str(), static_cast<int>(prev->pid), prev->start_time.c_str());
  }
  describe_run(opt, run, command_line);
  return std::nullopt;
}

void RunFolder::describe_run(const LaunchOptions& opt, const CheckedRun& run,
                             const std::vector<std::string>& command_line) {
  const CouplingSettings& settings = run.settings;
  RunRecord& record = record_;
  record.scene = fs::absolute(opt.scene);
  record.overrides = opt.sets;
  record.scene_hash = scene_hash(opt.scene, record.overrides);
  record.output_dir = fs::absolute(out_dir_);
  if (!cp_dir_.empty()) record.checkpoint_dir = fs::absolute(cp_dir_);
  record.in_process = !run.remote;
  record.command_line = command_line;
  {
    char host[256] = {};
    ::gethostname(host, sizeof(host) - 1);
    record.host = host;
  }
  record.pid = ::getpid();
  record.dem_backend = run.sections.dem_backend;
  if (settings.dem_external()) record.dem_command = settings.dem_command;
  if (settings.has_fem) {
    record.fem_backend = settings.fem_backend;
    record.fem_command = settings.fem_command;
  }
  record.dem_threads = run.sections.dem_threads;
  if (const char* omp = std::getenv("OMP_NUM_THREADS")) record.omp_num_threads = omp;
  record.hardware_threads = std::thread::hardware_concurrency();
  record.start_time = utc_now();
  record.end_time_simulated = settings.run.end_time;
  record.step_count = settings.step_count;
}

std::optional<int> RunFolder::clear_earlier_outputs() {
  try {
    record_.cleared = clear_owned_outputs(out_dir_);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "demfem run: %s\n", e.what());
    return kExitBadInput;
  }
  if (!record_.cleared.empty()) {
    std::fprintf(stderr, "demfem run: removed %zu files of an earlier run in %s\n",
                 record_.cleared.size(), out_dir_.c_str());
  }
  return std::nullopt;
}

std::optional<int> RunFolder::record_start() {
  try {
    write_run_record(out_dir_, record_);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "demfem run: %s; choose a writable output folder\n", e.what());
    return kExitBadInput;
  }
  return std::nullopt;
}

void RunFolder::check_lock() {
  const auto now = std::chrono::steady_clock::now();
  if (now - last_lock_check_ < std::chrono::seconds(1)) return;
  last_lock_check_ = now;
  for (const auto& lock : locks_) {
    if (lock.intact()) continue;
    throw OutputFolderLost(
        (lock.folder() / io::FolderLock::kFileName).string() +
        " was removed or replaced while this run was writing " + lock.folder().string() +
        " (the folder was deleted?); another run may be writing there now, so this one "
        "stops and writes nothing more there. Its output is incomplete: run it again into a "
        "folder of its own");
  }
}

}  // namespace demfem::coupling::launch
