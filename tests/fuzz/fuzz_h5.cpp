// libFuzzer harness for HDF5 particle files: a particle snapshot and a DEM state loaded by
// [dem.load] (with and without its contact history) and a checkpoint's DEM state. The first
// byte picks which, the rest is a raw file or a recipe of mutations of a valid one
// (particle_harness.hpp).
#include "particle_harness.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using fuzz_particles::Target;
  if (size == 0) return 0;
  const Target targets[] = {Target::raw_snapshot, Target::raw_state,     Target::snapshot,
                            Target::state,        Target::state_history, Target::checkpoint};
  fuzz_particles::run(targets[data[0] % 6], {data + 1, size - 1});
  return 0;
}
