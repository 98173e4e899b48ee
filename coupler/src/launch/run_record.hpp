#pragma once
// The run record: <output_dir>/run.json, written atomically by the launcher when a run starts
// (status "running") and again when it ends (completed, failed with the exit status and the
// reason, or interrupted by a signal). A finished run is told from one that is still going
// or was killed by it: "running" while the folder's lock (.demfem.lock) is free means the
// launcher was killed before it could write its end (docs/reliability.md, "Run record").

#include <sys/types.h>

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace demfem::coupling {

/// @brief What run.json holds.
struct RunRecord {
  std::string status = "running";        ///< running | completed | failed | interrupted
  int exit_code = -1;                    ///< the launcher's exit status (-1 while running)
  int signal = 0;                        ///< interrupted: the signal number
  std::string reason;                    ///< failed / interrupted: the message printed
  std::filesystem::path scene;           ///< absolute path of the scene file
  std::string scene_hash;                ///< scene_hash() of the scene and its overrides
  std::vector<std::string> overrides;    ///< command-line overrides of scene keys (KEY=VALUE)
  std::filesystem::path output_dir;      ///< absolute
  std::filesystem::path checkpoint_dir;  ///< absolute; empty without [checkpoint]
  std::string resumed_from;              ///< checkpoint folder of --resume ("" = fresh start)
  std::int64_t resumed_step = -1;
  std::vector<std::string> cleared;  ///< files of an earlier run removed at a fresh start
  std::string copied_from;           ///< resume into a new folder: the series' origin
  bool in_process = false;
  std::vector<std::string> command_line;
  std::string host;
  pid_t pid = 0;
  std::string dem_backend;  ///< "" = no DEM
  /// The FEM backend of this run ("fem", "modal", "rigid", "external"; "" = no FEM) and, for an
  /// external one, its command line.
  std::string fem_backend;
  std::vector<std::string> fem_command;
  std::vector<std::string> dem_command;  ///< dem.command of dem.backend = "external"
  int dem_threads = 0;          ///< threads of the DEM's CPU backend (dem.threads or OpenMP's)
  std::string omp_num_threads;  ///< the OMP_NUM_THREADS environment variable ("" = unset)
  unsigned hardware_threads = 0;
  std::string start_time;           ///< ISO 8601, UTC
  std::string end_time;             ///< ISO 8601, UTC ("" while running)
  double end_time_simulated = 0.0;  ///< run.end_time, s
  std::int64_t step_count = 0;      ///< coupling steps to reach it
  std::int64_t steps_done = -1;     ///< coupling steps done at the end (-1 = not known)
  double time_reached = -1.0;       ///< simulated time reached, s (-1 = not known)
};

/// @brief The record as JSON text.
std::string to_json(const RunRecord& record);

/// @brief Writes <dir>/run.json atomically (io::write_file_atomic).
void write_run_record(const std::filesystem::path& dir, const RunRecord& record);

/// @brief The status, pid, host and start time of the run.json in `dir`, if there is one.
struct RecordedRun {
  std::string status;
  pid_t pid = 0;
  std::string host;
  std::string start_time;
};
std::optional<RecordedRun> read_run_status(const std::filesystem::path& dir);

/// @brief The run a record says is `running` is still running: on this host, its pid is a
/// live demfem_run (or coupler) process that started no later than the record says (a pid
/// reused by a later process is not it). The folder lock says the same unless its file was
/// removed (rm -rf of the folder, a clean-up of dot files): then this is what still tells.
bool recorded_run_alive(const RecordedRun& run);

/// @brief FNV-1a 64 (16 hex digits) of the scene file's bytes followed by every override
/// ("\n" + KEY=VALUE), so that a change of either changes the hash. Throws naming the file.
std::string scene_hash(const std::filesystem::path& scene,
                       const std::vector<std::string>& overrides = {});

/// @brief Now, as "2024-05-01T12:00:00Z".
std::string utc_now();

/// @brief demfem's version, and the git commit (and whether the tree had uncommitted
/// changes) of the source it was built from ("unknown" outside a git checkout).
std::string demfem_version();
std::string demfem_git_commit();
bool demfem_git_dirty();

}  // namespace demfem::coupling
