// CPU vs CUDA with dilated polyhedra: rocks and spheres colliding on a mesh floor and against
// a flexible floor. Skips without a GPU; runs on the host under test_dem_cuda_emu (the kernels
// against a test double of the CUDA runtime).

#include <catch2/catch.hpp>
#include <cmath>
#include <random>

#include "dem_test_util.hpp"
#include "demfem/dem/dem_system.hpp"
#include "poly_test_util.hpp"

using namespace demfem::dem;
using namespace demfem::dem::test;

namespace {
// 96 particles: rocks of three hulls (r_d 0.4 mm, random orientations and spins) and spheres,
// falling in a converging field onto a mesh floor (rigid, or the flexible coupled mesh with
// prescribed kinematics); friction 0.5, rolling resistance 0.02 between spheres.
DemSystem poly_scene(DemBackendKind backend, bool flexible, MaterialPair::PolyLaw law) {
  auto s = two_material_settings(1e8, 0.3, 2500.0, 0.4, 0.5, 1e-5, 0.02);
  for (auto& pair : s.pairs) pair.poly_law = law;
  s.gravity = {0, 0, -9.81};
  s.threads = 1;
  s.backend = backend;
  DemSystem sys(s);
  std::mt19937_64 rng(21);
  for (int k = 0; k < 3; ++k)
    sys.add_shape(random_rock(rng, 8 + 2 * k, 0.0025, 0.002, 0.0015, 0.0004));
  sys.add_shape(box_shape(0.002, 0.0015, 0.001, 0.0004));
  const WallMesh floor = plane_mesh(0.05, 4);
  if (flexible) {
    demfem::InterfaceMesh im;
    im.reference_positions = floor.vertices;
    im.triangles = floor.triangles;
    sys.set_flexible_mesh(im, 1);
  } else {
    sys.add_wall(floor);
  }
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<ParticleInit> p;
  for (int l = 0; l < 4; ++l)
    for (int j = 0; j < 4; ++j)
      for (int i = 0; i < 6; ++i) {
        const std::array<double, 3> x{-0.015 + 0.006 * i + 3e-4 * u(rng),
                                      -0.009 + 0.006 * j + 3e-4 * u(rng), 0.004 + 0.006 * l};
        const std::array<double, 3> v{-50 * x[0], -50 * x[1], -0.4 - 30 * (x[2] - 0.013)};
        const std::array<double, 3> w{20 * u(rng), 20 * u(rng), 20 * u(rng)};
        if ((i + j + l) % 4 == 0) {
          p.push_back(sphere(x, 0.0022, v, w));
        } else {
          ParticleInit q;
          q.shape = ParticleShape::polyhedron;
          q.shape_id = (i + 2 * j + l) % 4;
          q.position = x;
          q.velocity = v;
          q.angular_velocity = w;
          q.orientation = random_quaternion(rng);
          p.push_back(q);
        }
      }
  sys.add_particles(p);
  return sys;
}
}  // namespace

TEST_CASE("CPU and CUDA backends agree with dilated polyhedra", "[dem][gpu][poly]") {
  // Reference: the CPU backend. 96 rocks and spheres, 600 steps onto a rigid floor and onto a
  // flexible floor (4 advances of 150 substeps, the mesh rising at 0.05 m/s). Tolerances
  // (round-off growth over 600 steps of a colliding packing; the device rounds like the CPU,
  // -fmad=false, except the sin/cos of large rotations): positions 1e-9 of the rock size
  // (5 mm), orientations 1e-9; flexible node forces 1e-6 of the largest (the device sums them
  // with atomics). Both contact laws of polyhedra (poly_law): the smooth law's terms run in
  // the same kernels.
  const auto law = GENERATE(MaterialPair::PolyLaw::pressure_centre, MaterialPair::PolyLaw::smooth);
  INFO("smooth law: " << (law == MaterialPair::PolyLaw::smooth));
  for (bool flexible : {false, true}) {
    INFO("flexible floor: " << flexible);
    DemSystem cpu = poly_scene(DemBackendKind::cpu, flexible, law);
    auto run = [&](DemSystem& sys, std::vector<std::vector<double>>& forces) {
      if (!flexible) {
        sys.advance(600);
        return;
      }
      const WallMesh floor = plane_mesh(0.05, 4);
      const std::size_t nn = floor.vertices.size() / 3;
      std::vector<double> x = floor.vertices, v(3 * nn, 0.0), a(3 * nn, 0.0);
      for (std::size_t k = 0; k < nn; ++k) v[3 * k + 2] = 0.05;
      for (int c = 0; c < 4; ++c) {
        sys.set_flexible_kinematics(x, v, a);
        sys.advance(150);
        std::vector<double> f(3 * nn);
        sys.flexible_forces(f);
        forces.push_back(f);
        for (std::size_t k = 0; k < 3 * nn; ++k) x[k] += v[k] * 150 * 1e-5;
      }
    };
    std::vector<std::vector<double>> fc, fg;
    run(cpu, fc);
    REQUIRE(cpu.max_overlap() > 0.0);
    REQUIRE(cpu.contact_count() > 5);
    if (!cuda_available()) {
      WARN("CPU-vs-CUDA comparison with polyhedra skipped: no CUDA device (or built without CUDA)");
      return;
    }
    DemSystem gpu = poly_scene(DemBackendKind::cuda, flexible, law);
    run(gpu, fg);
    const auto& a = cpu.particles();
    const auto& b = gpu.particles();
    REQUIRE(a.size() == b.size());
    CHECK(max_position_difference(a, b) < 1e-9 * 0.005);
    double dq = 0.0;
    for (std::size_t i = 0; i < a.size(); ++i)
      dq = std::max({dq, std::abs(a.qw[i] - b.qw[i]), std::abs(a.qx[i] - b.qx[i]),
                     std::abs(a.qy[i] - b.qy[i]), std::abs(a.qz[i] - b.qz[i])});
    CHECK(dq < 1e-9);
    CHECK(gpu.kinetic_energy() == Approx(cpu.kinetic_energy()).epsilon(1e-9));
    for (std::size_t c = 0; c < fc.size(); ++c) {
      double scale = 0.0;
      for (double f : fc[c]) scale = std::max(scale, std::abs(f));
      for (std::size_t k = 0; k < fc[c].size(); ++k)
        CHECK(std::abs(fc[c][k] - fg[c][k]) <= 1e-6 * scale);
    }
  }
}
