// CPU vs CUDA with walls moved by their loads: a rigid box body (a pressure cell, a sleeper)
// landing on a sphere layer while spheres land on it, and a force-limited plate pressing a
// bed. The device runs one step per wait; the host moves these walls between the steps by
// the CPU step's code (docs/dem.md, GPU).

#include <catch2/catch.hpp>
#include <cmath>
#include <random>

#include "dem_test_util.hpp"
#include "demfem/dem/dem_system.hpp"

using namespace demfem::dem;
using namespace demfem::dem::test;

namespace {

constexpr double kDt = 1e-5;
constexpr double kPlateLimit = 0.03;  // N: the plate's max_force

// Left (x < 0): a 3 x 3 sphere layer (r 2 mm) on the floor z = 0, a free box body
// (14 x 14 x 4 mm, 7800 kg/m^3) 0.05 mm above it, and 2 x 2 spheres thrown down onto the box.
// Right (x > 0): a bed of 3 x 3 x 2 spheres under a plate drifting down at 0.5 m/s, limited
// to kPlateLimit (more than the bed's weight, so it presses it and slows down).
DemSystem body_and_plate_scene(DemBackendKind backend) {
  auto s = two_material_settings(1e8, 0.3, 2500.0, 0.4, 0.5, kDt, 0.02);
  s.gravity = {0, 0, -9.81};
  s.threads = 1;
  s.backend = backend;
  DemSystem sys(s);
  sys.add_wall(plane_mesh(0.08, 4));
  WallMesh box = box_mesh({-0.025, -0.007, 0.00425}, {-0.011, 0.007, 0.00825});
  box.name = "box body";
  const double a = 0.014, b = 0.014, c = 0.004, mass = 7800.0 * a * b * c;
  box.body.enabled = true;
  box.body.mass = mass;
  box.body.centre = {-0.018, 0.0, 0.00625};
  box.body.inertia = {mass * (b * b + c * c) / 12, mass * (a * a + c * c) / 12,
                      mass * (a * a + b * b) / 12};
  sys.add_wall(box);
  WallMesh plate = plane_mesh(0.016, 2);
  plate.name = "plate";
  for (std::size_t k = 0; k < plate.vertices.size(); k += 3)
    plate.vertices[k] += 0.018, plate.vertices[k + 2] = 0.0089;
  for (std::size_t k = 0; k < plate.triangles.size(); k += 3)
    std::swap(plate.triangles[k + 1], plate.triangles[k + 2]);  // normal down, to the bed
  plate.motion.kind = WallMotion::Kind::translation;
  plate.motion.velocity = {0, 0, -0.5};
  plate.motion.max_force = kPlateLimit;
  sys.add_wall(plate);
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<ParticleInit> p;
  for (int j = 0; j < 3; ++j)
    for (int i = 0; i < 3; ++i) {  // resting on the floor
      const double r = 0.002 + 1e-4 * u(rng);
      p.push_back(sphere({-0.0224 + 0.0044 * i + 1e-4 * u(rng), -0.0044 + 0.0044 * j, r}, r));
    }
  for (int j = 0; j < 2; ++j)
    for (int i = 0; i < 2; ++i)
      p.push_back(sphere({-0.0205 + 0.005 * i, -0.0025 + 0.005 * j + 2e-4 * u(rng), 0.0112},
                         0.002 + 1e-4 * u(rng), {0.05 * u(rng), 0, -0.5}));
  for (int k = 0; k < 2; ++k)
    for (int j = 0; j < 3; ++j)
      for (int i = 0; i < 3; ++i)
        p.push_back(
            sphere({0.0136 + 0.0044 * i + 1e-4 * u(rng), -0.0044 + 0.0044 * j, 0.002 + 0.0042 * k},
                   0.002 + 1e-4 * u(rng)));
  sys.add_particles(p);
  return sys;
}

struct RunResult {  // per advance()
  std::vector<RigidBodyState> body;
  std::vector<std::vector<double>> plate;  // vertices
  std::vector<std::array<double, 3>> plate_force;
};

// Four advance() calls of 100 substeps.
RunResult run(DemSystem& sys) {
  RunResult out;
  for (int c = 0; c < 4; ++c) {
    sys.advance(100);
    out.body.push_back(sys.body_state(1));
    out.plate.push_back(sys.wall_vertices(2));
    out.plate_force.push_back(sys.wall_force(2));
  }
  return out;
}

double gap(const std::array<double, 3>& a, const std::array<double, 3>& b) {
  return std::max({std::abs(a[0] - b[0]), std::abs(a[1] - b[1]), std::abs(a[2] - b[2])});
}
}  // namespace

TEST_CASE(
    "CPU and CUDA backends agree with rigid bodies moved by contacts and a force-limited "
    "wall",
    "[dem][gpu]") {
  // The CPU run first, checked to be a meaningful reference: the body is pushed by the
  // particles (at the end of some advance() it is hit from above, at another it is held by
  // the layer) and the plate's drift is held back by the bed (it ends above where a free
  // drift would have taken it, with a load).
  DemSystem cpu = body_and_plate_scene(DemBackendKind::cpu);
  const RunResult rc = run(cpu);
  REQUIRE(cpu.step_count() == 400);
  bool hit_from_above = false, held_from_below = false;
  for (const auto& b : rc.body)
    hit_from_above = hit_from_above || b.force[2] < 0.0,
    held_from_below = held_from_below || b.force[2] > 0.0;
  REQUIRE(hit_from_above);
  REQUIRE(held_from_below);
  const double free_z = 0.0089 - 0.5 * 400 * kDt;
  REQUIRE(rc.plate.back()[2] > free_z + 1e-4);
  REQUIRE(rc.plate_force.back()[2] > 0.0);
  if (!cuda_available()) {
    WARN("CPU-vs-CUDA comparison with bodies skipped: no CUDA device (or built without CUDA)");
    return;
  }
  // Tolerances, as the moving-wall comparison (round-off growth over 400 steps of colliding
  // spheres; the device rounds like the CPU, -fmad=false): particle positions within 1e-9 of
  // the radius; body centre, plate vertices within the same 2e-12 m; velocities within 1e-9
  // of the largest body / particle speed; wall loads within 1e-6 of the largest component.
  DemSystem gpu = body_and_plate_scene(DemBackendKind::cuda);
  const RunResult rg = run(gpu);
  CHECK(gpu.step_count() == cpu.step_count());
  // lists built on the device (beyond the host's first): the step that waits for a device
  // build before its forces moves the walls too
  CHECK(gpu.neighbour_rebuilds() > 2);
  CHECK(gpu.time() == cpu.time());
  CHECK(max_position_difference(cpu.particles(), gpu.particles()) < 1e-9 * 0.002);
  for (int c = 0; c < 4; ++c) {
    INFO("advance " << c);
    const RigidBodyState &bc = rc.body[c], &bg = rg.body[c];
    CHECK(gap(bc.centre, bg.centre) < 1e-9 * 0.002);
    const double speed = std::max(0.5, gap(bc.velocity, {0, 0, 0}));
    CHECK(gap(bc.velocity, bg.velocity) < 1e-9 * speed);
    CHECK(gap(bc.angular_velocity, bg.angular_velocity) <
          1e-9 * std::max(1.0, gap(bc.angular_velocity, {0, 0, 0})));
    const double fscale = std::max(1e-12, gap(bc.force, {0, 0, 0}));
    CHECK(gap(bc.force, bg.force) <= 1e-6 * fscale);
    REQUIRE(rc.plate[c].size() == rg.plate[c].size());
    for (std::size_t k = 0; k < rc.plate[c].size(); ++k)
      CHECK(std::abs(rc.plate[c][k] - rg.plate[c][k]) < 1e-9 * 0.002);
    const double pscale = std::max(1e-12, gap(rc.plate_force[c], {0, 0, 0}));
    CHECK(gap(rc.plate_force[c], rg.plate_force[c]) <= 1e-6 * pscale);
  }
}
