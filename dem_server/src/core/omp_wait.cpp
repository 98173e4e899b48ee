#include "demfem/dem/omp_wait.hpp"

#include <unistd.h>

#include <cstdlib>
#include <string>

namespace demfem::dem {

void ensure_omp_wait_policy(char** argv) {
  if (std::getenv("GOMP_SPINCOUNT") != nullptr || std::getenv("OMP_WAIT_POLICY") != nullptr) return;
  // Set even if the exec fails, so that a child the program starts inherits it.
  if (::setenv("GOMP_SPINCOUNT", std::string(kOmpSpinCount).c_str(), 0) != 0) return;
  ::execv("/proc/self/exe", argv);
}

}  // namespace demfem::dem
