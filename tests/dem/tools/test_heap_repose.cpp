// Angle of repose of a poured heap grows with the particle-particle friction (thesis section
// 5.3: 15 degrees at mu = 0.17, about 22 degrees at mu = 1.0 for 3-5 mm spheres without
// rolling friction). A small quasi-2D version for ctest: spheres poured from a small region
// onto the floor of a box whose side walls are 4 diameters apart; stiffness reduced (E = 1 MPa)
// so that dt can be 5e-5 s (0.17 of the Rayleigh time step). Rolling friction acts only
// between particles and walls, so that particles reaching the floor stop rolling. The narrow slot
// and the small heap make the angles differ from the thesis's 3D chamber; the test checks the trend
// and a plausible range.

#include <catch2/catch.hpp>

#include <chrono>
#include <cmath>
#include <iostream>

#include "demfem/dem/insertion.hpp"
#include "demfem/dem/sensors.hpp"
#include "demfem/dem/stl_reader.hpp"

using namespace demfem::dem;

namespace {

struct HeapResult {
  ReposeResult repose;
  std::size_t particles = 0;
  double kinetic_energy = 0.0;
};

HeapResult pour_heap(double friction) {
  DemSettings s;
  s.dt = 5e-5;
  s.threads = 1;
  s.materials = {{"grain", 1e6, 0.3, 1242.0}, {"steel", 1e8, 0.3, 7850.0}};
  const MaterialPair pp{friction, 0.4, 0.0};
  // Walls: friction and rolling friction high so that the heap's toe does not slide or roll.
  const MaterialPair pw{0.5, 0.4, 0.2};
  s.pairs = {pp, pw, pw, pw};
  DemSystem sys(s);
  const double width = 0.016;
  WallMesh box = make_box_mesh({-0.15, 0, 0}, {0.15, width, 0.2}, true);
  box.material = 1;
  sys.add_wall(box);

  RandomInsertion q;
  q.region = {{-0.012, 0.0, 0.07}, {0.012, width, 0.09}};
  q.sizes = SizeDistribution::uniform(0.003, 0.005);
  q.count = 40;
  q.density = 1242.0;
  q.velocity = {0, 0, -0.3};
  // Pour: 40 particles every 0.04 s for 0.48 s (480 particles), then 0.3 s of settling.
  const std::int64_t steps_per_batch = 800;
  for (int batch = 0; batch < 12; ++batch) {
    q.seed = 100 + std::uint64_t(batch);
    const auto p = insert_random(q, &sys.particles());
    sys.add_particles(p);
    sys.advance(steps_per_batch);
  }
  sys.advance(6000);
  HeapResult r;
  r.particles = sys.particle_count();
  r.kinetic_energy = sys.kinetic_energy();
  ReposeOptions o;
  o.centre = {0.0, width / 2};
  o.planar = true;
  o.bin_width = 0.006;
  r.repose = angle_of_repose(sys.particles(), o);
  return r;
}

}  // namespace

TEST_CASE("angle of repose of a poured heap grows with friction", "[repose][slow]") {
  const auto t0 = std::chrono::steady_clock::now();
  const HeapResult low = pour_heap(0.17);
  const HeapResult high = pour_heap(1.0);
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::cout << "heap: mu 0.17 -> " << low.repose.angle_deg << " deg (R " << low.repose.heap_radius
            << " m, " << low.repose.fitted_bins << " bins, KE " << low.kinetic_energy
            << " J); mu 1.0 -> " << high.repose.angle_deg << " deg (R " << high.repose.heap_radius
            << " m, " << high.repose.fitted_bins << " bins, KE " << high.kinetic_energy << " J); "
            << secs << " s\n";
  CHECK(low.particles == 480);
  // Settled: kinetic energy far below the potential energy scale (480 * 4e-5 kg * g * 1 cm = 2e-3
  // J; 1 % of it).
  CHECK(low.kinetic_energy < 2e-5);
  CHECK(high.kinetic_energy < 2e-5);
  CHECK(high.repose.angle_deg > low.repose.angle_deg + 3.0);
  CHECK(low.repose.angle_deg > 5.0);
  CHECK(high.repose.angle_deg < 45.0);
}
