// A real process for the protocol tests: a raw ring producer, a solver (serve() with a test
// backend), or a coupler that can be killed. Test double: lives in tests/ only.
//
//   protocol_test_peer ring-producer SEGMENT COUNT
//   protocol_test_peer serve SEGMENT dem|fem [--nodes N] [--version V] [--step-sleep-ms S]
//                      [--iterates 0|1]
//                      [--throw-at-step K] [--throw-kind 0|1|2]  (a BackendError of that
//                      protocol::ErrorKind instead of a plain exception)
//   protocol_test_peer coupler-idle            (prints the segment name, then sleeps)
//   protocol_test_peer coupler-exit            (prints the segment name, then std::exit(0))
//   protocol_test_peer coupler-steps           (prints the name, waits for a DEM, steps forever)

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <stdexcept>
#include <string>
#include <thread>

#include "demfem/protocol/protocol.hpp"
#include "demfem/protocol/segment.hpp"

namespace proto = demfem::protocol;
namespace shm = demfem::protocol::shm;

namespace {

// A deterministic interface mesh of n nodes on a line-ish strip (values only need to be
// recognisable by the test, not physical).
demfem::InterfaceMesh test_mesh(std::size_t n) {
  demfem::InterfaceMesh mesh;
  for (std::size_t i = 0; i < n; ++i) {
    mesh.reference_positions.push_back(1e-3 * static_cast<double>(i));
    mesh.reference_positions.push_back(2e-3 * static_cast<double>(i));
    mesh.reference_positions.push_back(0.5);
  }
  for (std::size_t i = 0; i + 2 < n; ++i) {
    mesh.triangles.push_back(static_cast<std::int32_t>(i));
    mesh.triangles.push_back(static_cast<std::int32_t>(i + 1));
    mesh.triangles.push_back(static_cast<std::int32_t>(i + 2));
  }
  return mesh;
}

class TestBackend : public proto::SolverBackend {
 public:
  proto::Role role = proto::Role::dem;
  std::size_t nodes = 0;
  int step_sleep_ms = 0;
  long throw_at_step = -1;
  long throw_kind = -1;  // -1: std::runtime_error; else a BackendError of this ErrorKind
  std::size_t mesh_nodes_received = 0;
  std::int64_t restored_step = -1;
  // Iterated steps: a counter advanced by every step is the state; values[7] reports it and
  // the number of accepted steps (1000 each), so the coupler can see saves and restores.
  bool iterates = true;
  long state = 0, saved = -1, accepted = 0;
  bool supports_iteration() const override { return iterates; }
  void save_iteration_state() override { saved = state; }
  void restore_iteration_state() override { state = saved; }
  void accept_step() override { ++accepted; }

  std::string name() const override { return std::string("test-peer ") + proto::role_name(role); }
  std::optional<demfem::InterfaceMesh> published_mesh() override {
    if (role == proto::Role::fem && nodes > 0) return test_mesh(nodes);
    return std::nullopt;
  }
  void on_mesh(const demfem::InterfaceMesh& mesh) override {
    const demfem::InterfaceMesh expected = test_mesh(mesh.node_count());
    if (mesh.reference_positions != expected.reference_positions ||
        mesh.triangles != expected.triangles)
      throw std::runtime_error("received mesh differs from the published one");
    mesh_nodes_received = mesh.node_count();
  }
  proto::StepResult step(const proto::StepCommand& cmd, proto::InterfaceBuffers& b) override {
    if (cmd.step == throw_at_step && throw_kind >= 0)
      throw proto::BackendError(static_cast<proto::ErrorKind>(throw_kind),
                                "injected error at step " + std::to_string(cmd.step));
    if (cmd.step == throw_at_step)
      throw std::runtime_error("injected failure at step " + std::to_string(cmd.step));
    if (step_sleep_ms > 0) std::this_thread::sleep_for(std::chrono::milliseconds(step_sleep_ms));
    proto::StepResult r;
    r.values[0] = static_cast<double>(cmd.step);
    r.values[1] = cmd.time;
    r.values[2] = static_cast<double>(cmd.substeps);
    r.values[4] = static_cast<double>(mesh_nodes_received);
    r.values[5] = static_cast<double>(restored_step);
    r.values[6] = static_cast<double>(cmd.flags);
    ++state;
    r.values[7] = static_cast<double>(state + 1000 * accepted);
    if (b.empty()) return r;
    auto pos = b.positions(cmd.buffer);
    double sum = 0.0;
    for (double x : pos) sum += x;
    r.values[3] = sum;  // what the solver read in place
    if (role == proto::Role::fem) {
      // Move every coordinate by step * 1 mm from the reference.
      const auto ref = b.reference_mesh().reference_positions;
      for (std::size_t i = 0; i < pos.size(); ++i)
        pos[i] = ref[i] + 1e-3 * static_cast<double>(cmd.step);
    } else {
      auto f = b.forces(cmd.buffer);
      auto dem = b.dem_positions(cmd.buffer);
      for (std::size_t i = 0; i < pos.size(); ++i) {
        f[i] = 2.0 * pos[i];
        dem[i] = pos[i];
      }
    }
    return r;
  }
  void write_checkpoint(const std::filesystem::path& file, std::int64_t step) override {
    std::ofstream out(file);
    out << step << '\n';
    if (!out) throw std::runtime_error("cannot write " + file.string());
  }
  void restore_checkpoint(const std::filesystem::path& file, std::int64_t step) override {
    std::ifstream in(file);
    std::int64_t stored = -1;
    if (!(in >> stored)) throw std::runtime_error("cannot read checkpoint " + file.string());
    if (stored != step)
      throw std::runtime_error("checkpoint " + file.string() + " holds step " +
                               std::to_string(stored) + ", asked for " + std::to_string(step));
    restored_step = stored;
  }
};

int ring_producer(const std::string& segment, std::uint64_t count) {
  shm::MappedSegment mapped = shm::MappedSegment::open(segment);
  auto* seg = static_cast<shm::Segment*>(mapped.data());
  shm::Ring& ring = seg->channels[0].to_coupler;
  shm::PeerWatch owner(&seg->coupler, seg->fixed.owner_pid.load(), std::chrono::seconds(2));
  shm::Waiter waiter;
  waiter.policy.spin = std::chrono::microseconds(20);
  waiter.check = [&] {
    if (const std::string why = owner.check(); !why.empty())
      throw std::runtime_error("consumer gone: " + why);
  };
  shm::Message msg{};
  msg.kind = proto::MessageKind::step;
  for (std::uint64_t i = 0; i < count; ++i) {
    msg.time = static_cast<double>(i);
    msg.set(i);
    shm::push(ring, msg, waiter);
  }
  return 0;
}

int run_coupler(const std::string& mode) {
  proto::CouplerSession session;
  std::cout << session.segment_name() << std::endl;
  if (mode == "coupler-exit") std::exit(0);  // no destructor runs: the atexit hook must clean
  if (mode == "coupler-idle") {
    for (;;) std::this_thread::sleep_for(std::chrono::seconds(1));
  }
  session.wait_hello(proto::Role::dem, std::nullopt);
  session.exchange_mesh();
  for (std::int64_t step = 0;; ++step) {
    proto::StepCommand cmd;
    cmd.step = step;
    session.send_step(proto::Role::dem, cmd);
    session.wait_step_done(proto::Role::dem);
  }
}

}  // namespace

int main(int argc, char** argv) {
  try {
    if (argc < 2) throw std::invalid_argument("usage: protocol_test_peer MODE ...");
    const std::string mode = argv[1];
    if (mode == "ring-producer" && argc == 4) return ring_producer(argv[2], std::stoull(argv[3]));
    if (mode.rfind("coupler-", 0) == 0) return run_coupler(mode);
    if (mode == "serve" && argc >= 4) {
      TestBackend backend;
      proto::ServeOptions options;
      options.segment = argv[2];
      const std::string role = argv[3];
      if (role != "dem" && role != "fem") throw std::invalid_argument("role must be dem or fem");
      options.role = role == "dem" ? proto::Role::dem : proto::Role::fem;
      backend.role = options.role;
      for (int i = 4; i + 1 < argc; i += 2) {
        const std::string key = argv[i];
        const long value = std::stol(argv[i + 1]);
        if (key == "--nodes")
          backend.nodes = static_cast<std::size_t>(value);
        else if (key == "--version")
          options.claimed_version = static_cast<std::uint32_t>(value);
        else if (key == "--step-sleep-ms")
          backend.step_sleep_ms = static_cast<int>(value);
        else if (key == "--throw-at-step")
          backend.throw_at_step = value;
        else if (key == "--iterates")
          backend.iterates = value != 0;
        else if (key == "--throw-kind")
          backend.throw_kind = value;
        else
          throw std::invalid_argument("unknown option " + key);
      }
      return proto::serve(backend, options);
    }
    throw std::invalid_argument("bad arguments for mode " + mode);
  } catch (const std::exception& e) {
    std::cerr << "protocol_test_peer: " << e.what() << '\n';
    return 10;
  }
}
