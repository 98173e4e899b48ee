#pragma once
// Open MPI's shared-memory files of an MPI job that the launcher started (an external DEM
// under `mpirun`, e.g. examples/liggghts_dem), removed once the job has ended.
//
// Why the launcher does it: Open MPI's shared-memory transport (btl vader; "sm" from Open
// MPI 5) backs each node-local rank with a file /dev/shm/vader_segment.<node>.<job>.<local
// rank> that mpirun removes when the job ends. When a rank is killed, mpirun aborts the job,
// ends the other ranks by signal and exits; whether it removed a blocked rank's file before
// it exits is a race (seen: rank 0 waiting in MPI_Reduce when rank 1 was SIGKILLed left its
// file in about one run of three). demfem promises that a run leaves nothing in /dev/shm,
// so the launcher notes the job of the external DEM's rank 0 (its pid comes with its Hello)
// and removes that job's files on this node after the DEM process has ended, on every path.

#include <set>
#include <string>
#include <vector>

#include <sys/types.h>

namespace demfem::coupling::launch {

/// @brief The Open MPI jobs whose shared-memory files are removed after they ended.
class MpiJobFiles {
 public:
  /// Notes the job of `rank`, a live process: its Open MPI job id from its environment
  /// (OMPI_MCA_ess_base_jobid, set by mpirun). Returns false (and notes nothing) when the
  /// process is gone or not an Open MPI rank started by mpirun (dem_server, a Python
  /// backend, srun's ranks: Slurm removes those).
  bool note_rank(pid_t rank);
  /// Removes the shared-memory files of every noted job that this user owns, in `folder`
  /// (/dev/shm). Call only once the job's processes have ended. Returns the names removed.
  std::vector<std::string> remove_left(const std::string& folder = "/dev/shm") const;
  /// The noted job ids.
  const std::set<unsigned long>& jobs() const { return jobs_; }

  /// Whether `name` is an Open MPI shared-memory file of job `job`:
  /// "vader_segment.<node>.<job, hex>.<local rank>" (4.x) or "sm_segment.…" (5.x).
  static bool is_job_file(const std::string& name, unsigned long job);

 private:
  std::set<unsigned long> jobs_;
};

}  // namespace demfem::coupling::launch
