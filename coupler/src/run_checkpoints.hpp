#pragma once
// The checkpoints of a coupling run (docs/reliability.md): when one is due, taking one (each
// solver's part, then the coupler's coupler.h5, then the commit), and bringing every process
// back to one: the solvers, the scheme's history and the output series. coupler.h5 holds the
// run's totals, the scheme's state (SchemeState, the implicit scheme's accelerator), the
// interface buffers as the solvers left them, and how far the output series got. Private to
// the coupling library.

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "run_session.hpp"

namespace demfem::coupling {

/// @brief The checkpoints of one run, in checkpoint_directory().
class RunCheckpoints {
 public:
  explicit RunCheckpoints(RunSession& session);

  /// [checkpoint] asks for one after `steps` steps (every_steps, every_sim_time,
  /// every_wall_time), and the last one is not of that step.
  bool due(std::int64_t steps) const;
  /// Writes the checkpoint after `steps` coupling steps; a solver failing here is a
  /// SolverFailure like one failing in a step.
  void take(std::int64_t steps);
  /// Every process back to the checkpoint in `folder`: both solvers, the coupler's scheme
  /// history and the CSV rows. `resume`: the checkpoint of --resume (its wall times are the
  /// earlier sessions'), not a rollback within this session. Returns the step to continue from.
  std::int64_t restore(const std::filesystem::path& folder, bool resume);

  /// The newest committed checkpoint (none yet: empty) and its step (-1).
  const std::optional<std::filesystem::path>& last() const { return last_; }
  std::int64_t last_step() const { return last_step_; }
  const std::filesystem::path& directory() const { return directory_; }

 private:
  void save_coupler(const std::filesystem::path& file, std::int64_t steps) const;
  void save_buffers(io::H5File& h5) const;
  void load_coupler(const std::filesystem::path& file, std::int64_t steps, bool resume);
  void load_buffers(const io::H5File& h5, const std::filesystem::path& file);

  RunSession& run_;
  std::filesystem::path directory_;
  std::vector<std::string> parts_;
  std::optional<std::filesystem::path> last_;
  std::int64_t last_step_ = -1;
  RunClock::time_point last_wall_ = RunClock::now();
  std::int64_t restored_rows_ = 0;  // coupling.csv rows of the checkpoint being restored
};

}  // namespace demfem::coupling
