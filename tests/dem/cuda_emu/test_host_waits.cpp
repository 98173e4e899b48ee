// What the CUDA backend costs the host per advance() (one coupling step), counted by the
// runtime double (cuda_runtime.h, emu_counters): the state, the list and the step's graph stay
// on the device from one advance() to the next, and the host waits for the device once per
// advance() while the list lasts. Only in test_dem_cuda_emu (it reads the double's counters).

#include <catch2/catch.hpp>
#include <random>

#include <cuda_runtime.h>  // the double (tests/dem/cuda_emu): its counters

#include "dem_test_util.hpp"
#include "demfem/dem/dem_system.hpp"

using namespace demfem::dem;
using namespace demfem::dem::test;

namespace {

// 108 spheres of 2 mm in columns 4 mm apart (touching side by side), 3 layers 0.3 mm apart
// above a mesh floor, with small random sideways velocities: strongly damped (restitution
// 0.1) they fall (a list build or two) and settle within the first advances and rest after,
// so that later advances need no new list. Friction 0.5, rolling resistance 0.02, skin 1 mm.
DemSystem resting_bed(DemBackendKind backend) {
  auto s = two_material_settings(1e8, 0.3, 2500.0, 0.1, 0.5, 1e-5, 0.02);
  s.gravity = {0, 0, -9.81};
  s.threads = 1;
  s.backend = backend;
  s.skin = 1e-3;
  s.list_skin = 1.0;
  DemSystem sys(s);
  sys.add_wall(plane_mesh(0.05, 4));
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<ParticleInit> p;
  for (int k = 0; k < 3; ++k)
    for (int j = 0; j < 6; ++j)
      for (int i = 0; i < 6; ++i)
        p.push_back(sphere({-0.01 + 0.004 * i, -0.01 + 0.004 * j, 0.0023 + 0.0043 * k}, 0.002,
                           {1e-3 * u(rng), 1e-3 * u(rng), 0.0}));
  sys.add_particles(p);
  return sys;
}

struct AdvanceCost {
  long waits = 0, captures = 0;
  unsigned long long bytes_to_device = 0;
  std::int64_t builds = 0;
};

AdvanceCost advance_counted(DemSystem& sys, std::int64_t steps) {
  const EmuCounters before = emu_counters;
  const std::int64_t builds = sys.neighbour_rebuilds();
  sys.advance(steps);
  return AdvanceCost{emu_counters.host_waits - before.host_waits,
                     emu_counters.captures - before.captures,
                     emu_counters.bytes_to_device - before.bytes_to_device,
                     sys.neighbour_rebuilds() - builds};
}

}  // namespace

TEST_CASE("The device keeps the state between advances and the host waits once per advance",
          "[dem][gpu][sync]") {
  // 16 advances of 600 steps (more than the 256 steps the host once read a flag after), the
  // CPU twin alongside; at advance 8 both go back to the save point of advance 4 (the host
  // changed the state: the device must take it). An advance without a list build: exactly
  // one wait, no graph captured, and nothing copied to the device but the clock (16 bytes);
  // with builds: one wait to end each run, the held-back step's and the list build's own, so
  // at most 1 + 3 per build (the build's reads of its counts go through Thrust, which this
  // double does not count: two more per build on a device). Positions: within 1e-9 of the
  // radius of the CPU run's (as the other CPU-vs-CUDA tests).
  DemSystem cpu = resting_bed(DemBackendKind::cpu);
  DemSystem gpu = resting_bed(DemBackendKind::cuda);
  const std::size_t n = gpu.particle_count();
  DemStateCopy cpu_copy, gpu_copy;
  int quiet = 0, busy = 0;
  for (int a = 0; a < 16; ++a) {
    INFO("advance " << a);
    if (a == 8) {
      cpu.restore_state(cpu_copy);
      gpu.restore_state(gpu_copy);
    }
    cpu.advance(600);
    const AdvanceCost c = advance_counted(gpu, 600);
    INFO("waits " << c.waits << ", captures " << c.captures << ", bytes to the device "
                  << c.bytes_to_device << ", list builds " << c.builds);
    if (a == 0 || a == 8) {  // the state uploaded (at least positions, velocities, spins)
      CHECK(c.bytes_to_device >= 9 * 8 * n);
    } else if (c.builds == 0) {
      ++quiet;
      CHECK(c.waits == 1);
      CHECK(c.captures == 0);
      CHECK(c.bytes_to_device <= 16);
    } else {
      ++busy;
      CHECK(c.waits <= 1 + 3 * static_cast<long>(c.builds));
      CHECK(c.bytes_to_device <= 16 + 16 * static_cast<unsigned long long>(c.builds));
    }
    if (a == 4) {
      cpu.save_state(cpu_copy);
      gpu.save_state(gpu_copy);
    }
    CHECK(max_position_difference(cpu.particles(), gpu.particles()) < 1e-9 * 0.002);
  }
  // both kinds of advance were seen (the bed moved early, rested late)
  CHECK(quiet >= 3);
  CHECK(busy >= 1);
  CHECK(gpu.max_overlap() > 0.0);
  CHECK(gpu.max_overlap() == Approx(cpu.max_overlap()).epsilon(1e-9));
}

TEST_CASE("A run of device steps that reaches its batch cap without a list build runs on",
          "[dem][gpu][sync]") {
  // Two spheres thrown at 1 m/s onto a floor (no gravity, restitution 0.1, skin 1 mm): while
  // they fall the list is built every ~50 steps, so a run is capped at 256 steps; after the
  // bounce (~0.09 m/s) a list lasts ~550 steps, so runs end at the cap with no build due.
  // Such a run must not be taken for one that stopped for a build (a held-back step whose
  // drift was never done: the positions fell behind the CPU's by a drift per run).
  // Positions, velocities and list builds as the CPU's (positions within 1e-9 of the radius).
  auto make = [](DemBackendKind backend) {
    auto s = two_material_settings(1e8, 0.3, 2500.0, 0.1, 0.0, 1e-5, 0.02);
    s.threads = 1;
    s.backend = backend;
    s.skin = 1e-3;
    s.list_skin = 1.0;
    DemSystem sys(s);
    sys.add_wall(plane_mesh(0.05, 4));
    const std::vector<ParticleInit> p{sphere({0, 0, 0.012}, 0.002, {0, 0, -1.0}),
                                      sphere({0.01, 0, 0.012}, 0.002, {0, 0, -1.0})};
    sys.add_particles(p);
    return sys;
  };
  DemSystem cpu = make(DemBackendKind::cpu), gpu = make(DemBackendKind::cuda);
  for (int a = 0; a < 4; ++a) {
    INFO("advance " << a);
    cpu.advance(1500);
    gpu.advance(1500);
    CHECK(gpu.time() == cpu.time());
    CHECK(gpu.neighbour_rebuilds() == cpu.neighbour_rebuilds());
    CHECK(max_position_difference(cpu.particles(), gpu.particles()) < 1e-9 * 0.002);
    CHECK(std::abs(gpu.particles().vz[0] - cpu.particles().vz[0]) < 1e-9);
  }
  CHECK(cpu.particles().vz[0] > 0.05);  // bounced: the slow phase was reached
}
