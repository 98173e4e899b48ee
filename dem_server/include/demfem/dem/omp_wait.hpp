#pragma once
// How the DEM's OpenMP threads wait at a barrier (issue 34, item 18).
//
// libgomp's threads spin at every barrier (GOMP_SPINCOUNT, by default 300,000 pause
// instructions: milliseconds on current CPUs) before they sleep. The DEM meets several
// barriers per step; on a machine where another process is busy (a user's workstation, a sweep
// that fills every core) the thread that arrives first burns the core that its partner, or the
// other process, needs: two DEM threads beside one busy process ran up to 10 times slower.
// kOmpSpinCount keeps a short spin (about 30 us on the 2-core AMD EPYC VM of the measurements:
// on a quiet machine the partner usually arrives within it) and then sleeps in the kernel
// (futex) until the partner arrives. Measured (docs/dem.md, "Threads beside other work"):
// a 1000-rock bed on 2 threads, 5-10 times the libgomp default's rate both alone and beside a
// busy process, and above the purely passive policy (no spin) on a quiet machine.
//
// libgomp reads its settings once, when it is loaded (before main), so setting them in main
// is too late: ensure_omp_wait_policy re-executes the program once with GOMP_SPINCOUNT set,
// unless the user has set GOMP_SPINCOUNT or OMP_WAIT_POLICY (then theirs holds). Call it first
// thing in main, before any thread or file is opened.

#include <string_view>

namespace demfem::dem {

/// The spin count the programs set (GOMP_SPINCOUNT; libgomp's default is 300000).
inline constexpr std::string_view kOmpSpinCount = "1000";

/// Re-executes the running program (/proc/self/exe, same arguments) with GOMP_SPINCOUNT =
/// kOmpSpinCount when neither GOMP_SPINCOUNT nor OMP_WAIT_POLICY is set; returns otherwise
/// (also when the re-execution fails: the program then runs with libgomp's defaults).
void ensure_omp_wait_policy(char** argv);

}  // namespace demfem::dem
