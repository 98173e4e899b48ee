// CPU vs CUDA with moving walls and the flexible coupled mesh: a translating plate, a
// rotating flap, an oscillating side wall and a flexible floor with prescribed kinematics.

#include <catch2/catch.hpp>
#include <cmath>
#include <random>

#include "dem_test_util.hpp"
#include "demfem/dem/dem_system.hpp"

using namespace demfem::dem;
using namespace demfem::dem::test;

namespace {
// A rectangle o + s u + t v (s, t in [0, 1]) of n x n cells, two triangles each.
WallMesh rectangle(std::array<double, 3> o, std::array<double, 3> u, std::array<double, 3> v,
                   int n) {
  WallMesh w;
  w.name = "rectangle";
  w.material = 1;
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i)
      for (int d = 0; d < 3; ++d) w.vertices.push_back(o[d] + u[d] * i / n + v[d] * j / n);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const int a = j * (n + 1) + i, b = a + 1, d = a + n + 1, e = d + 1;
      w.triangles.insert(w.triangles.end(), {a, b, e, a, e, d});
    }
  return w;
}

constexpr double kDt = 1e-5;

// 144 spheres (r 1.5-2.5 mm, friction and rolling resistance) thrown down onto a flexible
// floor z = 0 (6 x 6 cells, 6 cm), between a plate at x = -18 mm translating in +x
// (0.5 m/s for 3 ms), a flap at x = 13 mm rotating about its bottom edge towards the
// particles (-20 rad/s from t = 1 ms) and a side wall at y = 13 mm oscillating along y
// (0.3 mm, 250 Hz).
DemSystem moving_scene(DemBackendKind backend) {
  auto s = two_material_settings(1e8, 0.3, 2500.0, 0.4, 0.5, kDt, 0.02);
  s.gravity = {0, 0, -9.81};
  s.threads = 1;
  s.backend = backend;
  DemSystem sys(s);
  const WallMesh floor = plane_mesh(0.06, 6);
  demfem::InterfaceMesh im;
  im.reference_positions = floor.vertices;
  im.triangles = floor.triangles;
  sys.set_flexible_mesh(im, 1);
  WallMesh plate = rectangle({-0.018, -0.03, 0.0}, {0, 0.06, 0}, {0, 0, 0.05}, 3);
  plate.motion.kind = WallMotion::Kind::translation;
  plate.motion.velocity = {0.5, 0, 0};
  plate.motion.end_time = 0.003;
  sys.add_wall(plate);
  WallMesh flap = rectangle({0.013, -0.03, 0.0}, {0, 0.06, 0}, {0, 0, 0.05}, 3);
  flap.motion.kind = WallMotion::Kind::rotation;
  flap.motion.axis = {0, 1, 0};
  flap.motion.axis_point = {0.013, 0, 0};
  flap.motion.angular_velocity = -20.0;
  flap.motion.start_time = 0.001;
  sys.add_wall(flap);
  WallMesh side = rectangle({-0.03, 0.0131, 0.0}, {0.06, 0, 0}, {0, 0, 0.05}, 3);
  side.motion.kind = WallMotion::Kind::sinusoid;
  side.motion.axis = {0, 1, 0};
  side.motion.amplitude = 3e-4;
  side.motion.frequency = 250.0;
  sys.add_wall(side);
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<ParticleInit> p;
  for (int k = 0; k < 4; ++k)
    for (int j = 0; j < 6; ++j)
      for (int i = 0; i < 6; ++i) {
        const double x = -0.0156 + 0.0052 * i + 2e-4 * u(rng);
        const double y = -0.0156 + 0.0052 * j + 2e-4 * u(rng);
        p.push_back(sphere({x, y, 0.0027 + 0.0052 * k}, 0.002 + 0.0005 * u(rng),
                           {0.1 * u(rng), 0.1 * u(rng), -0.5 + 0.3 * u(rng)}, {10 * u(rng), 0, 0}));
      }
  sys.add_particles(p);
  return sys;
}

struct RunResult {  // per advance()
  std::vector<std::vector<double>> flex_forces;
  std::vector<double> flex_max_overlap;
  std::vector<std::array<std::array<double, 3>, 3>> wall_forces;  // last step, per wall
};

// Four advance() calls of 100 substeps (last substep / average alternately); before each,
// the floor gets new kinematics: rising at 0.1 m/s, accelerating by 50 x (m/s^2, x in m),
// so that it tilts. The node state is integrated with the same formula the DEM uses.
RunResult run_moving_scene(DemSystem& sys) {
  RunResult out;
  const WallMesh floor = plane_mesh(0.06, 6);
  const std::size_t nn = floor.vertices.size() / 3;
  std::vector<double> x = floor.vertices, v(3 * nn, 0.0), a(3 * nn, 0.0);
  for (std::size_t k = 0; k < nn; ++k) v[3 * k + 2] = 0.1, a[3 * k + 2] = 50.0 * x[3 * k];
  for (int c = 0; c < 4; ++c) {
    sys.set_flexible_kinematics(x, v, a);
    sys.advance(100, c % 2 ? demfem::ForceMode::average : demfem::ForceMode::last_substep);
    std::vector<double> f(3 * nn);
    sys.flexible_forces(f);
    out.flex_forces.push_back(f);
    out.flex_max_overlap.push_back(sys.flexible_max_overlap());
    out.wall_forces.push_back({sys.wall_force(0), sys.wall_force(1), sys.wall_force(2)});
    const double tau = 100 * kDt;
    for (std::size_t k = 0; k < 3 * nn; ++k) {
      x[k] += v[k] * tau + 0.5 * a[k] * tau * tau;
      v[k] += a[k] * tau;
    }
  }
  return out;
}

// A plate sweeping at 2 m/s through a row of resting spheres without gravity: the particles do
// not move before the plate arrives, so only the wall part of the rebuild rule
// (particle + wall displacement > skin) brings the plate's triangles into their candidate lists.
DemSystem sweep_scene(DemBackendKind backend) {
  auto s = two_material_settings(1e8, 0.3, 2500.0, 0.5, 0.3, kDt);
  s.backend = backend;
  DemSystem sys(s);
  WallMesh plate = rectangle({-0.01, -0.01, -0.01}, {0, 0.02, 0}, {0, 0, 0.02}, 2);
  plate.motion.kind = WallMotion::Kind::translation;
  plate.motion.velocity = {2.0, 0, 0};
  sys.add_wall(plate);
  std::vector<ParticleInit> p;
  for (int i = 0; i < 5; ++i) p.push_back(sphere({-0.004 + 0.0045 * i, 0.001 * i, 0}, 0.002));
  sys.add_particles(p);
  return sys;
}

double max_abs(const std::vector<double>& v) {
  double m = 0.0;
  for (double x : v) m = std::max(m, std::abs(x));
  return m;
}
}  // namespace

TEST_CASE("CPU and CUDA backends agree with moving walls and a flexible mesh", "[dem][gpu]") {
  // The CPU run is checked first to be a meaningful reference: every moving wall is touched
  // at the end of some advance() (contacts come and go), the floor at the end of each.
  DemSystem cpu = moving_scene(DemBackendKind::cpu);
  const RunResult rc = run_moving_scene(cpu);
  REQUIRE(cpu.step_count() == 400);
  for (int w = 0; w < 3; ++w) {
    INFO("wall " << w);
    double touched = 0.0;
    for (const auto& f : rc.wall_forces) touched += std::abs(f[w][0]) + std::abs(f[w][2]);
    REQUIRE(touched > 0.0);
  }
  for (int c = 0; c < 4; ++c) {
    INFO("advance " << c);
    REQUIRE(max_abs(rc.flex_forces[c]) > 0.0);
    REQUIRE(rc.flex_max_overlap[c] > 0.0);
  }
  DemSystem cpu_sweep = sweep_scene(DemBackendKind::cpu);
  cpu_sweep.advance(300);  // the plate moves 6 mm and pushes the first sphere
  REQUIRE(cpu_sweep.particles().vx[0] > 0.1);
  if (!cuda_available()) {
    WARN(
        "CPU-vs-CUDA comparison with moving walls skipped: no CUDA device (or built without "
        "CUDA)");
    return;
  }
  // Tolerances (round-off growth over 400 steps of a colliding packing; the device rounds
  // like the CPU (-fmad=false) except for sin/cos of the rotating and oscillating walls
  // (CUDA: <= 2 ulp) and the order of the atomic sums of the node forces):
  //   particle positions: 1e-9 of the particle radius (as the static-wall comparison);
  //   flexible node positions: 1e-15 m (the same formula on the same doubles);
  //   rigid wall vertices: 1e-15 m (sin/cos differ by a few ulp of 1);
  //   node forces and wall forces: 1e-6 of the largest node / wall force component.
  //   the sweep: positions within 1e-9 of the radius.
  DemSystem gpu_sweep = sweep_scene(DemBackendKind::cuda);
  gpu_sweep.advance(300);
  for (std::size_t i = 0; i < 5; ++i) {
    INFO("sweep particle " << i);
    CHECK(std::abs(gpu_sweep.particles().px[i] - cpu_sweep.particles().px[i]) < 1e-9 * 0.002);
  }
  DemSystem gpu = moving_scene(DemBackendKind::cuda);
  const RunResult rg = run_moving_scene(gpu);
  CHECK(gpu.step_count() == cpu.step_count());
  CHECK(gpu.time() == cpu.time());
  const auto& a = cpu.particles();
  const auto& b = gpu.particles();
  REQUIRE(a.size() == b.size());
  const double worst = max_position_difference(a, b);
  CHECK(worst < 1e-9 * 0.002);
  const auto xc = cpu.flexible_positions(), xg = gpu.flexible_positions();
  REQUIRE(xc.size() == xg.size());
  for (std::size_t k = 0; k < xc.size(); ++k) CHECK(std::abs(xc[k] - xg[k]) <= 1e-15);
  for (std::int32_t w = 0; w < 3; ++w) {
    INFO("wall " << w);
    const auto vc = cpu.wall_vertices(w), vg = gpu.wall_vertices(w);
    REQUIRE(vc.size() == vg.size());
    for (std::size_t k = 0; k < vc.size(); ++k) CHECK(std::abs(vc[k] - vg[k]) <= 1e-15);
  }
  for (int c = 0; c < 4; ++c) {
    INFO("advance " << c);
    const double scale = max_abs(rc.flex_forces[c]);
    for (std::size_t k = 0; k < rc.flex_forces[c].size(); ++k)
      CHECK(std::abs(rc.flex_forces[c][k] - rg.flex_forces[c][k]) <= 1e-6 * scale);
    CHECK(rg.flex_max_overlap[c] == Approx(rc.flex_max_overlap[c]).epsilon(1e-6));
    for (int w = 0; w < 3; ++w) {
      INFO("wall " << w);
      const auto& fc = rc.wall_forces[c][w];
      const auto& fg = rg.wall_forces[c][w];
      const double wscale = std::max({std::abs(fc[0]), std::abs(fc[1]), std::abs(fc[2])});
      for (int d = 0; d < 3; ++d) CHECK(std::abs(fc[d] - fg[d]) <= 1e-6 * wscale);
    }
  }
}
