#pragma once
// The particle ranges of the threads in the CPU force pass (DemSystem::Impl::balance, used by
// forces_and_kick() in dem_step.cpp), moved towards equal busy times. The bottom of a bed has
// more contacts per particle and the wall contacts, so equal counts leave one thread waiting
// (measured on the 20,000-sphere bed: 0.3 of its time). The result does not depend on the
// ranges (every sum has a fixed order; see forces_and_kick()), so timing them is safe for
// bitwise reproducibility.

#include <cstdint>
#include <vector>

namespace demfem::dem::detail {

struct ThreadBalance {
  std::vector<std::int64_t> split;                 // T + 1 range bounds
  std::vector<double> busy;                        // per thread: time before the barrier, s
  std::vector<std::vector<std::int64_t>> waiting;  // per thread: particles gathered after it

  // Equal ranges of `count` particles for `threads` threads, unless the ranges are set for
  // them already.
  void ensure(int threads, std::int64_t count);
  // New bounds from each thread's particles per second, halfway towards the balanced ones
  // (timings on a shared machine are noisy).
  void adapt();
};

}  // namespace demfem::dem::detail
