#pragma once
// The coupler's copies of the interface that every coupling scheme reads and writes: the FEM's
// interface state at t_i (P, V, A), where the FEM ends the step, where the DEM had the nodes,
// the forces each solver was last given, and the interface work each side has seen. It is the
// schemes' history: a checkpoint (coupler.h5, group "scheme") holds all of it, so that a
// restored run goes on with exactly the same numbers. Private to the coupling library.

#include <array>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

namespace demfem::coupling {

/// The interface buffer every scheme exchanges through; the concurrent scheme gives the FEM
/// buffer 1, so that the two solvers, stepping at the same time, never touch the same array.
constexpr std::uint32_t kSharedBuffer = 0;
constexpr std::uint32_t kConcurrentFemBuffer = 1;

/// @brief The schemes' interface history; arrays are node-major xyz (3 per node).
struct SchemeState {
  /// Starts at the mesh's reference positions, at rest, with no forces.
  explicit SchemeState(const std::vector<double>& reference_positions)
      : positions(reference_positions),
        velocities(reference_positions.size(), 0.0),
        accelerations(reference_positions.size(), 0.0),
        next_positions(reference_positions.size()),
        dem_start(reference_positions.size()),
        dem_end(reference_positions.size()),
        dem_force(reference_positions.size(), 0.0),
        dem_force_prev(reference_positions.size(), 0.0),
        fem_force(reference_positions.size(), 0.0),
        fem_force_prev(reference_positions.size(), 0.0) {}

  std::vector<double> positions;       ///< the FEM's interface positions at t_i, m
  std::vector<double> velocities;      ///< its velocities at t_i, m/s
  std::vector<double> accelerations;   ///< its accelerations at t_i, m/s^2
  std::vector<double> next_positions;  ///< where the FEM ends the step (t_i+1), m
  std::vector<double> dem_start;       ///< where the DEM's mesh starts the step, m
  std::vector<double> dem_end;         ///< where the DEM's mesh ends it, m
  std::vector<double> dem_force;       ///< the DEM's interface forces of the step, N
  std::vector<double> dem_force_prev;  ///< those of the step before, N
  std::vector<double> fem_force;       ///< the forces the FEM was given in the step, N
  std::vector<double> fem_force_prev;  ///< those of the step before, N
  double work_dem = 0.0;               ///< cumulative interface work as the DEM sees it, J
  double work_fem = 0.0;               ///< cumulative interface work as the FEM sees it, J
  bool settled = false;                ///< one_way_static: the DEM came to rest

  /// The arrays with their dataset names in coupler.h5, in the order they are written.
  std::array<std::pair<const char*, std::vector<double>*>, 10> arrays() {
    return {{{"scheme/positions", &positions},
             {"scheme/velocities", &velocities},
             {"scheme/accelerations", &accelerations},
             {"scheme/next_positions", &next_positions},
             {"scheme/dem_start", &dem_start},
             {"scheme/dem_end", &dem_end},
             {"scheme/dem_force", &dem_force},
             {"scheme/dem_force_prev", &dem_force_prev},
             {"scheme/fem_force", &fem_force},
             {"scheme/fem_force_prev", &fem_force_prev}}};
  }
};

}  // namespace demfem::coupling
