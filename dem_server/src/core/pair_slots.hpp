#pragma once
// The per-pair slots of the CPU force pass (DemSystem::Impl::slots): one entry per pair of the
// neighbour list, in list order (pair p holds 3 values at 3p). The pair kernels write a pair's
// force and torques here and the gather sums them per particle in a fixed order, so that no
// two threads add into the same particle (dem_system_impl.hpp, step structure). The springs
// and the narrow phase's caches belong to the contact and are carried over when the list is
// refiltered or rebuilt (neighbour_list.cpp); the rest is rewritten every force pass.

#include <cstdint>
#include <vector>

namespace demfem::dem::detail {

struct PairSlots {
  // the contact's history (saved with the state: "shear", "rhist")
  std::vector<double> shear;            ///< tangential spring displacement, m (friction)
  std::vector<double> rolling_history;  ///< rolling-torque history, N m (rolling resistance)
  // this force pass
  std::vector<double> force;  ///< force on i, N (on j: minus it)
  /// sphere pairs: n × F_t, the tangential torque per unit radius (N; times r_i or r_j);
  /// systems with polyhedra: the torque on i, N m
  std::vector<double> torque;
  std::vector<double> torque_j;        ///< systems with polyhedra: the torque on j, N m
  std::vector<double> rolling_torque;  ///< rolling-resistance torque on i, N m (on j: minus it)
  // the narrow phase's caches (systems with polyhedra; saved with the state: "sepaxis",
  // "features", as a restored run must start each pair's narrow phase where it left off)
  std::vector<double> separating_axis;         ///< unit axis i -> j, or zero
  std::vector<std::int32_t> closest_features;  ///< 6 per pair: GJK warm start
};

}  // namespace demfem::dem::detail
