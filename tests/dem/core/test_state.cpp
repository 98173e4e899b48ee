// Determinism, save/restore, neighbour-list reuse, bad input, CPU vs CUDA.

#include <omp.h>

#include <catch2/catch.hpp>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <random>

#include "dem_test_util.hpp"
#include "demfem/dem/dem_system.hpp"
#include "demfem/io/h5_file.hpp"
#include "demfem_test/temp_dir.hpp"

using namespace demfem::dem;
using namespace demfem::dem::test;

namespace {
// A lattice of jittered spheres (radii 1.5-2.5 mm) falling onto a 4 x 4-cell floor with
// friction and rolling resistance, or without walls (for the CUDA comparison) in a
// converging velocity field so that many contacts form (v = -40 (x - c) 1/s: about 150-300
// contacts from step 400 on; -4 1/s left the cloud almost contact-free in 1000 steps).
DemSystem make_scene(int threads, bool walls, DemBackendKind backend = DemBackendKind::cpu, int side = 8,
                     double list_skin = 0.0) {
  auto s = two_material_settings(1e8, 0.3, 2500.0, 0.4, 0.5, 1e-5, 0.02);
  s.list_skin = list_skin;
  s.gravity = {0, 0, walls ? -9.81 : 0.0};
  s.threads = threads;
  s.backend = backend;
  DemSystem sys(s);
  if (walls) sys.add_wall(plane_mesh(0.0052 * side + 0.04, 4));
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<ParticleInit> p;
  const double x0 = -0.0026 * side;
  for (int k = 0; k < 8; ++k)
    for (int j = 0; j < side; ++j)
      for (int i = 0; i < side; ++i) {
        const double x = x0 + 0.0052 * i + 2e-4 * u(rng), y = x0 + 0.0052 * j + 2e-4 * u(rng);
        const double z = 0.0027 + 0.0052 * k;
        const std::array<double, 3> v =
            walls ? std::array<double, 3>{0.1 * u(rng), 0.1 * u(rng), -0.5 + 0.3 * u(rng)}
                  : std::array<double, 3>{-40 * x, -40 * y, -40 * (z - 0.02)};
        p.push_back(sphere({x, y, z}, 0.002 + 0.0005 * u(rng), v, {10 * u(rng), 0, 0}));
      }
  sys.add_particles(p);
  return sys;
}

bool same_state(const ParticleState& a, const ParticleState& b) {
  auto eq = [](const std::vector<double>& x, const std::vector<double>& y) {
    return x.size() == y.size() && std::memcmp(x.data(), y.data(), x.size() * sizeof(double)) == 0;
  };
  return eq(a.px, b.px) && eq(a.py, b.py) && eq(a.pz, b.pz) && eq(a.vx, b.vx) && eq(a.vy, b.vy) &&
         eq(a.vz, b.vz) && eq(a.wx, b.wx) && eq(a.wy, b.wy) && eq(a.wz, b.wz) && eq(a.qw, b.qw) &&
         eq(a.qx, b.qx) && eq(a.fx, b.fx) && eq(a.fz, b.fz);
}
}  // namespace

TEST_CASE("Runs are bitwise reproducible, also across thread counts", "[dem][determinism]") {
  // Reference: a run with one thread. Tolerance: none (bitwise). 2048 particles, so that
  // the particle loops run on two threads (systems below 2048 particles use one). The two
  // threads' particle ranges follow their measured busy times, so they differ from step to
  // step and from run to run: the bits must not depend on them.
  DemSystem a = make_scene(1, true, DemBackendKind::cpu, 16), b = make_scene(1, true, DemBackendKind::cpu, 16),
            c = make_scene(2, true, DemBackendKind::cpu, 16);
  a.advance(200);
  b.advance(200);
  c.advance(200);
  CHECK(a.max_overlap() > 0.0);
  CHECK(a.neighbour_rebuilds() >= 2);
  CHECK(same_state(a.particles(), b.particles()));
  CHECK(same_state(a.particles(), c.particles()));
  CHECK(std::memcmp(a.wall_force(0).data(), c.wall_force(0).data(), 3 * sizeof(double)) == 0);
}

TEST_CASE("A run inside a parallel region (fewer threads than asked) gives the same bits",
          "[dem][determinism]") {
  // Reference: the same run on one thread. Tolerance: none (bitwise). A parameter study may
  // run systems side by side from OpenMP threads: the inner regions then get fewer threads
  // than settings.threads (here one, nesting off), and every particle must still be done.
  DemSystem ref = make_scene(1, true, DemBackendKind::cpu, 16);
  ref.advance(100);
  const int levels = omp_get_max_active_levels();
  omp_set_max_active_levels(1);
  std::vector<DemSystem> runs;
  runs.push_back(make_scene(2, true, DemBackendKind::cpu, 16));
  runs.push_back(make_scene(2, true, DemBackendKind::cpu, 16));
#pragma omp parallel for num_threads(2)
  for (int r = 0; r < 2; ++r) runs[static_cast<std::size_t>(r)].advance(100);
  omp_set_max_active_levels(levels);
  CHECK(same_state(ref.particles(), runs[0].particles()));
  CHECK(same_state(ref.particles(), runs[1].particles()));
}

TEST_CASE("Save/restore mid-run continues bitwise identically", "[dem][restart]") {
  // Reference: an uninterrupted run of 600 steps. Tolerance: none (bitwise).
  // A folder of this process: test_dem_core and test_dem_cuda_emu both run this file's tests,
  // side by side under ctest -j.
  const demfem::test::TempDir tmp("dem_core_restart");
  const auto& dir = tmp.path;
  const auto file = dir / "state.h5";
  DemSystem ref = make_scene(2, true);
  ref.advance(600);

  DemSystem first = make_scene(2, true);
  first.advance(300);
  {
    demfem::io::H5File h5(file, demfem::io::H5File::Mode::create);
    first.save(h5, "/dem");
  }
  DemSystem second = make_scene(2, true);  // same walls and settings, state replaced
  {
    demfem::io::H5File h5(file, demfem::io::H5File::Mode::read);
    second.restore(h5, "/dem");
  }
  CHECK(second.step_count() == 300);
  second.advance(300);
  first.advance(300);
  CHECK(same_state(ref.particles(), first.particles()));
  CHECK(same_state(ref.particles(), second.particles()));
  CHECK(ref.time() == second.time());
  CHECK(std::memcmp(ref.wall_force(0).data(), second.wall_force(0).data(), 3 * sizeof(double)) ==
        0);
  // The saved pair list is the pairs with a spring, each row in the order of j: the
  // uninterrupted run and the restored one (whose list was rebuilt at step 300 with a fresh
  // adaptive skin) write the same arrays.
  const auto file_ref = dir / "ref.h5", file_second = dir / "second.h5";
  {
    demfem::io::H5File a(file_ref, demfem::io::H5File::Mode::create);
    ref.save(a, "/dem");
    demfem::io::H5File b(file_second, demfem::io::H5File::Mode::create);
    second.save(b, "/dem");
  }
  {
    demfem::io::H5File a(file_ref, demfem::io::H5File::Mode::read);
    demfem::io::H5File b(file_second, demfem::io::H5File::Mode::read);
    const auto row = a.read_int64("/dem/row"), nbr = a.read_int64("/dem/nbr");
    const auto shear = a.read_doubles("/dem/shear"), rhist = a.read_doubles("/dem/rhist");
    CHECK(row == b.read_int64("/dem/row"));
    CHECK(nbr == b.read_int64("/dem/nbr"));
    CHECK(shear == b.read_doubles("/dem/shear"));
    CHECK(rhist == b.read_doubles("/dem/rhist"));
    REQUIRE(row.size() == ref.particle_count() + 1);
    REQUIRE(shear.size() == 3 * nbr.size());
    REQUIRE(rhist.size() == shear.size());  // this scene has rolling resistance
    CHECK(nbr.size() > 10);                 // 24 pairs touch at step 600
    std::size_t unordered = 0, springless = 0;
    for (std::size_t i = 0; i + 1 < row.size(); ++i)
      for (auto k = row[i]; k < row[i + 1]; ++k) {
        const auto u = static_cast<std::size_t>(k);
        if (k > row[i] && nbr[u - 1] >= nbr[u]) ++unordered;
        bool spring = false;
        for (int c = 0; c < 3; ++c)
          spring = spring || shear[3 * u + c] != 0 || rhist[3 * u + c] != 0;
        if (!spring) ++springless;
      }
    CHECK(unordered == 0);
    CHECK(springless == 0);
  }
  // removal keeps the history of the others and still runs
  std::vector<std::uint8_t> keep(second.particle_count(), 1);
  keep[3] = keep[100] = 0;
  second.remove_particles(keep);
  CHECK(second.particle_count() == ref.particle_count() - 2);
  second.advance(10);
}

TEST_CASE("In-memory save point: a step redone from it gives the bits of its first try",
          "[dem][restart]") {
  // Implicit coupling goes back to a coupling step's start (save_state / restore_state) and
  // redoes it with other mesh kinematics. Reference: the same steps without going back.
  // Tolerance: none (bitwise). The floor is the flexible mesh, so that its kinematics, node
  // forces and wall contact slots (friction history) are part of the state; the bed has
  // friction and rolling resistance (pair springs). On the CUDA backend (where there is one,
  // or in the emulator build) the state goes to the device at every advance(): the same rule.
  DemBackendKind backend = DemBackendKind::cpu;
  SECTION("CPU backend") {}
  SECTION("CUDA backend") {
    if (!cuda_available()) {
      WARN("the CUDA save point is not checked here: no CUDA device (or built without CUDA)");
      return;
    }
    backend = DemBackendKind::cuda;
  }
  auto make = [](DemBackendKind kind) {
    DemSystem sys = make_scene(2, false, kind);
    const WallMesh floor = plane_mesh(0.08, 4);
    demfem::InterfaceMesh mesh;
    mesh.reference_positions = floor.vertices;
    mesh.triangles = floor.triangles;
    for (std::size_t k = 2; k < mesh.reference_positions.size(); k += 3)
      mesh.reference_positions[k] = -0.02;  // below the converging cloud
    sys.set_flexible_mesh(mesh, 1);
    return sys;
  };
  const std::size_t n3 = plane_mesh(0.08, 4).vertices.size();
  auto kinematics = [&](DemSystem& sys, double v) {
    std::vector<double> x = sys.flexible_positions(), vel(n3, 0.0), acc(n3, 0.0);
    for (std::size_t k = 2; k < n3; k += 3) vel[k] = v;
    sys.set_flexible_kinematics(x, vel, acc);
  };
  auto forces = [&](const DemSystem& sys) {
    std::vector<double> f(n3);
    sys.flexible_forces(f);
    return f;
  };
  DemSystem ref = make(backend), sys = make(backend);
  ref.advance(400);
  sys.advance(400);
  REQUIRE(ref.max_overlap() > 0.0);  // in contact (contact_count() is the CPU backend's)
  if (backend == DemBackendKind::cpu) REQUIRE(ref.contact_count() > 50);
  kinematics(ref, 0.5);
  ref.advance(50, demfem::ForceMode::average);
  const ParticleState first = ref.particles();
  const auto first_forces = forces(ref);
  ref.advance(100);

  DemStateCopy copy;
  sys.save_state(copy);
  for (double v : {0.5, -2.0, 0.5}) {  // the first try, another one, the first again
    sys.restore_state(copy);
    kinematics(sys, v);
    sys.advance(50, demfem::ForceMode::average);
  }
  CHECK(same_state(first, sys.particles()));
  CHECK(forces(sys) == first_forces);
  CHECK(sys.step_count() == 450);
  sys.advance(100);
  CHECK(same_state(ref.particles(), sys.particles()));
  CHECK(ref.time() == sys.time());
  CHECK(forces(sys) == forces(ref));
  // A copy of another particle count is refused.
  std::vector<std::uint8_t> keep(sys.particle_count(), 1);
  keep[0] = 0;
  sys.remove_particles(keep);
  CHECK_THROWS_WITH(sys.restore_state(copy), Catch::Contains("particles"));
}

TEST_CASE("Neighbour list is reused until two particles may have closed the skin",
          "[dem][detection]") {
  // A still row without gravity: one build, no rebuild. Then spheres at 1 m/s (0.01 mm per
  // step) with a one-level list (list_skin = 1, skin = 0.2 r_max = 0.4 mm): a build is due
  // when the two largest displacements since the last build sum to more than the skin, so
  // one moving sphere builds every 41 steps (its own displacement alone closes the skin)
  // and two every 21 (twice the largest: what a largest-displacement rule gives for any
  // number of moving spheres).
  auto s = two_material_settings(1e8, 0.3, 2500.0, 0.4, 0.5, 1e-5);
  s.list_skin = 1.0;
  auto row = [&] {
    DemSystem sys(s);
    std::vector<ParticleInit> p;
    for (int i = 0; i < 10; ++i) p.push_back(sphere({0.005 * i, 0, 0}, 0.002));
    sys.add_particles(p);
    sys.advance(100);
    CHECK(sys.neighbour_rebuilds() == 1);
    CHECK(sys.neighbour_pairs() == 0);  // spheres 1 mm apart, skin 0.4 mm
    return sys;
  };
  DemSystem one = row();
  one.add_particles(std::vector<ParticleInit>{sphere({0.0, 0.01, 0}, 0.002, {0, 1.0, 0})});
  one.advance(200);  // 2 mm: the build at the first step (new particle), then 4 (every 41)
  CHECK(one.neighbour_rebuilds() == 1 + 1 + 4);
  DemSystem two = row();
  two.add_particles(std::vector<ParticleInit>{sphere({0.0, 0.01, 0}, 0.002, {0, 1.0, 0}),
                                              sphere({0.02, 0.01, 0}, 0.002, {0, -1.0, 0})});
  two.advance(200);  // 9 more (every 21)
  CHECK(two.neighbour_rebuilds() == 1 + 1 + 9);
  CHECK(one.rayleigh_time_step() == Approx(3.14159265358979 * 0.002 / (0.1631 * 0.3 + 0.8766) *
                                           std::sqrt(2500.0 / (1e8 / 2.6))));  // eq. 2.27
}

TEST_CASE("A sphere moving alone through a resting row meets every sphere in its way",
          "[dem][detection]") {
  // The build rule above lets one fast sphere use the whole skin. It must still find every
  // contact: a sphere shot along a row of resting spheres with gaps of 1 mm collides with the
  // first, and the momentum passes down the row (Newton's cradle, e = 0.4). Reference: the same
  // run with a list rebuilt every step (skin used up at once: a huge speed bound) must give the
  // same bits. Tolerance: none.
  auto s = two_material_settings(1e8, 0.3, 2500.0, 0.4, 0.0, 1e-5);
  s.list_skin = 1.0;
  auto run = [&](bool every_step) {
    DemSystem sys(s);
    std::vector<ParticleInit> p;
    p.push_back(sphere({-0.006, 0, 0}, 0.002, {2.0, 0, 0}));
    for (int i = 0; i < 8; ++i) p.push_back(sphere({0.005 * i, 0, 0}, 0.002));
    sys.add_particles(p);
    for (int k = 0; k < 3000; ++k) {
      if (every_step) sys.add_particles(std::vector<ParticleInit>{});  // asks for a build
      sys.advance(1);
    }
    return sys;
  };
  DemSystem lazy = run(false), eager = run(true);
  CHECK(lazy.neighbour_rebuilds() < eager.neighbour_rebuilds());
  CHECK(same_state(lazy.particles(), eager.particles()));
  CHECK(lazy.particles().vx[8] > 0.0);  // the push reached the end of the row
}

TEST_CASE("The two-level pair list gives the bits of a one-level list", "[dem][detection]") {
  // Reference: the same run with list_skin = 1 (the pair list holds every candidate within
  // the whole skin, refiltered only at a build). Tolerance: none (bitwise): a pair list that
  // missed a touching pair, or a spring lost at a refilter, changes the trajectory.
  auto run = [](double list_skin) {
    DemSystem sys = make_scene(1, true, DemBackendKind::cpu, 8, list_skin);
    sys.advance(600);
    return sys;
  };
  DemSystem one = run(1.0), thin = run(0.1), adaptive = run(0.0);
  CHECK(one.neighbour_refilters() == one.neighbour_rebuilds());
  CHECK(one.neighbour_rebuilds() < 60);  // one level: a build per skin/2 of motion only
  CHECK(thin.neighbour_refilters() > thin.neighbour_rebuilds());  // refilters did happen
  // the spheres fall at ~0.5 m/s: the adaptive list goes to one level and builds as often as
  // one level (20 builds), less than a fixed thin list skin (22 builds and 150 refilters)
  CHECK(adaptive.neighbour_rebuilds() <= one.neighbour_rebuilds());
  CHECK(adaptive.neighbour_rebuilds() < thin.neighbour_rebuilds());
  CHECK(thin.neighbour_pairs() < one.neighbour_pairs());
  CHECK(thin.contact_count() == one.contact_count());
  CHECK(same_state(one.particles(), thin.particles()));
  CHECK(same_state(one.particles(), adaptive.particles()));
  CHECK(std::memcmp(one.wall_force(0).data(), thin.wall_force(0).data(), 3 * sizeof(double)) == 0);
  // and it is rejected outside [0, 1]
  auto bad = one.settings();
  bad.list_skin = 1.5;
  CHECK_THROWS_WITH(DemSystem(bad), Catch::Contains("settings.list_skin"));
}

TEST_CASE("Bad input is rejected with a message naming the key", "[dem][input]") {
  auto s = two_material_settings(1e8, 0.3, 2500.0, 0.4, 0.5, 1e-5);
  s.dt = -1;
  CHECK_THROWS_WITH(DemSystem(s), Catch::Contains("settings.dt"));
  s = two_material_settings(1e8, 0.3, 2500.0, 1.5, 0.5, 1e-5);
  CHECK_THROWS_WITH(DemSystem(s), Catch::Contains("restitution") && Catch::Contains("(0, 1]"));
  s = two_material_settings(1e8, 0.6, 2500.0, 0.4, 0.5, 1e-5);
  CHECK_THROWS_WITH(DemSystem(s), Catch::Contains("poisson_ratio"));
  s = two_material_settings(1e8, 0.3, 2500.0, 0.4, 0.5, 1e-5);
  s.pairs.pop_back();
  CHECK_THROWS_WITH(DemSystem(s), Catch::Contains("settings.pairs"));
  DemSystem sys(two_material_settings(1e8, 0.3, 2500.0, 0.4, 0.5, 1e-5));
  std::vector<ParticleInit> p = {sphere({0, 0, 0}, -1.0)};
  CHECK_THROWS_WITH(sys.add_particles(p), Catch::Contains("radius"));
  p = {sphere({std::nan(""), 0, 0}, 0.001)};
  CHECK_THROWS_WITH(sys.add_particles(p), Catch::Contains("non-finite"));
  CHECK_THROWS_WITH(sys.advance(-1), Catch::Contains("substeps"));
  WallMesh w = plane_mesh(0.01, 1);
  w.triangles[0] = 99;
  CHECK_THROWS_WITH(sys.add_wall(w), Catch::Contains("vertex index 99"));
  if (!cuda_available()) {
    auto sc = two_material_settings(1e8, 0.3, 2500.0, 0.4, 0.5, 1e-5);
    sc.backend = DemBackendKind::cuda;
    CHECK_THROWS_WITH(DemSystem(sc), Catch::Contains("cuda"));
  }
}

TEST_CASE("CPU and CUDA backends agree over 1000 steps", "[dem][gpu]") {
  // Reference: the CPU backend. Tolerance: 1e-9 of the particle radius in position after
  // 1000 steps of a colliding cloud and of spheres falling onto a mesh floor (round-off
  // growth; the device code is built without FMA contraction, so it rounds like the CPU;
  // 1e-6 for the wall force of the last step).
  if (!cuda_available()) {
    WARN("CPU-vs-CUDA comparison skipped: no CUDA device (or built without CUDA)");
    return;
  }
  for (bool walls : {false, true}) {
    INFO("with a mesh floor: " << walls);
    DemSystem cpu = make_scene(2, walls), gpu = make_scene(2, walls, DemBackendKind::cuda);
    cpu.advance(1000);
    gpu.advance(1000);
    const auto& a = cpu.particles();
    const auto& b = gpu.particles();
    REQUIRE(a.size() == b.size());
    const double worst = max_position_difference(a, b);
    CHECK(cpu.max_overlap() > 0.0);
    CHECK(worst < 1e-9 * 0.002);
    CHECK(gpu.kinetic_energy() == Approx(cpu.kinetic_energy()).epsilon(1e-9));
    if (walls) CHECK(gpu.wall_force(0)[2] == Approx(cpu.wall_force(0)[2]).epsilon(1e-6));
  }
}

TEST_CASE("Save/restore of a frictionless system (no springs) continues bitwise", "[dem][restart]") {
  // Reference: the uninterrupted run. Tolerance: none (bitwise). Without friction the pairs
  // carry no spring and the engine keeps no shear array: a saved state has no pairs.
  auto frictionless = [] {
    auto s = two_material_settings(1e8, 0.3, 2500.0, 0.4, 0.0, 1e-5);
    s.threads = 1;
    DemSystem sys(s);
    std::vector<ParticleInit> p;
    for (int k = 0; k < 4; ++k)
      for (int j = 0; j < 4; ++j)
        for (int i = 0; i < 4; ++i) {
          const double x = 0.0045 * (i - 1.5), y = 0.0045 * (j - 1.5), z = 0.0045 * (k - 1.5);
          p.push_back(sphere({x, y, z}, 0.002, {-100 * x, -100 * y, -100 * z}));
        }
    sys.add_particles(p);
    return sys;
  };
  const demfem::test::TempDir tmp("frictionless_restart");  // per process (see above)
  const auto& dir = tmp.path;
  DemSystem ref = frictionless();
  ref.advance(300);
  REQUIRE(ref.neighbour_pairs() > 0);  // a list the old save wrote whole
  REQUIRE(ref.advance_max_overlap() > 0.0);  // and spheres that touched
  {
    demfem::io::H5File h5(dir / "s.h5", demfem::io::H5File::Mode::create);
    ref.save(h5, "/dem");
  }
  DemSystem other = frictionless();
  {
    demfem::io::H5File h5(dir / "s.h5", demfem::io::H5File::Mode::read);
    other.restore(h5, "/dem");
    CHECK(h5.read_int64("/dem/nbr").empty());
  }
  ref.advance(200);
  other.advance(200);
  CHECK(same_state(ref.particles(), other.particles()));
}
