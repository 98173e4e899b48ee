#pragma once
// demfem inter-process protocol: the one public header.
//
// A run is one coupler process and up to two solver processes (the DEM and the FEM). The
// coupler creates a fixed-layout POSIX shared-memory segment ("/demfem-<runid>", mode 0600);
// each solver attaches to it by name (`--segment NAME`) and speaks through two lock-free
// single-producer single-consumer rings of fixed-size messages. Interface arrays (node
// positions, velocities, accelerations, forces) live in a second segment
// ("/demfem-<runid>-bulk"), created by the coupler once the FEM's Hello has reported the
// interface size, double-buffered and read in place. See docs/protocol.md for the layout, the
// messages and the lockstep sequence.
//
// An outside solver links `demfem::protocol` (find_package(demfemProtocol)), implements
// SolverBackend and calls serve(). The coupler uses CouplerSession.

#include <array>
#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>

#include <signal.h>
#include <sys/types.h>

#include "demfem/interface/exit_status.hpp"
#include "demfem/interface/interface_mesh.hpp"

namespace demfem::protocol {

/// @brief Version of the segment layout and the messages. Peers of different versions are
/// refused at the handshake. Version 2 added iterated steps (kStepIterate, kStepRedo, the
/// Hello's capabilities) and the solver's compute time in StepDone (docs/protocol.md).
inline constexpr std::uint32_t kProtocolVersion = 2;

/// @brief Which solver a process is.
enum class Role : std::uint8_t { dem = 0, fem = 1 };
inline constexpr std::size_t kRoleCount = 2;

/// @brief "dem" or "fem".
const char* role_name(Role role);

/// @brief Kinds of the fixed-size ring messages (docs/protocol.md has the table).
enum class MessageKind : std::uint32_t {
  hello,
  config,
  mesh,
  step,
  step_done,
  checkpoint,
  checkpoint_done,
  restore,
  restore_done,
  shutdown,
  error
};

/// @brief "hello", "step_done", ...
const char* message_kind_name(MessageKind kind);

/// @brief What an Error message reports, so that the coupler can tell a bad model from a
/// failure (docs/protocol.md, "Errors"). Sent with the text; a peer that does not set it sends
/// zeros, and a value this version does not know reads as `failure`.
enum class ErrorKind : std::uint32_t {
  failure = 0,    ///< the solver failed (I/O, a bug, an unknown cause): the run failed
  bad_input = 1,  ///< the model or scene is wrong, found only by the solver (a mechanism,
                  ///< displacements larger than the model): bad input, like a scene error
  blow_up = 2,    ///< the state became non-finite or unstable (a time step too large)
};

/// @brief "failure", "bad_input" or "blow_up".
const char* error_kind_name(ErrorKind kind);

// Step flags (generic: the coupler's schemes give them meaning).
inline constexpr std::uint32_t kStepStatic = 1;         ///< FEM: static solve, not a dynamic step
inline constexpr std::uint32_t kStepSetKinematics = 2;  ///< DEM: take the buffer's kinematics
                                                        ///< before stepping
/// An iteration of an implicit coupling step (docs/protocol.md, "Iterated steps"): the solver
/// keeps its state at the step's start in memory (SolverBackend::save_iteration_state) and
/// holds back the step's lasting effects (output files, sensor samples, insertions) until the
/// step is accepted. Only sent to a solver whose Hello announced kCapabilityIteration.
inline constexpr std::uint32_t kStepIterate = 4;
/// With kStepIterate: the previous iteration of this step is discarded; the solver returns to
/// the state saved at the step's start, then steps again with the buffer's new inputs.
inline constexpr std::uint32_t kStepRedo = 8;

// Capabilities a solver announces in its Hello (bits).
/// The solver can iterate a coupling step (kStepIterate, kStepRedo): implicit coupling.
inline constexpr std::uint32_t kCapabilityIteration = 1;

/// @brief What a Step message asks a solver to do.
struct StepCommand {
  std::int64_t step = 0;      ///< coupling step index (0-based)
  double time = 0.0;          ///< simulated time at the step's start, s
  double dt = 0.0;            ///< coupling step, s
  std::int64_t substeps = 1;  ///< DEM substeps per coupling step (n^D); 1 for the FEM
  std::uint32_t buffer = 0;   ///< bulk buffer (0 or 1) to read inputs from and write outputs to
  ForceMode force_mode = ForceMode::last_substep;
  std::uint32_t flags = 0;  ///< kStep* bits
};

/// @brief Scalar diagnostics returned in StepDone (meaning defined by each solver, e.g. max
/// overlap, kinetic energy).
struct StepResult {
  std::array<double, 8> values{};
  /// Wall time of the solver's step() in its own process, s (serve() measures it; the
  /// coupler's own timing adds the waiting and the message round trip).
  double compute_seconds = 0.0;
};

/// @brief In-place views of the bulk interface arrays of one run (both buffers). Arrays are
/// node-major xyz, 3 * node_count() doubles each. Empty (node_count() == 0) when the run has
/// no coupled surface (DEM-only scene).
class InterfaceBuffers {
 public:
  static constexpr std::uint32_t kBufferCount = 2;

  InterfaceBuffers() = default;

  std::size_t node_count() const { return node_count_; }
  std::size_t triangle_count() const { return triangle_count_; }
  bool empty() const { return node_count_ == 0; }

  /// FEM → DEM kinematics.
  std::span<double> positions(std::uint32_t buffer) { return array(buffer, 0); }
  std::span<double> velocities(std::uint32_t buffer) { return array(buffer, 1); }
  std::span<double> accelerations(std::uint32_t buffer) { return array(buffer, 2); }
  /// DEM → FEM interface forces (forces the particles exert on the structure), N.
  std::span<double> forces(std::uint32_t buffer) { return array(buffer, 3); }
  /// The DEM's own copy of the mesh node positions at the step's end (drift diagnostic).
  std::span<double> dem_positions(std::uint32_t buffer) { return array(buffer, 4); }

  /// @brief Copy of the reference mesh published by the FEM.
  InterfaceMesh reference_mesh() const;

  /// @brief Points the views at memory: reference positions (3n), triangles (3m) and
  /// `arrays` laid out [buffer 0..1][positions, velocities, accelerations, forces,
  /// dem_positions][3n]. The library binds the bulk segment; an in-process link may bind
  /// its own vectors. The memory must outlive the views.
  void bind(std::size_t nodes, std::size_t triangles, double* reference_positions,
            std::int32_t* triangle_indices, double* arrays);

 private:
  static constexpr std::size_t kArraysPerBuffer = 5;
  std::span<double> array(std::uint32_t buffer, std::size_t which);

  std::size_t node_count_ = 0;
  std::size_t triangle_count_ = 0;
  double* reference_positions_ = nullptr;
  std::int32_t* triangles_ = nullptr;
  double* arrays_ = nullptr;  // [buffer][which][3n]
};

/// @brief An exception a backend throws to say what kind of error it is: serve() sends the kind
/// with the Error message (every other exception is reported as ErrorKind::failure), and the
/// coupler's in-process link passes it on as it is.
class BackendError : public std::runtime_error {
 public:
  BackendError(ErrorKind kind, const std::string& text) : std::runtime_error(text), kind_(kind) {}
  ErrorKind kind() const { return kind_; }

 private:
  ErrorKind kind_;
};

/// @brief Solver side: implemented by each solver (dem_server, fem_server, or an outside code).
/// Exceptions thrown by these functions are sent to the coupler as an Error message (with the
/// kind of a BackendError) and end serve() with a non-zero code.
class SolverBackend {
 public:
  virtual ~SolverBackend() = default;
  /// e.g. "demfem-fem 0.1 (cpu)"; sent in Hello (at most 127 characters are kept).
  virtual std::string name() const = 0;
  /// The FEM returns its coupled surface (called once, before Hello); the DEM returns nullopt.
  virtual std::optional<InterfaceMesh> published_mesh() = 0;
  /// The DEM receives the FEM's mesh (not called when the run has no FEM).
  virtual void on_mesh(const InterfaceMesh& mesh) = 0;
  /// One coupling step; reads inputs from and writes outputs to buffers (cmd.buffer) in place.
  virtual StepResult step(const StepCommand& cmd, InterfaceBuffers& buffers) = 0;
  virtual void write_checkpoint(const std::filesystem::path& file, std::int64_t step) = 0;
  virtual void restore_checkpoint(const std::filesystem::path& file, std::int64_t step) = 0;
  /// serve() calls this once, before Hello, with a flag that turns true when the step in
  /// progress should be abandoned: a stop signal arrived, or the coupler is gone (its pid, or
  /// its heartbeat stale for peer_timeout). A backend whose step can take long polls it (it
  /// is an atomic load; reading it must not change any result) and throws when it is set;
  /// serve() then exits as for the signal or the dead coupler. The default ignores it: the
  /// step is then abandoned only when it ends.
  virtual void set_cancel_flag(const std::atomic<bool>* flag) { (void)flag; }

  // Iterated steps (implicit coupling; docs/protocol.md, "Iterated steps"). serve() calls
  // these through IterationGate; a backend that returns false from supports_iteration() is
  // never sent kStepIterate (the coupler refuses an implicit scheme at the start instead).
  /// Announced in Hello as kCapabilityIteration.
  virtual bool supports_iteration() const { return false; }
  /// Keep the state at the start of the coupling step in memory (no file): the first
  /// iteration of an iterated step. step() then sees kStepIterate and must hold back the
  /// step's lasting effects (output, sensor samples, insertions) until accept_step().
  virtual void save_iteration_state();
  /// Return to the state of save_iteration_state() (the previous iteration is discarded).
  virtual void restore_iteration_state();
  /// The last iterated step is final: write what it held back.
  virtual void accept_step() {}
};

/// @brief The rules of iterated steps (docs/protocol.md), applied between the messages and a
/// backend by serve() and by the coupler's in-process link alike: a Step with kStepIterate
/// saves the state first (or, with kStepRedo, restores it); any other Step, a Checkpoint or a
/// Shutdown accepts a held-back step first; a Restore discards it. Also measures
/// StepResult::compute_seconds.
class IterationGate {
 public:
  /// Applies the flags of `cmd`, then backend.step(). Throws ProtocolError for a kStepRedo
  /// without a save point of the same step, or kStepIterate to a backend without support.
  StepResult step(SolverBackend& backend, const StepCommand& cmd, InterfaceBuffers& buffers);
  /// Before a Checkpoint or a Shutdown: a held-back step is accepted.
  void accept(SolverBackend& backend);
  /// Before a Restore: a held-back step and the save point are dropped.
  void discard();
  /// A step is held back (iterated, not yet accepted).
  bool tentative() const { return tentative_; }

 private:
  bool tentative_ = false;
  std::int64_t saved_step_ = -1;  ///< step whose start state is saved, -1 = none
};

/// @brief How a waiting process waits: spin for `spin` then block on a futex in slices,
/// checking the peer's liveness between slices.
struct WaitPolicy {
  /// Busy-wait time before blocking. Zero: block at once (never burns a core).
  std::chrono::microseconds spin{20};
  /// Block after spinning; false = spin until the message comes (benchmarks only: it
  /// occupies a core; liveness is still checked every few milliseconds).
  bool block = true;
  /// While spinning, yield the CPU every few microseconds, so that a runnable peer (or a
  /// solver thread) queued on this CPU runs instead of waiting for the spin to end.
  bool yield = true;
};

struct ServeOptions {
  std::string segment;  ///< "/demfem-<runid>" as given by the coupler (--segment)
  Role role = Role::dem;
  /// A coupler whose pid is gone or whose heartbeat has not advanced for this long is dead.
  std::chrono::milliseconds peer_timeout{2000};
  WaitPolicy wait{};
  /// Testing only: the protocol version this process claims (0 = kProtocolVersion). Lets a
  /// test act as a peer of another version to check the refusal.
  std::uint32_t claimed_version = 0;
  /// Install SIGTERM/SIGINT handlers for the duration of serve() so that either signal
  /// makes it return promptly (exit code 128 + signal) after detaching cleanly.
  bool handle_signals = true;
  /// When the coupler has died (its pid is gone, not only its heartbeat stale), remove its
  /// segments on the way out, so that none stays in /dev/shm until the next run's cleanup.
  /// Off by default; dem_server and fem_server turn it on.
  bool remove_orphaned_segments = false;
};

/// @brief Attaches to the segment, Hello (version check), mesh exchange, then serves
/// Step/Checkpoint/Restore until Shutdown. Returns the process exit code: 0 after Shutdown;
/// non-zero with a message on stderr when the coupler died, the version differs, the segment
/// cannot be opened, a signal arrived, or the backend threw (its exception text is sent as an
/// Error message first).
int serve(SolverBackend& backend, const ServeOptions& options);

/// @brief Holds SIGTERM and SIGINT back while it lives: for the end state a solver writes after
/// serve() returned kExitOk (the last step is done, the coupler said Shutdown). A stop signal
/// then (the user's Ctrl-C reaching the coupler as it ends, which passes SIGTERM on) used to
/// kill the solver half-way through its last output: the run that had finished counted as
/// failed, and its series lost the row a resume needs. The signal is recorded, not acted on:
/// the work is done, the solver writes and exits 0. A handler, not a blocked mask, so that
/// threads started earlier (OpenMP) cannot take the signal by the default action.
class HeldStopSignals {
 public:
  HeldStopSignals();
  ~HeldStopSignals();
  HeldStopSignals(const HeldStopSignals&) = delete;
  HeldStopSignals& operator=(const HeldStopSignals&) = delete;
  /// The stop signal that came meanwhile, 0 if none.
  int signal() const;

 private:
  struct sigaction old_term_ {};
  struct sigaction old_int_ {};
};

// serve()'s exit codes (kExitOk, kExitBackendError, kExitCouplerDied, kExitVersionMismatch,
// kExitProtocolError) are in demfem/interface/exit_status.hpp with the run's.

/// @brief Base of every protocol failure.
class ProtocolError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// @brief A peer process is gone (pid gone, or heartbeat stale, or never said Hello).
class PeerDied : public ProtocolError {
 public:
  PeerDied(Role role, const std::string& why);
  Role role() const { return role_; }

 private:
  Role role_;
};

/// @brief An Error message from a solver, with its text and kind.
class SolverError : public ProtocolError {
 public:
  SolverError(Role role, const std::string& text, ErrorKind kind = ErrorKind::failure);
  Role role() const { return role_; }
  const std::string& text() const { return text_; }
  ErrorKind kind() const { return kind_; }

 private:
  Role role_;
  std::string text_;
  ErrorKind kind_;
};

/// @brief A solver of another protocol version tried to attach; the message names both.
class VersionMismatch : public ProtocolError {
 public:
  VersionMismatch(Role role, std::uint32_t ours, std::uint32_t theirs);
  std::uint32_t ours() const { return ours_; }
  std::uint32_t theirs() const { return theirs_; }

 private:
  std::uint32_t ours_;
  std::uint32_t theirs_;
};

struct CouplerOptions {
  /// A solver whose pid is gone or whose heartbeat has not advanced for this long is dead.
  std::chrono::milliseconds peer_timeout{2000};
  /// How long wait_hello() waits for the Hello, whether the solver can be watched (known pid,
  /// heartbeat) or not: a solver that started but never attaches (hung in its set-up, or not
  /// a demfem solver at all) is reported (PeerDied) instead of waited for as long as it
  /// lives. Zero: no limit for a solver that can be watched (an unwatchable one still gets
  /// 60 s). Set-up before the Hello includes reading the mesh and, for the FEM, assembling
  /// and factorising its matrices: raise it for very large models.
  std::chrono::milliseconds hello_timeout{600000};
  /// Longest wait for any reply (StepDone, checkpoint_done, ...) of a live solver; zero (the
  /// default) = no limit. The heartbeat proves a solver is alive, not that its step makes
  /// progress: set this to catch a solver that hangs inside step(). On expiry the call
  /// throws PeerDied and the solver is still running (kill it, then reset_peer()).
  std::chrono::milliseconds reply_timeout{0};
  WaitPolicy wait{};
  /// A stop request of the program (its signal handler's flag; nullptr = none). Once it is
  /// set, every wait for a solver gives up (ProtocolError) when the solver has not answered
  /// within `stop_grace`: the program has asked the solvers to stop (SIGTERM), and one that
  /// does not (stuck in a long computation) must not keep the coupler waiting.
  const std::atomic<bool>* stop = nullptr;
  std::chrono::milliseconds stop_grace{3000};
  /// On SIGTERM/SIGINT/SIGHUP with the default action, remove the segments before dying
  /// (handlers the program installed itself are kept and called instead).
  bool unlink_on_signal = true;
};

/// @brief The solver's Hello as the coupler received it.
struct PeerInfo {
  Role role = Role::dem;
  pid_t pid = 0;
  std::string name;
  std::size_t node_count = 0;
  std::size_t triangle_count = 0;
  std::uint32_t capabilities = 0;  ///< kCapability* bits
};

/// @brief Coupler side of one run.
class CouplerSession {
 public:
  /// Creates the segment (removes stale ones of dead owners first).
  explicit CouplerSession(CouplerOptions options = {});
  /// Removes the segments (also on exceptions; exit() and fatal signals via handlers).
  ~CouplerSession();
  CouplerSession(const CouplerSession&) = delete;
  CouplerSession& operator=(const CouplerSession&) = delete;

  /// "/demfem-<runid>", to pass to the solvers as --segment.
  const std::string& segment_name() const;
  /// This run uses this solver.
  void expect(Role role);
  /// Handshake; `pid` is the launched process, if known, to watch while waiting.
  /// Throws VersionMismatch, PeerDied (pid gone, or no Hello within hello_timeout).
  void wait_hello(Role role, std::optional<pid_t> pid);
  /// The Hello of a solver after wait_hello().
  const PeerInfo& peer(Role role) const;
  /// FEM publishes → bulk sized → DEM receives (when both). Returns the mesh (empty when the
  /// run has no FEM).
  InterfaceMesh exchange_mesh();
  void send_step(Role role, const StepCommand& cmd);
  /// Throws PeerDied / SolverError.
  StepResult wait_step_done(Role role);
  /// Sends Checkpoint; wait with wait_done().
  void checkpoint(Role role, const std::filesystem::path& file, std::int64_t step);
  /// Sends Restore; wait with wait_done().
  void restore(Role role, const std::filesystem::path& file, std::int64_t step);
  /// Waits for checkpoint_done / restore_done. Throws PeerDied / SolverError.
  void wait_done(Role role);
  /// Asks the solver to exit and waits briefly (peer_timeout) for its acknowledgement or its
  /// death. Never throws; returns true when the solver acknowledged.
  bool shutdown(Role role);
  InterfaceBuffers& buffers();
  /// After a solver died: clear its rings and slot so a restarted solver can attach again.
  void reset_peer(Role role);
  /// After reset_peer() and wait_hello() of a restarted solver: give it the existing bulk
  /// arrays (Config) and the mesh (the FEM rewrites the reference mesh, the DEM receives it
  /// via on_mesh). The buffers' contents are kept. Throws ProtocolError if a restarted FEM
  /// reports another interface size.
  void reattach(Role role);
  /// Simulated time stamped on the coupler's messages (informational).
  void set_time(double time);

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

// Defined here, not in the library, so that SolverBackend stays header-only (no key function).
inline void SolverBackend::save_iteration_state() {
  throw ProtocolError("the solver '" + name() +
                      "' cannot iterate a coupling step (it keeps no in-memory save point)");
}
inline void SolverBackend::restore_iteration_state() {
  throw ProtocolError("the solver '" + name() +
                      "' cannot iterate a coupling step (it keeps no in-memory save point)");
}

/// @brief Removes "demfem-*" segments in /dev/shm whose owner process is gone. Returns how
/// many were removed. CouplerSession calls it on construction.
int remove_stale_segments();

}  // namespace demfem::protocol
