// Coupler side: creates the segments, handshakes, drives the solvers, removes the segments.
#include <signal.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <cstdlib>
#include <cstring>
#include <mutex>

#include "demfem/protocol/protocol.hpp"
#include "demfem/protocol/segment.hpp"

namespace demfem::protocol {

namespace {

// A solver's Error message as the exception the caller sees, with its text and kind.
SolverError solver_error(Role role, const shm::Message& msg) {
  const auto payload = msg.get<shm::ErrorPayload>();
  return SolverError(role, shm::read_text(payload.text, shm::kErrorTextLength),
                     shm::error_kind_of(payload));
}

// ---- Removal on exit() and fatal signals --------------------------------------------------
// Segment paths registered by live sessions. A fixed array of plain chars so that the signal
// handler can read it (unlink() is async-signal-safe; shm_unlink is unlink in /dev/shm).
constexpr std::size_t kCleanupSlots = 16;
constexpr std::size_t kCleanupPath = 96;
struct CleanupEntry {
  std::atomic<int> used{0};
  char path[kCleanupPath]{};
};
std::array<CleanupEntry, kCleanupSlots> g_cleanup;
std::once_flag g_cleanup_once;
struct sigaction g_previous[65];
constexpr std::array<int, 4> kCleanupSignals{SIGTERM, SIGINT, SIGHUP, SIGPIPE};

void unlink_registered() {
  for (auto& entry : g_cleanup)
    if (entry.used.load() == 1) ::unlink(entry.path);
}

void cleanup_signal_handler(int sig) {
  unlink_registered();
  // Only installed over SIG_DFL: restore it and die of the same signal.
  ::signal(sig, SIG_DFL);
  ::raise(sig);
}

void install_cleanup(bool on_signal) {
  std::call_once(g_cleanup_once, [on_signal] {
    std::atexit(unlink_registered);
    if (!on_signal) return;
    for (int sig : kCleanupSignals) {
      struct sigaction old {};
      ::sigaction(sig, nullptr, &old);
      // Keep a handler the program installed (it then unwinds and the destructor cleans up);
      // keep SIG_IGN; only replace the default action, which would skip the destructors.
      if ((old.sa_flags & SA_SIGINFO) == 0 && old.sa_handler == SIG_DFL) {
        struct sigaction sa {};
        sa.sa_handler = cleanup_signal_handler;
        sigemptyset(&sa.sa_mask);
        ::sigaction(sig, &sa, &g_previous[sig]);
      }
    }
  });
}

int register_cleanup(const std::string& name) {
  const std::string path = "/dev/shm" + name;
  if (path.size() >= kCleanupPath) return -1;
  for (std::size_t i = 0; i < kCleanupSlots; ++i) {
    int expected = 0;
    if (g_cleanup[i].used.compare_exchange_strong(expected, 2)) {
      std::memset(g_cleanup[i].path, 0, kCleanupPath);
      std::memcpy(g_cleanup[i].path, path.data(), path.size());
      g_cleanup[i].used.store(1);
      return static_cast<int>(i);
    }
  }
  return -1;
}

void unregister_cleanup(int slot) {
  if (slot >= 0) g_cleanup[static_cast<std::size_t>(slot)].used.store(0);
}

std::size_t index(Role role) {
  return static_cast<std::size_t>(role);
}

}  // namespace

struct CouplerSession::Impl {
  CouplerOptions options;
  std::string run_id;
  std::string name;
  std::string bulk_name;
  shm::MappedSegment segment;
  shm::MappedSegment bulk;
  int cleanup_slot = -1;
  int bulk_cleanup_slot = -1;
  shm::Segment* seg = nullptr;
  std::unique_ptr<shm::Heartbeat> heartbeat;
  std::array<bool, kRoleCount> expected{};
  std::array<bool, kRoleCount> hello{};
  std::array<PeerInfo, kRoleCount> peers{};
  std::array<shm::PeerWatch, kRoleCount> watches{};
  std::array<pid_t, kRoleCount> known_pid{};
  InterfaceBuffers buffers;
  double time = 0.0;
  std::optional<std::chrono::steady_clock::time_point> stop_seen;  // options.stop first set

  shm::Channel& channel(Role role) { return seg->channels[index(role)]; }

  // Throws PeerDied when the solver is gone, VersionMismatch when it was refused.
  void check_peer(Role role) {
    const std::uint32_t refused = seg->fixed.refused_version.load(std::memory_order_acquire);
    if (refused != 0 && seg->fixed.refused_role.load() == static_cast<std::uint32_t>(role))
      throw VersionMismatch(role, kProtocolVersion, refused);
    const std::string why = watches[index(role)].check();
    if (!why.empty()) throw PeerDied(role, why);
    if (options.stop != nullptr && options.stop->load()) {
      const auto now = std::chrono::steady_clock::now();
      if (!stop_seen) stop_seen = now;
      if (now - *stop_seen > options.stop_grace)
        throw ProtocolError("stop requested: the " + std::string(role_name(role)) +
                            " solver did not end within " +
                            std::to_string(options.stop_grace.count()) + " ms");
    }
  }

  shm::Waiter waiter(Role role) {
    shm::Waiter w;
    w.policy = options.wait;
    w.slice = shm::check_slice(options.peer_timeout);
    w.check = [this, role] { check_peer(role); };
    return w;
  }

  void send(Role role, shm::Message& msg) {
    msg.role = static_cast<std::uint16_t>(role);
    msg.time = time;
    shm::push(channel(role).to_solver, msg, waiter(role));
  }

  shm::Message receive(Role role) {
    shm::Waiter w = waiter(role);
    if (options.reply_timeout.count() > 0) {
      const auto deadline = std::chrono::steady_clock::now() + options.reply_timeout;
      w.check = [this, role, deadline] {
        check_peer(role);
        if (std::chrono::steady_clock::now() > deadline)
          throw PeerDied(role, "no reply within reply_timeout (" +
                                   std::to_string(options.reply_timeout.count()) +
                                   " ms); the process is alive but not answering");
      };
    }
    shm::Message msg = shm::pop(channel(role).to_coupler, w);
    if (msg.kind == MessageKind::error) throw solver_error(role, msg);
    return msg;
  }

  shm::Message receive_kind(Role role, MessageKind kind) {
    shm::Message msg = receive(role);
    if (msg.kind != kind)
      throw ProtocolError(std::string("expected ") + message_kind_name(kind) + " from the " +
                          role_name(role) + " solver, got " + message_kind_name(msg.kind));
    return msg;
  }

  // Config: where the bulk arrays are (or that there are none).
  void send_config(Role role) {
    shm::ConfigPayload config{};
    config.node_count = buffers.node_count();
    config.triangle_count = buffers.triangle_count();
    if (!buffers.empty())
      shm::copy_text(config.bulk_segment, shm::kNameLength, bulk_name, "bulk name");
    shm::Message msg;  // payload left unset: only payload_size bytes travel
    msg.kind = MessageKind::config;
    msg.set(config);
    send(role, msg);
    receive_kind(role, MessageKind::config);
  }

  void send_mesh(Role role, bool initialize_buffers) {
    shm::MeshPayload payload{};
    payload.initialize_buffers = initialize_buffers ? 1 : 0;
    shm::Message msg;  // payload left unset: only payload_size bytes travel
    msg.kind = MessageKind::mesh;
    msg.set(payload);
    send(role, msg);
    receive_kind(role, MessageKind::mesh);
  }

  void require_hello(Role role, const char* what) {
    if (!hello[index(role)])
      throw ProtocolError(std::string(what) + ": the " + role_name(role) +
                          " solver has not completed the handshake");
  }
};

CouplerSession::CouplerSession(CouplerOptions options) : impl_(std::make_unique<Impl>()) {
  Impl& s = *impl_;
  s.options = options;
  shm::check_slice(options.peer_timeout);  // validates it before anything is created
  install_cleanup(options.unlink_on_signal);
  remove_stale_segments();
  // A collision of 64-bit random ids is practically impossible; create_only would refuse it.
  for (int attempt = 0;; ++attempt) {
    s.run_id = shm::make_run_id();
    s.name = "/demfem-" + s.run_id;
    try {
      s.segment = shm::MappedSegment::create(s.name, sizeof(shm::Segment));
      break;
    } catch (const ProtocolError&) {
      if (attempt >= 3) throw;
    }
  }
  s.cleanup_slot = register_cleanup(s.name);
  s.seg = new (s.segment.data()) shm::Segment();
  shm::FixedHeader& h = s.seg->fixed;
  h.version = kProtocolVersion;
  h.layout_size = sizeof(shm::Segment);
  std::strncpy(h.run_id, s.run_id.c_str(), sizeof(h.run_id) - 1);
  h.owner_pid.store(::getpid());
  s.seg->coupler.pid.store(::getpid());
  // Magic last: a segment is recognised only once its owner is known.
  std::atomic_thread_fence(std::memory_order_seq_cst);
  h.magic = shm::kSegmentMagic;
  std::atomic_thread_fence(std::memory_order_seq_cst);
  s.heartbeat = std::make_unique<shm::Heartbeat>(s.seg->coupler);
}

CouplerSession::~CouplerSession() {
  Impl& s = *impl_;
  s.heartbeat.reset();
  // Solvers still attached see the coupler leave at their next check, not after a timeout.
  s.seg->coupler.detached.store(1, std::memory_order_release);
  if (!s.bulk_name.empty()) shm::MappedSegment::remove(s.bulk_name);
  unregister_cleanup(s.bulk_cleanup_slot);
  shm::MappedSegment::remove(s.name);
  unregister_cleanup(s.cleanup_slot);
}

const std::string& CouplerSession::segment_name() const {
  return impl_->name;
}

void CouplerSession::expect(Role role) {
  impl_->expected[index(role)] = true;
  impl_->seg->expected[index(role)].store(1);
}

void CouplerSession::wait_hello(Role role, std::optional<pid_t> pid) {
  Impl& s = *impl_;
  const std::size_t r = index(role);
  s.expected[r] = true;
  s.seg->expected[r].store(1);
  s.known_pid[r] = pid.value_or(0);
  s.watches[r] =
      shm::PeerWatch(&s.seg->solvers[r], s.known_pid[r], shm::stale_after(s.options.peer_timeout));
  const bool bounded = s.options.hello_timeout.count() > 0;
  const auto limit = bounded ? s.options.hello_timeout : std::chrono::milliseconds(60000);
  const auto deadline = std::chrono::steady_clock::now() + limit;
  shm::Waiter w = s.waiter(role);
  const bool watchable = s.known_pid[r] > 0;
  w.check = [&s, role, r, deadline, watchable, bounded, limit] {
    s.check_peer(role);
    // Without a limit, a solver that can be watched (known pid, or attached with a heartbeat)
    // may take as long as it lives; an unwatchable wait is always bounded.
    const bool attached = s.seg->solvers[r].pid.load(std::memory_order_acquire) != 0;
    if ((bounded || (!watchable && !attached)) && std::chrono::steady_clock::now() > deadline) {
      const pid_t who = s.known_pid[r] > 0 ? s.known_pid[r]
                                           : s.seg->solvers[r].pid.load(std::memory_order_acquire);
      throw PeerDied(role, "no Hello within " + std::to_string(limit.count()) + " ms" +
                               (who > 0 ? " from process " + std::to_string(who) : "") +
                               (attached ? " (it attached to the segment but never said Hello)"
                                         : " (it started but never attached)"));
    }
  };
  shm::Message msg = shm::pop(s.channel(role).to_coupler, w);
  if (msg.kind == MessageKind::error) throw solver_error(role, msg);
  if (msg.kind != MessageKind::hello)
    throw ProtocolError(std::string("expected hello from the ") + role_name(role) +
                        " solver, got " + message_kind_name(msg.kind));
  const auto hello = msg.get<shm::HelloPayload>();
  if (hello.version != kProtocolVersion) {
    shm::Message err;  // payload left unset: only payload_size bytes travel
    err.kind = MessageKind::error;
    shm::ErrorPayload text{};
    const VersionMismatch mismatch(role, kProtocolVersion, hello.version);
    shm::copy_text_truncated(text.text, shm::kErrorTextLength, mismatch.what());
    err.set(text);
    s.send(role, err);
    throw mismatch;
  }
  if (hello.role != static_cast<std::uint32_t>(role))
    throw ProtocolError(std::string("the solver on the ") + role_name(role) +
                        " channel says it is the " + role_name(static_cast<Role>(hello.role)));
  PeerInfo& info = s.peers[r];
  info.role = role;
  info.pid = hello.pid;
  info.name = shm::read_text(hello.name, shm::kNameLength);
  info.node_count = hello.node_count;
  info.triangle_count = hello.triangle_count;
  info.capabilities = hello.capabilities;
  s.hello[r] = true;
  // From now on watch the pid the solver announced as well.
  if (s.known_pid[r] == 0) s.known_pid[r] = hello.pid;
  s.watches[r] =
      shm::PeerWatch(&s.seg->solvers[r], s.known_pid[r], shm::stale_after(s.options.peer_timeout));
}

const PeerInfo& CouplerSession::peer(Role role) const {
  if (!impl_->hello[index(role)])
    throw ProtocolError(std::string("no Hello from the ") + role_name(role) + " solver yet");
  return impl_->peers[index(role)];
}

InterfaceMesh CouplerSession::exchange_mesh() {
  Impl& s = *impl_;
  for (Role role : {Role::dem, Role::fem})
    if (s.expected[index(role)]) s.require_hello(role, "exchange_mesh");
  const bool fem = s.expected[index(Role::fem)];
  const std::size_t nodes = fem ? s.peers[index(Role::fem)].node_count : 0;
  const std::size_t triangles = fem ? s.peers[index(Role::fem)].triangle_count : 0;

  if (s.bulk.valid() &&
      (nodes != s.buffers.node_count() || triangles != s.buffers.triangle_count()))
    throw ProtocolError("exchange_mesh called again with another interface size");
  if (nodes > 0 && !s.bulk.valid()) {
    s.bulk_name = s.name + "-bulk";
    const shm::BulkHeader layout = shm::bulk_layout(nodes, triangles);
    s.bulk = shm::MappedSegment::create(s.bulk_name, layout.layout_size);
    s.bulk_cleanup_slot = register_cleanup(s.bulk_name);
    auto* base = static_cast<std::byte*>(s.bulk.data());
    shm::BulkHeader header = layout;
    header.owner_pid = ::getpid();
    std::memcpy(base, &header, sizeof(header));
    s.buffers.bind(nodes, triangles, reinterpret_cast<double*>(base + layout.reference_offset),
                   reinterpret_cast<std::int32_t*>(base + layout.triangles_offset),
                   reinterpret_cast<double*>(base + layout.arrays_offset));
  }

  for (Role role : {Role::fem, Role::dem})
    if (s.expected[index(role)]) s.send_config(role);
  if (!fem) return {};
  // The FEM writes its reference mesh into the bulk segment, then the DEM reads it.
  s.send_mesh(Role::fem, true);
  InterfaceMesh mesh = s.buffers.reference_mesh();
  for (std::int32_t t : mesh.triangles)
    if (t < 0 || static_cast<std::size_t>(t) >= nodes)
      throw ProtocolError("the FEM's interface mesh has triangle node index " + std::to_string(t) +
                          " outside [0, " + std::to_string(nodes) + ")");
  if (s.expected[index(Role::dem)]) s.send_mesh(Role::dem, false);
  return mesh;
}

void CouplerSession::reattach(Role role) {
  Impl& s = *impl_;
  s.require_hello(role, "reattach");
  if (role == Role::fem && (s.peers[index(role)].node_count != s.buffers.node_count() ||
                            s.peers[index(role)].triangle_count != s.buffers.triangle_count()))
    throw ProtocolError("the restarted FEM reports " +
                        std::to_string(s.peers[index(role)].node_count) + " interface nodes and " +
                        std::to_string(s.peers[index(role)].triangle_count) +
                        " triangles; the run has " + std::to_string(s.buffers.node_count()) +
                        " and " + std::to_string(s.buffers.triangle_count()));
  s.send_config(role);
  if (!s.buffers.empty()) s.send_mesh(role, false);
}

void CouplerSession::send_step(Role role, const StepCommand& cmd) {
  impl_->require_hello(role, "send_step");
  if (cmd.buffer >= InterfaceBuffers::kBufferCount)
    throw ProtocolError("step buffer " + std::to_string(cmd.buffer) + " out of range [0, 1]");
  shm::Message msg;  // payload left unset: only payload_size bytes travel
  msg.kind = MessageKind::step;
  msg.set(cmd);
  impl_->time = cmd.time;
  impl_->send(role, msg);
}

StepResult CouplerSession::wait_step_done(Role role) {
  impl_->require_hello(role, "wait_step_done");
  shm::Message msg = impl_->receive_kind(role, MessageKind::step_done);
  return msg.get<shm::StepDonePayload>().result;
}

namespace {
void send_file_message(CouplerSession::Impl& s, Role role, MessageKind kind,
                       const std::filesystem::path& file, std::int64_t step) {
  s.require_hello(role, message_kind_name(kind));
  shm::FilePayload payload{};
  payload.step = step;
  shm::copy_text(payload.path, shm::kPathLength, file.string(), "checkpoint path");
  shm::Message msg;  // payload left unset: only payload_size bytes travel
  msg.kind = kind;
  msg.set(payload);
  s.send(role, msg);
}
}  // namespace

void CouplerSession::checkpoint(Role role, const std::filesystem::path& file, std::int64_t step) {
  send_file_message(*impl_, role, MessageKind::checkpoint, file, step);
}

void CouplerSession::restore(Role role, const std::filesystem::path& file, std::int64_t step) {
  send_file_message(*impl_, role, MessageKind::restore, file, step);
}

void CouplerSession::wait_done(Role role) {
  impl_->require_hello(role, "wait_done");
  shm::Message msg = impl_->receive(role);
  if (msg.kind != MessageKind::checkpoint_done && msg.kind != MessageKind::restore_done)
    throw ProtocolError(std::string("expected checkpoint_done or restore_done from the ") +
                        role_name(role) + " solver, got " + message_kind_name(msg.kind));
}

bool CouplerSession::shutdown(Role role) {
  Impl& s = *impl_;
  const std::size_t r = index(role);
  if (!s.hello[r]) return false;
  try {
    shm::Message msg;  // payload left unset: only payload_size bytes travel
    msg.kind = MessageKind::shutdown;
    s.send(role, msg);
    const auto deadline = std::chrono::steady_clock::now() + s.options.peer_timeout;
    shm::Waiter w = s.waiter(role);
    w.check = [&s, role, deadline] {
      s.check_peer(role);
      if (std::chrono::steady_clock::now() > deadline)
        throw PeerDied(role, "no shutdown acknowledgement");
    };
    // Drain whatever is still in flight (a late StepDone) until the acknowledgement.
    for (;;) {
      shm::Message reply = shm::pop(s.channel(role).to_coupler, w);
      if (reply.kind == MessageKind::shutdown) {
        s.hello[r] = false;
        return true;
      }
    }
  } catch (const std::exception&) {
    return false;
  }
}

InterfaceBuffers& CouplerSession::buffers() {
  return impl_->buffers;
}

void CouplerSession::reset_peer(Role role) {
  Impl& s = *impl_;
  const std::size_t r = index(role);
  shm::reset(s.channel(role).to_solver);
  shm::reset(s.channel(role).to_coupler);
  s.seg->solvers[r].heartbeat.store(0);
  s.seg->solvers[r].detached.store(0);
  s.seg->solvers[r].pid.store(0);
  if (s.seg->fixed.refused_role.load() == static_cast<std::uint32_t>(role)) {
    s.seg->fixed.refused_version.store(0);
    s.seg->fixed.refused_pid.store(0);
  }
  s.hello[r] = false;
  s.peers[r] = PeerInfo{};
  s.known_pid[r] = 0;
  s.watches[r] = shm::PeerWatch();
}

void CouplerSession::set_time(double time) {
  impl_->time = time;
}

}  // namespace demfem::protocol
