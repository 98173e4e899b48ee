// Solver side: attach, Hello, then serve the coupler's requests until Shutdown.
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <mutex>
#include <thread>

#include "demfem/protocol/protocol.hpp"
#include "demfem/protocol/segment.hpp"

namespace demfem::protocol {

namespace {

volatile sig_atomic_t g_signal = 0;
// Set by a stop signal or by the watchdog (coupler gone): the backend's long step polls it
// (SolverBackend::set_cancel_flag). Lock-free, so the signal handler may set it.
std::atomic<bool> g_cancel{false};
static_assert(std::atomic<bool>::is_always_lock_free);

void on_stop_signal(int sig) {
  g_signal = sig;
  g_cancel.store(true, std::memory_order_relaxed);
}

// Installs SIGTERM/SIGINT handlers (without SA_RESTART, so a futex wait returns at once) for
// the lifetime of serve() and restores the previous ones afterwards.
class SignalGuard {
 public:
  explicit SignalGuard(bool enable) : enabled_(enable) {
    g_signal = 0;
    g_cancel.store(false);
    if (!enabled_) return;
    struct sigaction sa {};
    sa.sa_handler = on_stop_signal;
    sigemptyset(&sa.sa_mask);
    ::sigaction(SIGTERM, &sa, &old_term_);
    ::sigaction(SIGINT, &sa, &old_int_);
    // SIGUSR1/2 ask demfem_run for a checkpoint; a signal sent to the whole process group or
    // job step (Slurm's --signal without B:) must not end a solver by the default action.
    struct sigaction ignore {};
    ignore.sa_handler = SIG_IGN;
    sigemptyset(&ignore.sa_mask);
    ::sigaction(SIGUSR1, &ignore, &old_usr1_);
    ::sigaction(SIGUSR2, &ignore, &old_usr2_);
  }
  ~SignalGuard() {
    if (!enabled_) return;
    ::sigaction(SIGTERM, &old_term_, nullptr);
    ::sigaction(SIGINT, &old_int_, nullptr);
    ::sigaction(SIGUSR1, &old_usr1_, nullptr);
    ::sigaction(SIGUSR2, &old_usr2_, nullptr);
  }
  SignalGuard(const SignalGuard&) = delete;
  SignalGuard& operator=(const SignalGuard&) = delete;

 private:
  bool enabled_;
  struct sigaction old_term_ {};
  struct sigaction old_int_ {};
  struct sigaction old_usr1_ {};
  struct sigaction old_usr2_ {};
};

struct Interrupted {
  int signal;
};
struct CouplerGone {
  std::string why;
};
// An exception from the backend, to be reported as an Error message.
struct BackendFailure {
  std::string text;
  ErrorKind kind = ErrorKind::failure;
};

// Watches the coupler while the solver computes: the serve loop checks the coupler only while
// it waits for a message, so without this a solver in a long step (10^6 substeps) would run on
// as an orphan until the step ends. Every check slice it looks at the coupler's pid, detached
// flag and heartbeat (its own PeerWatch: the serve loop's is not shared across threads) and,
// when the coupler is gone, records why and sets g_cancel.
class CouplerWatchdog {
 public:
  CouplerWatchdog(const shm::ProcessSlot* coupler, pid_t pid, std::chrono::milliseconds timeout)
      : watch_(coupler, pid, shm::stale_after(timeout)), slice_(shm::check_slice(timeout)) {
    thread_ = std::thread([this] { loop(); });
  }
  ~CouplerWatchdog() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    wake_.notify_all();
    thread_.join();
  }
  CouplerWatchdog(const CouplerWatchdog&) = delete;
  CouplerWatchdog& operator=(const CouplerWatchdog&) = delete;
  /// Why the coupler counts as gone ("" while it is there).
  std::string gone() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return why_;
  }

 private:
  void loop() {
    std::unique_lock<std::mutex> lock(mutex_);
    while (!stop_) {
      wake_.wait_for(lock, slice_, [this] { return stop_; });
      if (stop_ || !why_.empty()) continue;
      lock.unlock();
      std::string why = watch_.check();
      lock.lock();
      if (!why.empty()) {
        why_ = std::move(why);
        g_cancel.store(true, std::memory_order_relaxed);
      }
    }
  }
  shm::PeerWatch watch_;
  std::chrono::milliseconds slice_;
  mutable std::mutex mutex_;
  std::condition_variable wake_;
  bool stop_ = false;
  std::string why_;
  std::thread thread_;
};

class Server {
 public:
  Server(SolverBackend& backend, const ServeOptions& options)
      : backend_(backend), options_(options) {}

  int run() {
    const std::string prefix = "demfem-protocol (" + std::string(role_name(options_.role)) + "): ";
    try {
      return serve_loop();
    } catch (const Interrupted& i) {
      std::fprintf(stderr, "%sstopped by signal %d\n", prefix.c_str(), i.signal);
      detach();
      return 128 + i.signal;
    } catch (const CouplerGone& g) {
      std::fprintf(stderr, "%sthe coupler died: %s\n", prefix.c_str(), g.why.c_str());
      detach();
      // A coupler that is certainly gone (its pid, not only a stale heartbeat) cannot remove
      // its segments any more: the solvers do, so that nothing stays in /dev/shm until the
      // next run (a second remover finds nothing; a stopped coupler keeps them).
      if (options_.remove_orphaned_segments && coupler_pid_ > 0 &&
          !shm::process_alive(coupler_pid_)) {
        shm::MappedSegment::remove(options_.segment + "-bulk");
        shm::MappedSegment::remove(options_.segment);
      }
      return kExitCouplerDied;
    } catch (const BackendFailure& f) {
      std::fprintf(stderr, "%s%s\n", prefix.c_str(), f.text.c_str());
      send_error(f.text, f.kind);
      detach();
      return kExitBackendError;
    } catch (const std::exception& e) {
      std::fprintf(stderr, "%s%s\n", prefix.c_str(), e.what());
      send_error(e.what());
      detach();
      return kExitProtocolError;
    }
  }

 private:
  std::size_t r() const { return static_cast<std::size_t>(options_.role); }
  shm::Channel& channel() { return seg_->channels[r()]; }

  void check() {
    if (g_signal != 0) throw Interrupted{g_signal};
    const std::string why = coupler_watch_.check();
    if (!why.empty()) throw CouplerGone{why};
  }

  shm::Waiter waiter() {
    shm::Waiter w;
    w.policy = options_.wait;
    w.slice = shm::check_slice(options_.peer_timeout);
    w.check = [this] { check(); };
    return w;
  }

  void send(shm::Message& msg) {
    msg.role = static_cast<std::uint16_t>(options_.role);
    msg.time = time_;
    shm::push(channel().to_coupler, msg, waiter());
  }

  void send_error(const std::string& text, ErrorKind kind = ErrorKind::failure) {
    if (!attached_) return;
    try {
      shm::Message msg;  // payload left unset: only payload_size bytes travel
      msg.kind = MessageKind::error;
      shm::ErrorPayload payload{};
      shm::copy_text_truncated(payload.text, shm::kErrorTextLength, text);
      payload.kind = static_cast<std::uint32_t>(kind);
      msg.set(payload);
      // A full ring means the coupler is not listening; do not wait for it.
      msg.role = static_cast<std::uint16_t>(options_.role);
      msg.time = time_;
      shm::try_push(channel().to_coupler, msg);
    } catch (...) {
    }
  }

  void detach() {
    watchdog_.reset();
    heartbeat_.reset();
    if (attached_) seg_->solvers[r()].detached.store(1, std::memory_order_release);
    attached_ = false;
  }

  // A backend that stopped because g_cancel was set: the signal or the dead coupler is the
  // cause, not the backend.
  void throw_if_cancelled() {
    if (g_signal != 0) throw Interrupted{g_signal};
    if (watchdog_) {
      if (std::string why = watchdog_->gone(); !why.empty()) throw CouplerGone{why};
    }
  }

  template <class F>
  auto call_backend(const char* what, F&& f) {
    try {
      return f();
    } catch (const ProtocolError&) {
      throw;  // a message the rules refuse (IterationGate): a protocol error, not the backend's
    } catch (const BackendError& e) {
      throw_if_cancelled();
      throw BackendFailure{std::string(what) + " failed: " + e.what(), e.kind()};
    } catch (const std::exception& e) {
      throw_if_cancelled();
      throw BackendFailure{std::string(what) + " failed: " + e.what()};
    } catch (...) {
      throw_if_cancelled();
      throw BackendFailure{std::string(what) + " failed with an unknown exception"};
    }
  }

  void attach() {
    segment_ = shm::MappedSegment::open(options_.segment);
    if (segment_.size() < sizeof(shm::FixedHeader))
      throw ProtocolError("segment " + options_.segment + " is too small to be a demfem segment");
    auto* fixed = static_cast<shm::FixedHeader*>(segment_.data());
    if (fixed->magic != shm::kSegmentMagic)
      throw ProtocolError("segment " + options_.segment + " is not a demfem segment (bad magic)");
    const std::uint32_t ours =
        options_.claimed_version != 0 ? options_.claimed_version : kProtocolVersion;
    if (fixed->version != ours) {
      // Tell the coupler through the version-independent part of the header.
      fixed->refused_role.store(static_cast<std::uint32_t>(options_.role));
      fixed->refused_pid.store(::getpid());
      fixed->refused_version.store(ours, std::memory_order_release);
      throw VersionMismatchExit{fixed->version, ours};
    }
    if (fixed->layout_size != sizeof(shm::Segment) || segment_.size() < sizeof(shm::Segment))
      throw ProtocolError("segment " + options_.segment + " has layout size " +
                          std::to_string(fixed->layout_size) + ", expected " +
                          std::to_string(sizeof(shm::Segment)));
    seg_ = static_cast<shm::Segment*>(segment_.data());
    coupler_pid_ = fixed->owner_pid.load();
    coupler_watch_ = shm::PeerWatch(&seg_->coupler, fixed->owner_pid.load(),
                                    shm::stale_after(options_.peer_timeout));
    if (const std::string why = coupler_watch_.check(); !why.empty()) throw CouplerGone{why};
    shm::ProcessSlot& slot = seg_->solvers[r()];
    std::int32_t expected = 0;
    if (!slot.pid.compare_exchange_strong(expected, ::getpid()))
      throw ProtocolError("the " + std::string(role_name(options_.role)) + " slot of segment " +
                          options_.segment + " is already taken by process " +
                          std::to_string(expected));
    slot.detached.store(0);
    attached_ = true;
    heartbeat_ = std::make_unique<shm::Heartbeat>(slot);
    watchdog_ =
        std::make_unique<CouplerWatchdog>(&seg_->coupler, coupler_pid_, options_.peer_timeout);
  }

  struct VersionMismatchExit {
    std::uint32_t segment_version;
    std::uint32_t ours;
  };

  void attach_bulk(const shm::ConfigPayload& config) {
    buffers_ = InterfaceBuffers{};
    bulk_ = shm::MappedSegment{};
    if (config.node_count == 0) return;
    const std::string name = shm::read_text(config.bulk_segment, shm::kNameLength);
    bulk_ = shm::MappedSegment::open(name);
    const shm::BulkHeader expected = shm::bulk_layout(config.node_count, config.triangle_count);
    auto* base = static_cast<std::byte*>(bulk_.data());
    shm::BulkHeader header;
    std::memcpy(&header, base, sizeof(header));
    if (header.magic != shm::kBulkMagic || header.layout_size != expected.layout_size ||
        bulk_.size() < expected.layout_size || header.node_count != config.node_count ||
        header.triangle_count != config.triangle_count)
      throw ProtocolError("bulk segment " + name + " does not match the announced " +
                          std::to_string(config.node_count) + " nodes and " +
                          std::to_string(config.triangle_count) + " triangles");
    buffers_.bind(config.node_count, config.triangle_count,
                  reinterpret_cast<double*>(base + expected.reference_offset),
                  reinterpret_cast<std::int32_t*>(base + expected.triangles_offset),
                  reinterpret_cast<double*>(base + expected.arrays_offset));
  }

  void handle_mesh(const shm::MeshPayload& request) {
    if (mesh_) {
      // The mesh owner writes its reference mesh into the bulk segment.
      if (buffers_.node_count() != mesh_->node_count() ||
          buffers_.triangle_count() != mesh_->triangle_count())
        throw ProtocolError("bulk segment sized for " + std::to_string(buffers_.node_count()) +
                            " nodes, but the published mesh has " +
                            std::to_string(mesh_->node_count()));
      auto* base = static_cast<std::byte*>(bulk_.data());
      const shm::BulkHeader layout = shm::bulk_layout(mesh_->node_count(), mesh_->triangle_count());
      std::memcpy(base + layout.reference_offset, mesh_->reference_positions.data(),
                  mesh_->reference_positions.size() * sizeof(double));
      std::memcpy(base + layout.triangles_offset, mesh_->triangles.data(),
                  mesh_->triangles.size() * sizeof(std::int32_t));
      // Start both buffers at the reference configuration (not when a restarted FEM
      // re-publishes its mesh: the buffers then hold the run's current state).
      for (std::uint32_t b = 0;
           request.initialize_buffers != 0 && b < InterfaceBuffers::kBufferCount; ++b) {
        auto pos = buffers_.positions(b);
        std::copy(mesh_->reference_positions.begin(), mesh_->reference_positions.end(),
                  pos.begin());
        auto dem = buffers_.dem_positions(b);
        std::copy(mesh_->reference_positions.begin(), mesh_->reference_positions.end(),
                  dem.begin());
      }
    } else {
      const InterfaceMesh mesh = buffers_.reference_mesh();
      call_backend("on_mesh", [&] {
        backend_.on_mesh(mesh);
        return 0;
      });
    }
  }

  // The launcher names the role it started the process for (DEMFEM_ROLE, dem or fem): a
  // program that serves the other side (an FEM backend given as dem.command) would take the
  // other solver's slot of the segment; it is refused before it attaches (issue 36).
  void check_started_role() const {
    const char* env = std::getenv("DEMFEM_ROLE");
    if (env == nullptr || *env == '\0') return;
    const std::string started = env;
    if (started == role_name(options_.role)) return;
    throw ProtocolError("demfem started this program as its " + started +
                        " solver (DEMFEM_ROLE=" + started + "), but it serves the " +
                        role_name(options_.role) +
                        " side of the protocol: it was refused before attaching to segment " +
                        options_.segment + " (a " + role_name(options_.role) +
                        " backend belongs in " + role_name(options_.role) + ".command, or call "
                        "serve() with the role " + started + ")");
  }

  int serve_loop() {
    check_started_role();
    try {
      attach();
    } catch (const VersionMismatchExit& v) {
      std::fprintf(stderr,
                   "demfem-protocol (%s): protocol version mismatch: segment %s speaks protocol "
                   "version %u, this solver speaks version %u; refusing to attach\n",
                   role_name(options_.role), options_.segment.c_str(), v.segment_version, v.ours);
      return kExitVersionMismatch;
    }
    backend_.set_cancel_flag(&g_cancel);
    mesh_ = call_backend("published_mesh", [&] { return backend_.published_mesh(); });
    if (mesh_) {
      const std::size_t n = mesh_->node_count();
      if (mesh_->reference_positions.size() != 3 * n || mesh_->triangles.size() % 3 != 0)
        throw BackendFailure{"published_mesh: array sizes are not multiples of 3"};
      for (std::int32_t t : mesh_->triangles)
        if (t < 0 || static_cast<std::size_t>(t) >= n)
          throw BackendFailure{"published_mesh: triangle node index " + std::to_string(t) +
                               " outside [0, " + std::to_string(n) + ")"};
    }
    {
      shm::HelloPayload hello{};
      hello.version = options_.claimed_version != 0 ? options_.claimed_version : kProtocolVersion;
      hello.role = static_cast<std::uint32_t>(options_.role);
      hello.pid = ::getpid();
      hello.node_count = mesh_ ? mesh_->node_count() : 0;
      hello.triangle_count = mesh_ ? mesh_->triangle_count() : 0;
      hello.capabilities =
          call_backend("supports_iteration", [&] { return backend_.supports_iteration(); })
              ? kCapabilityIteration
              : 0;
      shm::copy_text_truncated(hello.name, shm::kNameLength,
                               call_backend("name", [&] { return backend_.name(); }));
      shm::Message msg;  // payload left unset: only payload_size bytes travel
      msg.kind = MessageKind::hello;
      msg.set(hello);
      send(msg);
    }
    for (;;) {
      shm::Message msg = shm::pop(channel().to_solver, waiter());
      time_ = msg.time;
      shm::Message reply;  // payload left unset: only payload_size bytes travel
      switch (msg.kind) {
        case MessageKind::config:
          attach_bulk(msg.get<shm::ConfigPayload>());
          reply.kind = MessageKind::config;
          break;
        case MessageKind::mesh:
          handle_mesh(msg.get<shm::MeshPayload>());
          reply.kind = MessageKind::mesh;
          break;
        case MessageKind::step: {
          const auto cmd = msg.get<StepCommand>();
          if (cmd.buffer >= InterfaceBuffers::kBufferCount)
            throw ProtocolError("step names buffer " + std::to_string(cmd.buffer) +
                                ", accepted range [0, 1]");
          time_ = cmd.time;
          shm::StepDonePayload done{};
          done.step = cmd.step;
          done.result = call_backend("step", [&] { return gate_.step(backend_, cmd, buffers_); });
          throw_if_cancelled();
          reply.kind = MessageKind::step_done;
          reply.set(done);
          break;
        }
        case MessageKind::checkpoint:
        case MessageKind::restore: {
          const auto file = msg.get<shm::FilePayload>();
          const std::filesystem::path path = shm::read_text(file.path, shm::kPathLength);
          if (msg.kind == MessageKind::checkpoint) {
            call_backend("write_checkpoint", [&] {
              gate_.accept(backend_);  // a checkpoint holds an accepted step
              backend_.write_checkpoint(path, file.step);
              return 0;
            });
            reply.kind = MessageKind::checkpoint_done;
          } else {
            gate_.discard();  // a held-back step is not part of the restored state
            call_backend("restore_checkpoint", [&] {
              backend_.restore_checkpoint(path, file.step);
              return 0;
            });
            reply.kind = MessageKind::restore_done;
          }
          break;
        }
        case MessageKind::shutdown:
          call_backend("accept_step", [&] {
            gate_.accept(backend_);  // the last step is final
            return 0;
          });
          reply.kind = MessageKind::shutdown;
          send(reply);
          detach();
          return kExitOk;
        case MessageKind::error:
          throw ProtocolError(
              "the coupler refused: " +
              shm::read_text(msg.get<shm::ErrorPayload>().text, shm::kErrorTextLength));
        default:
          throw ProtocolError(std::string("unexpected message from the coupler: ") +
                              message_kind_name(msg.kind));
      }
      send(reply);
    }
  }

  SolverBackend& backend_;
  ServeOptions options_;
  shm::MappedSegment segment_;
  shm::MappedSegment bulk_;
  pid_t coupler_pid_ = 0;  // the segment's owner
  shm::Segment* seg_ = nullptr;
  shm::PeerWatch coupler_watch_;
  std::unique_ptr<shm::Heartbeat> heartbeat_;
  std::unique_ptr<CouplerWatchdog> watchdog_;
  bool attached_ = false;
  std::optional<InterfaceMesh> mesh_;
  InterfaceBuffers buffers_;
  IterationGate gate_;
  double time_ = 0.0;
};

}  // namespace

int serve(SolverBackend& backend, const ServeOptions& options) {
  SignalGuard guard(options.handle_signals);
  Server server(backend, options);
  return server.run();
}

namespace {
std::atomic<int> g_held_signal{0};
void on_held_signal(int sig) { g_held_signal.store(sig); }
}  // namespace

HeldStopSignals::HeldStopSignals() {
  g_held_signal.store(0);
  struct sigaction sa {};
  sa.sa_handler = on_held_signal;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = SA_RESTART;  // the writes go on
  ::sigaction(SIGTERM, &sa, &old_term_);
  ::sigaction(SIGINT, &sa, &old_int_);
}

HeldStopSignals::~HeldStopSignals() {
  ::sigaction(SIGTERM, &old_term_, nullptr);
  ::sigaction(SIGINT, &old_int_, nullptr);
}

int HeldStopSignals::signal() const { return g_held_signal.load(); }

}  // namespace demfem::protocol
