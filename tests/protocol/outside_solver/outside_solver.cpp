// An outside solver that links the installed demfem::protocol package. Run without
// arguments it plays the coupler: it creates a session, starts itself as the FEM solver
// (`outside_solver SEGMENT`), exchanges the mesh, does two steps and shuts down.
#include <sys/wait.h>
#include <unistd.h>

#include <demfem/protocol/protocol.hpp>
#include <iostream>

namespace proto = demfem::protocol;

namespace {
class OutsideFem : public proto::SolverBackend {
 public:
  std::string name() const override { return "outside-fem"; }
  std::optional<demfem::InterfaceMesh> published_mesh() override {
    demfem::InterfaceMesh mesh;
    mesh.reference_positions = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    mesh.triangles = {0, 1, 2};
    return mesh;
  }
  void on_mesh(const demfem::InterfaceMesh&) override {}
  proto::StepResult step(const proto::StepCommand& cmd, proto::InterfaceBuffers& b) override {
    auto x = b.positions(cmd.buffer);
    x[2] = 0.25 * static_cast<double>(cmd.step);  // node 0 moves up in z
    proto::StepResult r;
    r.values[0] = static_cast<double>(b.node_count());
    return r;
  }
  void write_checkpoint(const std::filesystem::path&, std::int64_t) override {}
  void restore_checkpoint(const std::filesystem::path&, std::int64_t) override {}
};
}  // namespace

int main(int argc, char** argv) {
  if (argc == 2) {
    OutsideFem fem;
    proto::ServeOptions options;
    options.segment = argv[1];
    options.role = proto::Role::fem;
    return proto::serve(fem, options);
  }
  try {
    proto::CouplerSession session;
    const pid_t pid = fork();
    if (pid == 0) {
      execl("/proc/self/exe", argv[0], session.segment_name().c_str(), nullptr);
      _exit(127);
    }
    session.expect(proto::Role::fem);
    session.wait_hello(proto::Role::fem, pid);
    const demfem::InterfaceMesh mesh = session.exchange_mesh();
    int failures = mesh.node_count() == 3 ? 0 : 1;
    for (std::int64_t step = 1; step <= 2; ++step) {
      proto::StepCommand cmd;
      cmd.step = step;
      cmd.buffer = static_cast<std::uint32_t>(step % 2);
      session.send_step(proto::Role::fem, cmd);
      if (session.wait_step_done(proto::Role::fem).values[0] != 3.0) ++failures;
      if (session.buffers().positions(cmd.buffer)[2] != 0.25 * static_cast<double>(step))
        ++failures;
    }
    if (!session.shutdown(proto::Role::fem)) ++failures;
    int status = 0;
    waitpid(pid, &status, 0);
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) ++failures;
    std::cout << "outside_solver: " << failures << " failures\n";
    return failures == 0 ? 0 : 1;
  } catch (const std::exception& e) {
    std::cerr << "outside_solver: " << e.what() << '\n';
    return 1;
  }
}
