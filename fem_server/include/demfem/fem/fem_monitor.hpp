#pragma once
// [fem.monitor]: what the structure does between field outputs, sampled after every step of
// a run. Probes give the displacement of chosen points (the nearest mesh node of each: the
// deflection at a measurement position, thesis fig. 5.4) and the total interface force the
// particles exert; a time window gives the time-mean of the interface forces and of the
// displacement field, from which a static solve checks the dynamic result (fem_static_check):
//   <dir>/fem_monitor.csv  time, <probe>_ux, <probe>_uy, <probe>_uz (m) per probe,
//                          force_x, force_y, force_z (N, sum of the interface forces)
//   <dir>/fem_mean.h5      written when the window ends: /interface_force (interface nodes
//                          x 3, N), /displacement (mesh nodes x 3, m), /interface_mesh_nodes;
//                          attributes start, end (s), duration (s, the time averaged), steps
// Time means weight each step's values by its dt (the force held during the step and the
// displacement at its end, as the Bossak step uses them).

#include <array>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "demfem/fem/fem_problem.hpp"
#include "demfem/scene/scene_reader.hpp"

namespace demfem::io {
class CsvWriter;
class H5File;
}  // namespace demfem::io

namespace demfem::fem {

class FemSolver;

/// @brief A measuring point: the mesh node nearest to `point`.
struct FemProbe {
  std::string name;
  std::array<double, 3> point{};  ///< m, as given
  std::int32_t node = -1;         ///< nearest mesh node
  double distance = 0.0;          ///< from point to the node, m
};

/// @brief [fem.monitor].
struct FemMonitorSettings {
  bool enabled = false;
  double interval = 0.0;  ///< s; 0 = every step
  std::vector<FemProbe> probes;
  bool mean = false;  ///< a mean window is given
  double mean_start = 0.0, mean_end = 0.0;
};

/// @brief Reads [fem.monitor] against the mesh (probe nodes are found here).
FemMonitorSettings read_fem_monitor(const scene::Table& monitor, const Mesh& mesh);

/// @brief Writes fem_monitor.csv and fem_mean.h5 (above) into `dir`.
class FemMonitor {
 public:
  /// `resume`: continue the series in `dir` (a restarted solver; restore() then cuts it back).
  FemMonitor(std::filesystem::path dir, FemMonitorSettings settings, bool resume = false);
  ~FemMonitor();
  FemMonitor(const FemMonitor&) = delete;
  FemMonitor& operator=(const FemMonitor&) = delete;

  /// After a step: `forces` are the interface forces the step used.
  void sample(const FemSolver& solver, std::span<const double> forces);
  /// The window's accumulators and schedule into `group` of a checkpoint file.
  void save(io::H5File& file, const std::string& group) const;
  /// Back to a checkpoint at solver time `time`: the accumulators of the file (when it has
  /// the group), CSV rows after `time` dropped.
  void restore(const io::H5File& file, const std::string& group, double time);

  std::filesystem::path csv_path() const { return dir_ / "fem_monitor.csv"; }
  std::filesystem::path mean_path() const { return dir_ / "fem_mean.h5"; }
  const FemMonitorSettings& settings() const { return settings_; }

 private:
  void write_mean(const FemSolver& solver) const;
  std::filesystem::path dir_;
  FemMonitorSettings settings_;
  std::unique_ptr<io::CsvWriter> csv_;
  std::vector<double> times_;  // of the CSV rows
  double next_ = 0.0;          // next sample time
  double last_time_ = 0.0;     // solver time of the previous sample() call
  bool started_ = false;
  // window
  std::vector<double> sum_force_, sum_u_;
  double weight_ = 0.0;
  std::int64_t steps_ = 0;
  bool mean_written_ = false;
};

}  // namespace demfem::fem
