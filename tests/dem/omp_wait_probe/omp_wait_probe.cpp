// Probe for the OpenMP wait policy (issue 34, item 18): starts as the DEM programs do
// (ensure_omp_wait_policy first), then two threads meet at 40 barriers where thread 0 is late
// by 5 ms each time (it sleeps), and prints the CPU time that thread 1 burnt waiting, with the
// spin count this process image was loaded with. test_omp_wait.cpp runs it.
#include <omp.h>
#include <time.h>

#include <cstdio>
#include <cstdlib>

#include "demfem/dem/omp_wait.hpp"

namespace {
double thread_cpu_ms() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return 1e3 * double(t.tv_sec) + 1e-6 * double(t.tv_nsec);
}
}  // namespace

int main(int argc, char** argv) {
  demfem::dem::ensure_omp_wait_policy(argv);
  (void)argc;
  double waiting_ms = 0.0;
  int threads = 0;
#pragma omp parallel num_threads(2)
  {
    if (omp_get_thread_num() == 0) threads = omp_get_num_threads();
    for (int k = 0; k < 40; ++k) {
      const timespec late{0, 5'000'000};
      if (omp_get_thread_num() == 0) nanosleep(&late, nullptr);
      const double c0 = thread_cpu_ms();
#pragma omp barrier
      if (omp_get_thread_num() == 1) waiting_ms += thread_cpu_ms() - c0;
#pragma omp barrier
    }
  }
  const char* spin = std::getenv("GOMP_SPINCOUNT");
  const char* policy = std::getenv("OMP_WAIT_POLICY");
  std::printf("GOMP_SPINCOUNT=%s OMP_WAIT_POLICY=%s threads=%d procs=%d waiting_cpu_ms=%.3f\n",
              spin ? spin : "(unset)", policy ? policy : "(unset)", threads, omp_get_num_procs(),
              waiting_ms);
  return 0;
}
