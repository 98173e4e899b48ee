// fem_server as a separate process serving a coupler (this test plays the coupler through
// protocol::CouplerSession): the kinematics it returns equal an in-process FemSolver fed the
// same forces, a checkpoint/restore round trip repeats a step bitwise, Shutdown exits 0.
#ifdef DEMFEM_HAVE_PROTOCOL
#include <catch2/catch.hpp>

#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <vector>

#include "demfem/fem/fem_scene.hpp"
#include "demfem/fem/fem_solver.hpp"
#include "demfem/protocol/protocol.hpp"

extern char** environ;

using namespace demfem;

namespace {

const char* kScene = R"([run]
end_time = 1e-3
[fem]
dt = 1e-4
mesh = { box = { lo = [0, 0, 0], hi = [0.4, 0.1, 0.1], cells = [4, 1, 1] } }
materials = [{ name = "steel", youngs_modulus = 2.1e11, poisson_ratio = 0.3, density = 7850 }]
[[fem.clamps]]
nodes = "x <= 0"
)";

}  // namespace

TEST_CASE("fem_server --segment: steps match the in-process solver, checkpoint, shutdown") {
  const std::string exe = std::string(DEMFEM_BINARY_DIR) + "/bin/fem_server";
  REQUIRE(std::filesystem::exists(exe));
  const auto dir = std::filesystem::temp_directory_path() /
                   ("demfem_fem_server_coupled_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const auto scene_file = dir / "scene.toml";
  std::ofstream(scene_file) << kScene;

  protocol::CouplerSession session;
  session.expect(protocol::Role::fem);
  const std::string scene_arg = scene_file.string();
  const std::string out_arg = (dir / "out").string();
  std::vector<const char*> argv{exe.c_str(),
                                "--scene",
                                scene_arg.c_str(),
                                "--segment",
                                session.segment_name().c_str(),
                                "--output-dir",
                                out_arg.c_str(),
                                nullptr};
  pid_t pid = 0;
  REQUIRE(posix_spawn(&pid, exe.c_str(), nullptr, nullptr, const_cast<char**>(argv.data()),
                      environ) == 0);
  session.wait_hello(protocol::Role::fem, pid);
  CHECK(session.peer(protocol::Role::fem).name.find("demfem-fem") != std::string::npos);
  const InterfaceMesh mesh = session.exchange_mesh();
  REQUIRE(mesh.node_count() > 0);

  // Reference: the same problem in this process.
  const auto doc = scene::Document::load(scene_file);
  fem::FemSolver ref(fem::read_fem_scene(doc.root().required_table("fem")).problem);
  REQUIRE(ref.interface_mesh().reference_positions == mesh.reference_positions);

  const std::size_t n3 = 3 * mesh.node_count();
  std::vector<double> force(n3, 0.0), pos(n3), vel(n3), acc(n3);
  auto& buffers = session.buffers();
  std::vector<double> after_step3;
  for (std::int64_t s = 0; s < 4; ++s) {
    for (std::size_t i = 0; i < mesh.node_count(); ++i) force[3 * i + 2] = -1.0 - 0.1 * s;
    const std::uint32_t buf = static_cast<std::uint32_t>(s % 2);
    std::copy(force.begin(), force.end(), buffers.forces(buf).begin());
    protocol::StepCommand cmd;
    cmd.step = s;
    cmd.time = 1e-4 * s;
    cmd.dt = 1e-4;
    cmd.buffer = buf;
    if (s == 3) {
      session.checkpoint(protocol::Role::fem, dir / "fem_ckpt.h5", 3);
      session.wait_done(protocol::Role::fem);
    }
    session.send_step(protocol::Role::fem, cmd);
    const auto result = session.wait_step_done(protocol::Role::fem);
    ref.set_interface_forces(force);
    ref.advance(1e-4);
    ref.interface_kinematics(pos, vel, acc);
    const auto got = buffers.positions(buf);
    CHECK(std::vector<double>(got.begin(), got.end()) == pos);
    const auto gota = buffers.accelerations(buf);
    CHECK(std::vector<double>(gota.begin(), gota.end()) == acc);
    CHECK(result.values[3] == Approx(1e-4 * (s + 1)));
    if (s == 3) {
      after_step3.assign(got.begin(), got.end());
      // Roll back to the checkpoint and repeat the step: bitwise the same.
      session.restore(protocol::Role::fem, dir / "fem_ckpt.h5", 3);
      session.wait_done(protocol::Role::fem);
      session.send_step(protocol::Role::fem, cmd);
      session.wait_step_done(protocol::Role::fem);
      const auto again = buffers.positions(buf);
      CHECK(std::vector<double>(again.begin(), again.end()) == after_step3);
    }
  }
  CHECK(session.shutdown(protocol::Role::fem));
  int status = 0;
  REQUIRE(waitpid(pid, &status, 0) == pid);
  CHECK(WIFEXITED(status));
  CHECK(WEXITSTATUS(status) == 0);
  // Output: the reference state and the end state.
  CHECK(std::filesystem::exists(dir / "out/fem.xdmf"));
  CHECK(std::filesystem::exists(dir / "out/fem_000000.h5"));
  CHECK(std::filesystem::exists(dir / "out/fem_000001.h5"));
  CHECK_FALSE(std::filesystem::exists(dir / "out/fem_000002.h5"));
  std::filesystem::remove_all(dir);
}
#endif
