#pragma once
// The coupling interface as output files (docs/coupling.md, "Output"): coupling.h5, the state
// at the end of the run, and the series coupling_NNNNNN.h5 at the run's output times with
// coupling.xdmf, the index that opens it in ParaView. Private to the coupling library.

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "demfem/interface/interface_mesh.hpp"

namespace demfem::coupling {

/// @brief The FEM interface at one time. Arrays are node-major xyz, 3 per node.
struct InterfaceState {
  const InterfaceMesh* mesh = nullptr;
  std::span<const double> positions;      ///< the FEM's interface positions, m
  std::span<const double> velocities;     ///< the coupler's copy of the FEM's velocities, m/s
  std::span<const double> forces;         ///< the DEM's forces on the nodes, N
  std::span<const double> dem_positions;  ///< where the DEM last had the nodes, m
};

/// @brief Writes `dir`/coupling.h5 (under a temporary name, renamed when complete): the
/// interface mesh and `state` under /interface, attributes scheme, steps and time on "/".
void write_coupling_h5(const std::filesystem::path& dir, const InterfaceState& state,
                       const std::string& scheme, std::int64_t steps, double time);

/// @brief coupling_NNNNNN.h5, one per output (numbered from 000000, the initial state), and
/// coupling.xdmf indexing them: the interface triangles on the reference positions with the
/// node arrays force, displacement, position, velocity and dem_position. Each step file is
/// written under a temporary name and renamed when complete, the index rewritten after it.
class InterfaceSeries {
 public:
  /// A new series removes the step files of an earlier run in `dir`; `resume` continues the
  /// series found there (a `.part` left by a crash is removed).
  InterfaceSeries(std::filesystem::path dir, const InterfaceMesh& mesh, bool resume);

  /// Appends `state` as the next step, labelled `time` (the nominal output time, s), of the
  /// state at `state_time` (s).
  void write(const InterfaceState& state, double time, double state_time);

  /// Drops the steps of states later than `time` (a checkpoint restored): files deleted,
  /// index rewritten first.
  void rollback(double time);

  std::size_t steps() const { return times_.size(); }
  std::optional<double> last_state_time() const {
    if (state_times_.empty()) return std::nullopt;
    return state_times_.back();
  }

 private:
  std::filesystem::path step_path(std::size_t k) const;
  void write_xdmf() const;

  std::filesystem::path dir_;
  std::size_t nodes_ = 0, triangles_ = 0;
  std::vector<double> times_, state_times_;
};

}  // namespace demfem::coupling
