// libFuzzer harness for a CSV particle file ([dem.load] file = "*.csv"): any bytes give loaded
// particles or a clean error. The common part: particle_harness.hpp.
#include "particle_harness.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  fuzz_particles::run(fuzz_particles::Target::csv, {data, size});
  return 0;
}
