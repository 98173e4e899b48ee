// CPU vs CUDA with frozen particles (DemSystem::freeze): a bed of spheres (or of rocks and
// spheres) falls onto a floor; then its lower part is frozen and the rest goes on falling onto
// it. The device holds the frozen particles in their poses after the drift and after the force
// pass (phys::hold_pose, as the CPU's hold_frozen), does not move a frozen body among
// polyhedra, and skips the pairs of two frozen polyhedra. Runs on the host under
// test_dem_cuda_emu; without a device only the CPU half runs.

#include <catch2/catch.hpp>
#include <cmath>
#include <random>

#include "dem_test_util.hpp"
#include "demfem/dem/dem_system.hpp"
#include "poly_test_util.hpp"

using namespace demfem::dem;
using namespace demfem::dem::test;

namespace {

// 96 bodies in 4 layers of 4 x 6 over a mesh floor, falling in a converging field: spheres of
// 2.2 mm, or (rocks) three quarters rounded boxes turned at random. Friction 0.5, rolling
// resistance 0.02.
DemSystem falling_bed(DemBackendKind backend, bool rocks) {
  auto s = two_material_settings(1e8, 0.3, 2500.0, 0.4, 0.5, 1e-5, 0.02);
  s.gravity = {0, 0, -9.81};
  s.threads = 1;
  s.backend = backend;
  DemSystem sys(s);
  sys.add_wall(plane_mesh(0.05, 4));
  const auto shape = sys.add_shape(box_shape(0.002, 0.0015, 0.001, 0.0004));
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<ParticleInit> p;
  for (int l = 0; l < 4; ++l)
    for (int j = 0; j < 4; ++j)
      for (int i = 0; i < 6; ++i) {
        const std::array<double, 3> x{-0.015 + 0.006 * i + 3e-4 * u(rng),
                                      -0.009 + 0.006 * j + 3e-4 * u(rng), 0.004 + 0.006 * l};
        const std::array<double, 3> v{-30 * x[0], -30 * x[1], -0.4};
        if (!rocks || (i + j + l) % 4 == 0)
          p.push_back(sphere(x, 0.0022, v, {20 * u(rng), 0, 0}));
        else
          p.push_back(poly(shape, x, random_quaternion(rng), v, {20 * u(rng), 20 * u(rng), 0}));
      }
  sys.add_particles(p);
  return sys;
}

// The bodies below 7 mm (the lowest layer and what has fallen to it).
std::vector<std::uint8_t> lower_part(const DemSystem& sys) {
  const ParticleState& st = sys.particles();
  std::vector<std::uint8_t> mask(st.size(), 0);
  for (std::size_t i = 0; i < st.size(); ++i) mask[i] = st.pz[i] < 0.007 ? 1 : 0;
  return mask;
}

}  // namespace

TEST_CASE("CPU and CUDA backends agree with frozen particles", "[dem][gpu][frozen]") {
  // Reference: the CPU backend (its freezing is checked against a held bed in
  // test_dem_scene_poly.cpp). 200 steps, the lower part frozen (the same mask for both, from
  // the CPU run), then 3 advances of 200 steps. Tolerances: positions 1e-9 of the sphere
  // radius (2.2 mm), as the other CPU-vs-CUDA tests; the frozen poses bit for bit (held, not
  // computed); the frozen particles' support (the force their holding supplies: a sum of
  // contact forces) within 1e-9 of its magnitude.
  const bool rocks = GENERATE(false, true);
  INFO("rocks: " << rocks);
  DemSystem cpu = falling_bed(DemBackendKind::cpu, rocks);
  cpu.advance(200);
  const std::vector<std::uint8_t> mask = lower_part(cpu);
  std::size_t held = 0;
  for (std::uint8_t m : mask) held += m;
  REQUIRE(held >= 10);
  REQUIRE(held + 10 <= mask.size());
  const ParticleState at_freeze = cpu.particles();
  cpu.freeze(mask);
  for (int c = 0; c < 3; ++c) cpu.advance(200);
  // the CPU reference is meaningful: the holding supplies a force, and the free part moved
  REQUIRE(std::abs(cpu.frozen_support()[2]) > 0.0);
  double moved = 0.0;
  for (std::size_t i = 0; i < mask.size(); ++i)
    if (mask[i] == 0) moved = std::max(moved, std::abs(cpu.particles().pz[i] - at_freeze.pz[i]));
  REQUIRE(moved > 1e-3);
  if (!cuda_available()) {
    WARN("CPU-vs-CUDA comparison with frozen particles skipped: no CUDA device (or no CUDA build)");
    return;
  }
  DemSystem gpu = falling_bed(DemBackendKind::cuda, rocks);
  gpu.advance(200);
  gpu.freeze(mask);
  for (int c = 0; c < 3; ++c) gpu.advance(200);
  const ParticleState& a = cpu.particles();
  const ParticleState& b = gpu.particles();
  REQUIRE(a.size() == b.size());
  CHECK(max_position_difference(a, b) < 1e-9 * 0.0022);
  CHECK(gpu.frozen_count() == held);
  int kept = 0;
  for (std::size_t i = 0; i < mask.size(); ++i)
    if (mask[i] != 0)
      kept += b.px[i] == at_freeze.px[i] && b.pz[i] == at_freeze.pz[i] &&
              b.qw[i] == at_freeze.qw[i] && b.vz[i] == 0.0 && b.wx[i] == 0.0;
  CHECK(kept == static_cast<int>(held));
  const auto sc = cpu.frozen_support(), sg = gpu.frozen_support();
  const double scale = std::max({std::abs(sc[0]), std::abs(sc[1]), std::abs(sc[2])});
  for (int d = 0; d < 3; ++d) CHECK(std::abs(sc[d] - sg[d]) <= 1e-9 * scale);
}
