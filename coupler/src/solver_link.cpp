#include "demfem/coupling/solver_link.hpp"

#include <algorithm>
#include <condition_variable>
#include <cstdio>
#include <functional>
#include <mutex>
#include <stdexcept>
#include <thread>

namespace demfem::coupling {

namespace {
std::size_t index(Role role) {
  return static_cast<std::size_t>(role);
}
}  // namespace

// One long-lived thread that runs a task at a time: a thread per step would cost its start
// every step, and the OpenMP team of a solver that uses one would be made afresh each time.
class LocalLink::Worker {
 public:
  Worker() : thread_([this] { loop(); }) {}
  ~Worker() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    wake_.notify_all();
    thread_.join();
  }
  void start(std::function<void()> task) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      task_ = std::move(task);
      busy_ = true;
    }
    wake_.notify_all();
  }
  void wait() {
    std::unique_lock<std::mutex> lock(mutex_);
    wake_.wait(lock, [this] { return !busy_; });
  }

 private:
  void loop() {
    std::unique_lock<std::mutex> lock(mutex_);
    for (;;) {
      wake_.wait(lock, [this] { return stop_ || task_; });
      if (stop_) return;
      auto task = std::move(task_);
      task_ = nullptr;
      lock.unlock();
      task();  // run_step() catches everything
      lock.lock();
      busy_ = false;
      wake_.notify_all();
    }
  }
  std::mutex mutex_;
  std::condition_variable wake_;
  std::function<void()> task_;
  bool busy_ = false;
  bool stop_ = false;
  std::thread thread_;
};

LocalLink::LocalLink(std::unique_ptr<protocol::SolverBackend> dem,
                     std::unique_ptr<protocol::SolverBackend> fem) {
  backends_[index(Role::dem)] = std::move(dem);
  backends_[index(Role::fem)] = std::move(fem);
}

LocalLink::~LocalLink() = default;

bool LocalLink::supports_iteration(Role role) const {
  auto* b = backend(role);
  return b != nullptr && b->supports_iteration();
}

bool LocalLink::has(Role role) const {
  return backends_[index(role)] != nullptr;
}

protocol::SolverBackend* LocalLink::backend(Role role) const {
  return backends_[index(role)].get();
}

InterfaceMesh LocalLink::start() {
  InterfaceMesh mesh;
  // serve() asks every backend for its mesh before Hello; do the same, in the same order.
  if (auto* dem = backend(Role::dem)) (void)dem->published_mesh();
  if (auto* fem = backend(Role::fem)) {
    auto published = fem->published_mesh();
    if (!published) throw std::runtime_error("the FEM backend published no interface mesh");
    mesh = std::move(*published);
  }
  // The same layout as the bulk segment: reference mesh, then [buffer][array][3n].
  const std::size_t n = mesh.node_count();
  reference_ = mesh.reference_positions;
  triangles_ = mesh.triangles;
  arrays_.assign(InterfaceBuffers::kBufferCount * 5 * 3 * n, 0.0);
  buffers_.bind(n, mesh.triangle_count(), reference_.data(), triangles_.data(), arrays_.data());
  // As serve() does for the mesh owner: both buffers start at the reference configuration.
  for (std::uint32_t b = 0; b < InterfaceBuffers::kBufferCount; ++b) {
    std::copy(reference_.begin(), reference_.end(), buffers_.positions(b).begin());
    std::copy(reference_.begin(), reference_.end(), buffers_.dem_positions(b).begin());
  }
  if (auto* dem = backend(Role::dem); dem && backend(Role::fem)) dem->on_mesh(mesh);
  return mesh;
}

std::string LocalLink::name(Role role) const {
  auto* b = backend(role);
  return b ? b->name() : std::string();
}

void LocalLink::send_step(Role role, const StepCommand& cmd) {
  auto* b = backend(role);
  if (!b) throw std::logic_error(std::string("no ") + protocol::role_name(role) + " solver");
  const std::size_t r = index(role);
  if (sent_[r] || results_[r] || errors_[r])
    throw std::logic_error("send_step while a step of that solver is in progress");
  sent_[r] = cmd;
}

// Runs the sent step of `role` through its gate (as serve() would) and keeps the outcome.
void LocalLink::run_step(Role role) {
  const std::size_t r = index(role);
  const StepCommand cmd = *sent_[r];
  sent_[r].reset();
  try {
    results_[r] = gates_[r].step(*backends_[r], cmd, buffers_);
  } catch (...) {
    errors_[r] = std::current_exception();
  }
}

StepResult LocalLink::wait_step_done(Role role) {
  const std::size_t r = index(role);
  if (sent_[r]) {
    const std::size_t other = 1 - r;
    if (sent_[other]) {
      // Both solvers have a step to do: the FEM's on the worker, the DEM's here.
      if (!worker_) worker_ = std::make_unique<Worker>();
      worker_->start([this] { run_step(Role::fem); });
      run_step(Role::dem);
      worker_->wait();
    } else {
      run_step(role);
    }
  }
  if (errors_[r]) {
    std::exception_ptr e = errors_[r];
    errors_[r] = nullptr;
    std::rethrow_exception(e);
  }
  if (!results_[r]) throw std::logic_error("wait_step_done without send_step");
  StepResult out = *results_[r];
  results_[r].reset();
  return out;
}

void LocalLink::checkpoint(Role role, const std::filesystem::path& file, std::int64_t step) {
  gates_[index(role)].accept(*backend(role));  // a checkpoint holds an accepted step
  backend(role)->write_checkpoint(file, step);
}

void LocalLink::restore(Role role, const std::filesystem::path& file, std::int64_t step) {
  const std::size_t r = index(role);
  gates_[r].discard();
  sent_[r].reset(), results_[r].reset(), errors_[r] = nullptr;
  backend(role)->restore_checkpoint(file, step);
}

void LocalLink::shutdown() {
  for (Role role : {Role::dem, Role::fem}) {
    auto* b = backend(role);
    if (!b) continue;
    try {
      gates_[index(role)].accept(*b);
    } catch (const std::exception& e) {  // never throws, as serve() answers Shutdown
      std::fprintf(stderr, "%s: accepting the last step failed: %s\n", protocol::role_name(role),
                   e.what());
    }
  }
}

RemoteLink::RemoteLink(protocol::CouplerSession& session, std::optional<pid_t> dem_pid,
                       std::optional<pid_t> fem_pid)
    : session_(session) {
  pids_[index(Role::dem)] = dem_pid;
  pids_[index(Role::fem)] = fem_pid;
}

bool RemoteLink::has(Role role) const {
  return pids_[index(role)].has_value();
}

std::string RemoteLink::description(Role role) const {
  const std::string& d = descriptions_[index(role)];
  return d.empty() ? std::string("the ") + protocol::role_name(role) + " solver" : d;
}

InterfaceMesh RemoteLink::start() {
  for (Role r : {Role::fem, Role::dem}) {
    if (has(r)) session_.expect(r);
  }
  // A process that dies before it attaches is reported by the launcher (PeerDied, with its
  // exit status); one that answers with an error or breaks the protocol is named here.
  Role current = Role::fem;
  auto handshake_failure = [&](const std::exception& e, const char* how, bool bad_input = false) {
    return HandshakeFailed(current,
                           description(current) + " " + how + " in its handshake: " + e.what(),
                           bad_input);
  };
  try {
    for (Role r : {Role::fem, Role::dem}) {
      if (!has(r)) continue;
      current = r;
      session_.wait_hello(r, pids_[index(r)]);
      if (on_hello_) on_hello_(r, session_.peer(r).pid);
    }
    if (has(Role::fem) && expected_fem_nodes_ &&
        session_.peer(Role::fem).node_count != *expected_fem_nodes_) {
      const auto& p = session_.peer(Role::fem);
      throw InterfaceMismatch(description(Role::fem) + " (\"" + p.name +
                              "\") reports an interface of " + std::to_string(p.node_count) +
                              " nodes, but " + expected_fem_what_ + " has " +
                              std::to_string(*expected_fem_nodes_) +
                              "; it is refused (is it the structure of this scene?)");
    }
    current = Role::fem;
    return session_.exchange_mesh();
  } catch (const protocol::PeerDied&) {
    throw;
  } catch (const protocol::VersionMismatch& e) {
    // Built against another demfem: named, so that the user knows which program to rebuild.
    throw handshake_failure(e, "was refused");
  } catch (const InterfaceMismatch&) {
    throw;
  } catch (const protocol::SolverError& e) {
    // The mesh goes to both solvers: the error names the one that sent it, not the FEM whose
    // turn the exchange began with.
    current = e.role();
    throw handshake_failure(e, "reported an error", e.kind() == protocol::ErrorKind::bad_input);
  } catch (const protocol::ProtocolError& e) {
    throw handshake_failure(e, "broke the protocol");
  }
}

std::string RemoteLink::name(Role role) const {
  return has(role) ? session_.peer(role).name : std::string();
}

bool RemoteLink::supports_iteration(Role role) const {
  return has(role) && (session_.peer(role).capabilities & protocol::kCapabilityIteration) != 0;
}

void RemoteLink::send_step(Role role, const StepCommand& cmd) {
  session_.set_time(cmd.time);
  session_.send_step(role, cmd);
}

StepResult RemoteLink::wait_step_done(Role role) {
  return session_.wait_step_done(role);
}

InterfaceBuffers& RemoteLink::buffers() {
  return session_.buffers();
}

// Paths go to the solver absolute: it may run in another folder than the coupler (an
// external backend runs in the scene's folder), where a relative path names another file.
void RemoteLink::checkpoint(Role role, const std::filesystem::path& file, std::int64_t step) {
  session_.checkpoint(role, std::filesystem::absolute(file), step);
  session_.wait_done(role);
}

void RemoteLink::restore(Role role, const std::filesystem::path& file, std::int64_t step) {
  session_.restore(role, std::filesystem::absolute(file), step);
  session_.wait_done(role);
}

void RemoteLink::shutdown() {
  for (Role r : {Role::dem, Role::fem}) {
    if (has(r)) session_.shutdown(r);
  }
}

}  // namespace demfem::coupling
