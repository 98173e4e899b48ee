#pragma once
// Low-level layer of the protocol: the fixed segment layout, the SPSC rings, futex waiting and
// peer liveness. protocol.hpp is the supported API; this header is installed for tests,
// benchmarks and diagnostics tools that need the raw rings.
//
// Nothing in the segment is guarded by a mutex or a condition variable: a process that dies
// at any instant leaves only atomics behind, which the survivor can read (Debian's Boost 1.74
// has no robust interprocess mutexes, and glibc's process-shared condition variables can
// hang when a waiter dies).

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <functional>
#include <memory>
#include <string>

#include <sys/types.h>

#include "demfem/protocol/protocol.hpp"

namespace demfem::protocol::shm {

inline constexpr std::uint64_t kSegmentMagic = 0x31474553'4d454644ULL;  // "DFEMSEG1"
inline constexpr std::uint64_t kBulkMagic = 0x4b4c5542'4d454644ULL;     // "DFEMBULK"
inline constexpr std::size_t kMessageSize = 1024;
inline constexpr std::uint32_t kRingCapacity = 64;  // power of two
inline constexpr std::size_t kPayloadSize = kMessageSize - 24;
inline constexpr std::size_t kNameLength = 128;
inline constexpr std::size_t kPathLength = kPayloadSize - 8;
inline constexpr std::size_t kTextLength = kPayloadSize;

static_assert(std::atomic<std::uint32_t>::is_always_lock_free);
static_assert(std::atomic<std::uint64_t>::is_always_lock_free);
static_assert(sizeof(std::atomic<std::uint32_t>) == 4, "futex words are 32-bit");

/// @brief One fixed-size ring slot. Only the header and the used part of the payload are
/// copied in and out of the ring (a Step is ~70 bytes of the 1024), which keeps a round trip
/// to a few cache lines.
struct Message {
  MessageKind kind = MessageKind::hello;
  std::uint16_t role = 0;          ///< sender's role for solver messages, target role otherwise
  std::uint16_t payload_size = 0;  ///< bytes of payload in use (set by set())
  std::uint64_t sequence = 0;      ///< 1, 2, 3... per ring; set by push()
  double time = 0.0;               ///< simulated time, s
  alignas(8) std::byte payload[kPayloadSize];

  static constexpr std::size_t kHeaderSize = 24;

  template <class T>
  void set(const T& value) {
    static_assert(sizeof(T) <= kPayloadSize && std::is_trivially_copyable_v<T>);
    std::memcpy(payload, &value, sizeof(T));
    payload_size = static_cast<std::uint16_t>(sizeof(T));
  }
  /// The payload as T; bytes the sender did not set read as zero.
  template <class T>
  T get() const {
    static_assert(sizeof(T) <= kPayloadSize && std::is_trivially_copyable_v<T>);
    T value;
    std::memset(static_cast<void*>(&value), 0, sizeof(T));
    std::memcpy(
        static_cast<void*>(&value), payload,
        std::min<std::size_t>(sizeof(T), std::min<std::size_t>(payload_size, kPayloadSize)));
    return value;
  }
};
static_assert(offsetof(Message, payload) == Message::kHeaderSize);
static_assert(sizeof(Message) == kMessageSize);

struct HelloPayload {
  std::uint32_t version;
  std::uint32_t role;
  std::int32_t pid;
  std::uint32_t capabilities;  ///< kCapability* bits (protocol 2; "reserved" in protocol 1)
  std::uint64_t node_count;
  std::uint64_t triangle_count;
  char name[kNameLength];
};
struct ConfigPayload {
  std::uint64_t node_count;
  std::uint64_t triangle_count;
  char bulk_segment[kNameLength];  ///< "" when the run has no coupled surface
};
struct MeshPayload {
  std::uint32_t initialize_buffers;  ///< 1: the mesh owner also sets both buffers' positions
                                     ///< and dem_positions to the reference positions
  std::uint32_t reserved;
};
struct StepDonePayload {
  std::int64_t step;
  StepResult result;
};
struct FilePayload {
  std::int64_t step;
  char path[kPathLength];
};
struct TextPayload {
  char text[kTextLength];
};
/// The Error message: the text where TextPayload has it (so a peer that reads the payload as
/// text still reads it whole), then the kind (protocol::ErrorKind; 0 = failure).
inline constexpr std::size_t kErrorTextLength = kTextLength - 8;
struct ErrorPayload {
  char text[kErrorTextLength];
  std::uint32_t kind;
  std::uint32_t reserved;
};
static_assert(sizeof(ErrorPayload) == kTextLength);
/// The kind of a received Error message; values this version does not know are failures.
inline ErrorKind error_kind_of(const ErrorPayload& p) {
  return p.kind <= static_cast<std::uint32_t>(ErrorKind::blow_up) ? static_cast<ErrorKind>(p.kind)
                                                                  : ErrorKind::failure;
}

/// @brief A single-producer single-consumer ring. head and tail count messages (mod 2^32)
/// and double as futex words.
struct Ring {
  alignas(64) std::atomic<std::uint32_t> head;  ///< written by the producer
  std::atomic<std::uint32_t> consumer_waiting;
  std::uint64_t pushed;       ///< producer's sequence counter
  std::uint32_t cached_tail;  ///< producer's last view of tail (saves a cache miss per push)
  alignas(64) std::atomic<std::uint32_t> tail;  ///< written by the consumer
  std::atomic<std::uint32_t> producer_waiting;
  std::uint64_t popped;  ///< consumer's sequence counter
  alignas(64) Message slots[kRingCapacity];
};

/// @brief Identity and liveness of one process.
struct ProcessSlot {
  std::atomic<std::int32_t> pid;         ///< 0: none attached
  std::atomic<std::uint32_t> detached;   ///< 1 after the process left cleanly
  std::atomic<std::uint64_t> heartbeat;  ///< advanced by the process every kHeartbeatPeriod
};
inline constexpr std::chrono::milliseconds kHeartbeatPeriod{50};
/// @brief Smallest accepted peer_timeout: several heartbeat periods, so that a busy machine
/// does not make a live peer look dead.
inline constexpr std::chrono::milliseconds kMinPeerTimeout{200};

/// @brief How often a waiting process checks its peer: peer_timeout / 10 in [5, 100] ms.
/// Throws ProtocolError if peer_timeout is below kMinPeerTimeout.
std::chrono::milliseconds check_slice(std::chrono::milliseconds peer_timeout);
/// @brief Heartbeat age after which a peer is dead: peer_timeout minus one check slice, so
/// that a stale peer is reported within peer_timeout.
std::chrono::milliseconds stale_after(std::chrono::milliseconds peer_timeout);

struct Channel {
  Ring to_solver;
  Ring to_coupler;
};

/// @brief The part of the header that never moves between protocol versions, so that peers
/// of different versions can still recognise each other and refuse cleanly.
struct FixedHeader {
  std::uint64_t magic;
  std::uint32_t version;
  std::uint32_t reserved;
  std::uint64_t layout_size;
  char run_id[32];
  std::atomic<std::int32_t> owner_pid;         ///< the coupler
  std::atomic<std::uint32_t> refused_version;  ///< a refused peer's version, else 0
  std::atomic<std::uint32_t> refused_role;
  std::atomic<std::int32_t> refused_pid;
};

/// @brief The control segment "/demfem-<runid>".
struct Segment {
  FixedHeader fixed;
  ProcessSlot coupler;
  ProcessSlot solvers[kRoleCount];
  std::atomic<std::uint32_t> expected[kRoleCount];
  Channel channels[kRoleCount];
};

/// @brief Header of the bulk segment "/demfem-<runid>-bulk"; arrays follow at the offsets.
struct BulkHeader {
  std::uint64_t magic;
  std::uint32_t version;
  std::int32_t owner_pid;
  std::uint64_t layout_size;
  std::uint64_t node_count;
  std::uint64_t triangle_count;
  std::uint64_t reference_offset;  ///< 3n double
  std::uint64_t triangles_offset;  ///< 3m int32
  std::uint64_t arrays_offset;     ///< [2 buffers][5 arrays][3n] double
};
/// @brief Total bulk segment size for n nodes and m triangles.
std::size_t bulk_layout_size(std::size_t nodes, std::size_t triangles);
/// @brief Fills the header offsets for n nodes and m triangles.
BulkHeader bulk_layout(std::size_t nodes, std::size_t triangles);

/// @brief A mapped POSIX shared-memory object (Boost.Interprocess shared_memory_object +
/// mapped_region). Unmaps on destruction; remove() unlinks the name.
class MappedSegment {
 public:
  MappedSegment();
  ~MappedSegment();
  MappedSegment(MappedSegment&&) noexcept;
  MappedSegment& operator=(MappedSegment&&) noexcept;

  /// Creates a new object (fails if the name exists), mode 0600, zero-filled.
  static MappedSegment create(const std::string& name, std::size_t size);
  /// Opens an existing object read-write. Throws ProtocolError naming the segment.
  static MappedSegment open(const std::string& name);

  void* data() const;
  std::size_t size() const;
  const std::string& name() const { return name_; }
  bool valid() const;
  /// Unlinks the name (the mapping stays valid). Returns true if it existed.
  static bool remove(const std::string& name);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::string name_;
};

/// @brief A random run id: 16 hex digits from the kernel's random source.
std::string make_run_id();

/// @brief True if the process exists and is not a zombie (a killed child that has not been
/// reaped yet counts as dead).
bool process_alive(pid_t pid);

/// @brief Watches one process through its slot (pid and heartbeat) and an optional pid
/// known beforehand. check() returns "" while alive, else why it is considered dead.
class PeerWatch {
 public:
  PeerWatch() = default;
  /// `stale` is the heartbeat age after which the peer counts as dead (see stale_after()).
  PeerWatch(const ProcessSlot* slot, pid_t known_pid, std::chrono::milliseconds stale);
  std::string check();

 private:
  const ProcessSlot* slot_ = nullptr;
  pid_t known_pid_ = 0;
  std::chrono::milliseconds timeout_{2000};
  std::uint64_t last_heartbeat_ = 0;
  std::chrono::steady_clock::time_point last_change_{};
  bool seen_ = false;
};

/// @brief How to wait and what to check between waits. `check` is called at least every
/// `slice` while waiting; it throws to abandon the wait (peer dead, signal, deadline).
struct Waiter {
  WaitPolicy policy{};
  std::chrono::milliseconds slice{50};
  std::function<void()> check;
};

/// @brief Non-blocking push; false when the ring is full. Sets msg.sequence.
bool try_push(Ring& ring, Message& msg);
/// @brief Non-blocking pop; false when empty. Throws ProtocolError on a sequence gap.
bool try_pop(Ring& ring, Message& out);
/// @brief Blocking push/pop per the waiter's policy.
void push(Ring& ring, Message& msg, const Waiter& waiter);
Message pop(Ring& ring, const Waiter& waiter);
/// @brief Empties a ring (only when neither side is attached).
void reset(Ring& ring);

/// @brief Advances a slot's heartbeat from a background thread until destroyed.
class Heartbeat {
 public:
  explicit Heartbeat(ProcessSlot& slot);
  ~Heartbeat();
  Heartbeat(const Heartbeat&) = delete;
  Heartbeat& operator=(const Heartbeat&) = delete;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// @brief Copies a string into a fixed char array, NUL-terminated; throws ProtocolError if
/// it does not fit.
void copy_text(char* dest, std::size_t capacity, const std::string& text, const char* what);
/// @brief Like copy_text but cuts the text to fit.
void copy_text_truncated(char* dest, std::size_t capacity, const std::string& text);
/// @brief Reads a fixed char array (stops at NUL or capacity).
std::string read_text(const char* src, std::size_t capacity);

}  // namespace demfem::protocol::shm
