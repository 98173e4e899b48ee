// DemBackend, the protocol adapter of dem_server, driven in-process with real interface
// buffers: the flexible mesh carries the particles' weight, the buffers are filled as the
// protocol says, a restored checkpoint continues bitwise identically, bad input is refused.
#if DEMFEM_HAVE_PROTOCOL

#include <catch2/catch.hpp>

#include <cmath>

#include "demfem/dem/dem_backend.hpp"
#include "demfem_test/dem_material_text.hpp"
#include "demfem_test/temp_dir.hpp"

using namespace demfem;
using namespace demfem::dem;
using demfem::test::TempDir;

namespace {

const std::string kScene = std::string(R"(
[run]
end_time = 1.0

[dem]
dt = 2e-5
threads = 1
interface_material = "sheet"

)") +
    // grain (E, density), sheet (E), both pairs: friction, restitution
    demfem::test::grain_and_wall("grain", "1e7", "1000.0", "sheet", "2e11", "0.5", "0.3") +
    R"(
[[dem.lattice]]
material = "grain"
lo = [-0.0152, -0.0152, 0.0005]
hi = [0.0152, 0.0152, 0.0110]
diameter = 0.01
spacing = 0.0101
)";

/// A 0.2 m square at z = 0 (normal +z) as the coupled surface: 4 nodes, 2 triangles.
InterfaceMesh sheet() {
  InterfaceMesh m;
  m.reference_positions = {-0.1, -0.1, 0, 0.1, -0.1, 0, 0.1, 0.1, 0, -0.1, 0.1, 0};
  m.triangles = {0, 1, 2, 0, 2, 3};
  return m;
}

/// Interface buffers over local arrays (what the protocol library maps from shared memory).
struct LocalBuffers {
  InterfaceMesh mesh = sheet();
  std::vector<double> arrays = std::vector<double>(2 * 5 * 12, 0.0);
  protocol::InterfaceBuffers buffers;
  LocalBuffers() {
    buffers.bind(4, 2, mesh.reference_positions.data(), mesh.triangles.data(), arrays.data());
    for (std::uint32_t b = 0; b < 2; ++b) {
      auto x = buffers.positions(b);
      std::copy(mesh.reference_positions.begin(), mesh.reference_positions.end(), x.begin());
    }
  }
};

DemScene read_scene(const std::string& text) {
  auto d = scene::Document::parse(text, "backend.toml");
  return read_dem_scene(d.root().required_table("dem"));
}

protocol::StepCommand step_cmd(std::int64_t k, std::uint32_t flags) {
  protocol::StepCommand c;
  c.step = k;
  c.substeps = 50;
  c.dt = 50 * 2e-5;
  c.buffer = std::uint32_t(k % 2);
  c.flags = flags;
  c.force_mode = ForceMode::average;
  return c;
}

}  // namespace

TEST_CASE("DemBackend: the flexible mesh carries the weight; checkpoints continue bitwise",
          "[backend]") {
  TempDir dir;
  const DemScene s = read_scene(kScene);
  DemRun run(s, dir / "out", 1, 0.0, nullptr, true);
  REQUIRE(run.system().particle_count() == 9);
  DemBackend backend(run);
  CHECK_FALSE(backend.published_mesh().has_value());
  LocalBuffers lb;
  backend.on_mesh(lb.mesh);
  // 0.3 s: the particles fall 0.5 mm and settle.
  protocol::StepResult r;
  for (std::int64_t k = 0; k < 300; ++k) {
    r = backend.step(step_cmd(k, k == 0 ? protocol::kStepSetKinematics : 0), lb.buffers);
  }
  const std::uint32_t last = 299 % 2;
  double fz = 0.0;
  for (std::size_t i = 0; i < 4; ++i) fz += lb.buffers.forces(last)[3 * i + 2];
  // Static equilibrium: the sheet carries the weight of the 9 spheres, m g = 9 * 1000 *
  // pi/6 * 0.01^3 * 9.81 = 0.04623 N, pushing down (-z). Settled to 1e-3 relative.
  const double weight = 9 * 1000.0 * M_PI / 6 * 1e-6 * 9.81;
  CHECK(fz == Approx(-weight).epsilon(1e-3));
  CHECK(r.values[0] > 0.0);  // the spheres overlap the sheet a little
  CHECK(r.values[0] < 1e-4);
  CHECK(r.values[1] == run.system().kinetic_energy());
  CHECK(r.values[2] > 0.0);  // last step only (values[0] is the maximum over the substeps)
  for (std::size_t i = 0; i < 12; ++i) {
    CHECK(lb.buffers.dem_positions(last)[i] == lb.mesh.reference_positions[i]);
  }

  // Checkpoint, go on 20 steps; a fresh run restored from it must give the same forces.
  backend.write_checkpoint(dir / "dem.h5", 300);
  std::vector<double> forces_a;
  for (std::int64_t k = 300; k < 320; ++k) {
    backend.step(step_cmd(k, protocol::kStepSetKinematics), lb.buffers);
    const auto f = lb.buffers.forces(std::uint32_t(k % 2));
    forces_a.insert(forces_a.end(), f.begin(), f.end());
  }
  DemRun run2(s, dir / "out", 1, 0.0, nullptr, true);
  DemBackend backend2(run2);
  LocalBuffers lb2;
  backend2.on_mesh(lb2.mesh);
  CHECK_THROWS_WITH(backend2.restore_checkpoint(dir / "dem.h5", 299),
                    Catch::Contains("checkpoint is of step 300"));
  backend2.restore_checkpoint(dir / "dem.h5", 300);
  std::vector<double> forces_b;
  for (std::int64_t k = 300; k < 320; ++k) {
    backend2.step(step_cmd(k, protocol::kStepSetKinematics), lb2.buffers);
    const auto f = lb2.buffers.forces(std::uint32_t(k % 2));
    forces_b.insert(forces_b.end(), f.begin(), f.end());
  }
  CHECK(forces_a == forces_b);  // bitwise
  CHECK(run2.ids().size() == 9);
}

TEST_CASE("DemBackend: iterated steps leave the series of plain steps, bit for bit", "[backend]") {
  // Implicit coupling: every step tried three times (the last try with the kinematics the
  // plain run uses) through the IterationGate, as serve() drives it. The sensor series and the
  // particle output must be those of the plain run: a try that is redone leaves no sample, no
  // snapshot and no insertion behind; the accepted one leaves exactly one.
  std::string text = kScene;
  text += R"(
[[dem.sensors]]
name = "ke"
kind = "kinetic_energy"
interval = 0.01

[[dem.sensors]]
name = "flow"
kind = "mass_flow"
interval = 0.01
point = [0.0, 0.0, 0.004]
direction = [0.0, 0.0, -1.0]

[dem.output]
interval = 0.02
)";
  const DemScene s = read_scene(text);
  auto kinematics = [](LocalBuffers& lb, std::uint32_t b, double vz) {
    auto v = lb.buffers.velocities(b);
    for (std::size_t i = 0; i < 4; ++i) v[3 * i + 2] = vz;
  };
  TempDir plain_dir, iter_dir;
  std::vector<double> plain_forces, iter_forces;
  {
    DemRun run(s, plain_dir / "out", 1, 0.05, nullptr, true);
    DemBackend backend(run);
    LocalBuffers lb;
    backend.on_mesh(lb.mesh);
    for (std::int64_t k = 0; k < 60; ++k) {
      const auto cmd = step_cmd(k, protocol::kStepSetKinematics);
      kinematics(lb, cmd.buffer, k < 30 ? 0.0 : -1e-3);
      backend.step(cmd, lb.buffers);
      const auto f = lb.buffers.forces(cmd.buffer);
      plain_forces.insert(plain_forces.end(), f.begin(), f.end());
    }
    run.finish();
  }
  {
    DemRun run(s, iter_dir / "out", 1, 0.05, nullptr, true);
    DemBackend backend(run);
    protocol::IterationGate gate;
    LocalBuffers lb;
    backend.on_mesh(lb.mesh);
    for (std::int64_t k = 0; k < 60; ++k) {
      for (int t = 0; t < 3; ++t) {
        auto cmd = step_cmd(k, protocol::kStepSetKinematics | protocol::kStepIterate |
                                   (t > 0 ? protocol::kStepRedo : 0u));
        kinematics(lb, cmd.buffer, t == 1 ? 5e-3 : (k < 30 ? 0.0 : -1e-3));
        gate.step(backend, cmd, lb.buffers);
      }
      const auto f = lb.buffers.forces(std::uint32_t(k % 2));
      iter_forces.insert(iter_forces.end(), f.begin(), f.end());
    }
    gate.accept(backend);  // as on Shutdown
    run.finish();
  }
  CHECK(iter_forces == plain_forces);  // bitwise
  for (const char* file : {"sensor_ke.csv", "sensor_flow.csv", "particles.xdmf"}) {
    INFO(file);
    const std::string a = demfem::test::read_text(plain_dir / "out" / file);
    CHECK(a.size() > 100);
    CHECK(a == demfem::test::read_text(iter_dir / "out" / file));
  }
}

TEST_CASE("DemBackend refuses inconsistent steps and a scene without interface material",
          "[backend]") {
  const DemScene s = read_scene(kScene);
  DemRun run(s, "", 1, 0.0, nullptr, true);
  DemBackend backend(run);
  LocalBuffers lb;
  backend.on_mesh(lb.mesh);
  auto bad = step_cmd(0, 0);
  bad.dt = 1e-3 * 1.01;
  CHECK_THROWS_WITH(backend.step(bad, lb.buffers),
                    Catch::Contains("do not make the coupling step"));
  bad = step_cmd(0, 0);
  bad.substeps = 0;
  CHECK_THROWS_WITH(backend.step(bad, lb.buffers), Catch::Contains("must be >= 1"));

  std::string text = kScene;
  text.erase(text.find("interface_material = \"sheet\"\n"), 30);
  // Without interface_material the sheet pair is not needed either; the scene reads, but a
  // coupled run cannot start.
  DemRun run2(read_scene(text), "", 1, 0.0, nullptr, true);
  DemBackend backend2(run2);
  CHECK_THROWS_WITH(backend2.on_mesh(lb.mesh), Catch::Contains("needs 'interface_material'"));
}

#endif
