// Segment mapping, rings, futex waiting and liveness (see segment.hpp).
#include "demfem/protocol/segment.hpp"

#include <climits>
#include <condition_variable>
#include <fstream>
#include <mutex>
#include <new>
#include <sstream>
#include <thread>

#include <linux/futex.h>
#include <sched.h>
#include <signal.h>
#include <sys/random.h>
#include <sys/syscall.h>
#include <unistd.h>
#include <boost/interprocess/exceptions.hpp>
#include <boost/interprocess/mapped_region.hpp>
#include <boost/interprocess/permissions.hpp>
#include <boost/interprocess/shared_memory_object.hpp>

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#endif

namespace bip = boost::interprocess;

namespace demfem::protocol::shm {

namespace {

std::uint32_t* futex_address(std::atomic<std::uint32_t>& word) {
  return reinterpret_cast<std::uint32_t*>(&word);
}

// Shared (not FUTEX_PRIVATE) futex: the word lives in memory mapped by several processes.
void futex_wait(std::atomic<std::uint32_t>& word, std::uint32_t expected,
                std::chrono::nanoseconds timeout) {
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(timeout.count() / 1'000'000'000);
  ts.tv_nsec = static_cast<long>(timeout.count() % 1'000'000'000);
  // EAGAIN (value changed), ETIMEDOUT and EINTR all just return to the caller's loop.
  syscall(SYS_futex, futex_address(word), FUTEX_WAIT, expected, &ts, nullptr, 0);
}

void futex_wake(std::atomic<std::uint32_t>& word) {
  syscall(SYS_futex, futex_address(word), FUTEX_WAKE, INT_MAX, nullptr, nullptr, 0);
}

inline void cpu_relax() {
#if defined(__x86_64__) || defined(__i386__)
  _mm_pause();
#else
  std::this_thread::yield();
#endif
}

// Waits until ready() holds. `word` is the futex word that the other side changes (and then
// wakes, if `waiting` is set) when ready() may have become true.
template <class Ready>
void wait_until(std::atomic<std::uint32_t>& word, std::atomic<std::uint32_t>& waiting, Ready ready,
                const Waiter& waiter) {
  if (ready()) return;
  using clock = std::chrono::steady_clock;
  const auto start = clock::now();
  auto next_check = start + waiter.slice;
  const bool spin = !waiter.policy.block || waiter.policy.spin.count() > 0;
  while (spin) {
    for (int i = 0; i < 64; ++i) {
      if (ready()) return;
      cpu_relax();
    }
    // Give the CPU to a runnable thread queued here. The peer we wait for is often that
    // thread: the kernel tends to wake a futex sleeper on the waker's CPU, and without the
    // yield every hand-off would cost a whole spin period.
    if (waiter.policy.yield) sched_yield();
    const auto now = clock::now();
    if (waiter.policy.block && now - start >= waiter.policy.spin) break;
    if (now >= next_check) {
      if (waiter.check) waiter.check();
      next_check = now + waiter.slice;
    }
  }
  for (;;) {
    const std::uint32_t observed = word.load(std::memory_order_acquire);
    waiting.store(1, std::memory_order_relaxed);
    // Pairs with the fence in the waking side: either it sees `waiting`, or we see its store.
    std::atomic_thread_fence(std::memory_order_seq_cst);
    if (ready()) {
      waiting.store(0, std::memory_order_relaxed);
      return;
    }
    futex_wait(word, observed, waiter.slice);
    waiting.store(0, std::memory_order_relaxed);
    if (ready()) return;
    if (waiter.check) waiter.check();
  }
}

}  // namespace

// ---- Bulk layout --------------------------------------------------------------------------

namespace {
std::size_t align64(std::size_t n) {
  return (n + 63) / 64 * 64;
}
}  // namespace

BulkHeader bulk_layout(std::size_t nodes, std::size_t triangles) {
  BulkHeader h{};
  h.magic = kBulkMagic;
  h.version = kProtocolVersion;
  h.node_count = nodes;
  h.triangle_count = triangles;
  h.reference_offset = align64(sizeof(BulkHeader));
  h.triangles_offset = align64(h.reference_offset + 3 * nodes * sizeof(double));
  h.arrays_offset = align64(h.triangles_offset + 3 * triangles * sizeof(std::int32_t));
  h.layout_size =
      align64(h.arrays_offset + InterfaceBuffers::kBufferCount * 5 * 3 * nodes * sizeof(double));
  return h;
}

std::size_t bulk_layout_size(std::size_t nodes, std::size_t triangles) {
  return bulk_layout(nodes, triangles).layout_size;
}

// ---- MappedSegment ------------------------------------------------------------------------

struct MappedSegment::Impl {
  bip::shared_memory_object object;
  bip::mapped_region region;
};

MappedSegment::MappedSegment() = default;
MappedSegment::~MappedSegment() = default;
MappedSegment::MappedSegment(MappedSegment&&) noexcept = default;
MappedSegment& MappedSegment::operator=(MappedSegment&&) noexcept = default;

MappedSegment MappedSegment::create(const std::string& name, std::size_t size) {
  MappedSegment s;
  s.name_ = name;
  try {
    bip::permissions perm(0600);
    auto impl = std::make_unique<Impl>();
    impl->object = bip::shared_memory_object(bip::create_only, name.c_str(), bip::read_write, perm);
    try {
      impl->object.truncate(static_cast<bip::offset_t>(size));
      impl->region = bip::mapped_region(impl->object, bip::read_write);
    } catch (...) {
      bip::shared_memory_object::remove(name.c_str());
      throw;
    }
    s.impl_ = std::move(impl);
  } catch (const bip::interprocess_exception& e) {
    throw ProtocolError("cannot create shared-memory segment " + name + ": " + e.what());
  }
  return s;
}

MappedSegment MappedSegment::open(const std::string& name) {
  MappedSegment s;
  s.name_ = name;
  try {
    auto impl = std::make_unique<Impl>();
    impl->object = bip::shared_memory_object(bip::open_only, name.c_str(), bip::read_write);
    impl->region = bip::mapped_region(impl->object, bip::read_write);
    s.impl_ = std::move(impl);
  } catch (const bip::interprocess_exception& e) {
    throw ProtocolError("cannot open shared-memory segment " + name + ": " + e.what());
  }
  return s;
}

void* MappedSegment::data() const {
  return impl_ ? impl_->region.get_address() : nullptr;
}
std::size_t MappedSegment::size() const {
  return impl_ ? impl_->region.get_size() : 0;
}
bool MappedSegment::valid() const {
  return impl_ != nullptr;
}
bool MappedSegment::remove(const std::string& name) {
  return bip::shared_memory_object::remove(name.c_str());
}

// ---- Ids and liveness ---------------------------------------------------------------------

std::string make_run_id() {
  std::uint64_t value = 0;
  std::size_t got = 0;
  auto* bytes = reinterpret_cast<unsigned char*>(&value);
  while (got < sizeof(value)) {
    const ssize_t n = getrandom(bytes + got, sizeof(value) - got, 0);
    if (n < 0) {
      if (errno == EINTR) continue;
      throw ProtocolError("getrandom failed: " + std::string(std::strerror(errno)));
    }
    got += static_cast<std::size_t>(n);
  }
  char text[17];
  std::snprintf(text, sizeof(text), "%016llx", static_cast<unsigned long long>(value));
  return text;
}

bool process_alive(pid_t pid) {
  if (pid <= 0) return false;
  if (::kill(pid, 0) != 0 && errno != EPERM) return false;
  // A killed child stays a zombie until its parent reaps it; it is dead for our purposes.
  std::ifstream stat("/proc/" + std::to_string(pid) + "/stat");
  if (!stat) return true;  // no procfs: trust kill()
  std::string line;
  std::getline(stat, line);
  const auto paren = line.rfind(')');
  if (paren == std::string::npos || paren + 2 >= line.size()) return true;
  const char state = line[paren + 2];
  return state != 'Z' && state != 'X';
}

std::chrono::milliseconds check_slice(std::chrono::milliseconds peer_timeout) {
  if (peer_timeout < kMinPeerTimeout)
    throw ProtocolError("peer_timeout " + std::to_string(peer_timeout.count()) +
                        " ms is too short; accepted: at least " +
                        std::to_string(kMinPeerTimeout.count()) + " ms");
  return std::clamp(peer_timeout / 10, std::chrono::milliseconds(5),
                    std::chrono::milliseconds(100));
}

std::chrono::milliseconds stale_after(std::chrono::milliseconds peer_timeout) {
  return peer_timeout - check_slice(peer_timeout);
}

PeerWatch::PeerWatch(const ProcessSlot* slot, pid_t known_pid, std::chrono::milliseconds timeout)
    : slot_(slot), known_pid_(known_pid), timeout_(timeout) {}

std::string PeerWatch::check() {
  const auto now = std::chrono::steady_clock::now();
  if (known_pid_ > 0 && !process_alive(known_pid_))
    return "process " + std::to_string(known_pid_) + " is gone";
  if (slot_ == nullptr) return "";
  const pid_t pid = slot_->pid.load(std::memory_order_acquire);
  if (pid == 0) return "";  // not attached yet: only the known pid can be watched
  if (slot_->detached.load(std::memory_order_acquire) != 0)
    return "process " + std::to_string(pid) + " detached";
  if (!process_alive(pid)) return "process " + std::to_string(pid) + " is gone";
  const std::uint64_t hb = slot_->heartbeat.load(std::memory_order_acquire);
  if (!seen_ || hb != last_heartbeat_) {
    seen_ = true;
    last_heartbeat_ = hb;
    last_change_ = now;
    return "";
  }
  if (now - last_change_ > timeout_) {
    const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(now - last_change_);
    return "process " + std::to_string(pid) + " heartbeat stale for " + std::to_string(ms.count()) +
           " ms";
  }
  return "";
}

// ---- Rings --------------------------------------------------------------------------------

bool try_push(Ring& ring, Message& msg) {
  const std::uint32_t head = ring.head.load(std::memory_order_relaxed);
  if (head - ring.cached_tail >= kRingCapacity) {
    ring.cached_tail = ring.tail.load(std::memory_order_acquire);
    if (head - ring.cached_tail >= kRingCapacity) return false;
  }
  msg.sequence = ++ring.pushed;
  const std::size_t used = std::min<std::size_t>(msg.payload_size, kPayloadSize);
  msg.payload_size = static_cast<std::uint16_t>(used);
  std::memcpy(static_cast<void*>(&ring.slots[head % kRingCapacity]), &msg,
              Message::kHeaderSize + used);
  ring.head.store(head + 1, std::memory_order_release);
  std::atomic_thread_fence(std::memory_order_seq_cst);
  if (ring.consumer_waiting.load(std::memory_order_relaxed) != 0) futex_wake(ring.head);
  return true;
}

bool try_pop(Ring& ring, Message& out) {
  const std::uint32_t tail = ring.tail.load(std::memory_order_relaxed);
  const std::uint32_t head = ring.head.load(std::memory_order_acquire);
  if (head == tail) return false;
  const Message& slot = ring.slots[tail % kRingCapacity];
  std::memcpy(static_cast<void*>(&out), &slot, Message::kHeaderSize);
  out.payload_size =
      static_cast<std::uint16_t>(std::min<std::size_t>(out.payload_size, kPayloadSize));
  std::memcpy(out.payload, slot.payload, out.payload_size);
  const std::uint64_t expected = ring.popped + 1;
  ring.popped = expected;
  ring.tail.store(tail + 1, std::memory_order_release);
  std::atomic_thread_fence(std::memory_order_seq_cst);
  if (ring.producer_waiting.load(std::memory_order_relaxed) != 0) futex_wake(ring.tail);
  if (out.sequence != expected)
    throw ProtocolError("ring sequence gap: expected message " + std::to_string(expected) +
                        ", got " + std::to_string(out.sequence));
  return true;
}

void push(Ring& ring, Message& msg, const Waiter& waiter) {
  if (try_push(ring, msg)) return;
  wait_until(
      ring.tail, ring.producer_waiting,
      [&] {
        return ring.head.load(std::memory_order_relaxed) -
                   ring.tail.load(std::memory_order_acquire) <
               kRingCapacity;
      },
      waiter);
  if (!try_push(ring, msg)) throw ProtocolError("ring full after wait (two producers?)");
}

Message pop(Ring& ring, const Waiter& waiter) {
  Message msg;
  if (try_pop(ring, msg)) return msg;
  wait_until(
      ring.head, ring.consumer_waiting,
      [&] {
        return ring.head.load(std::memory_order_acquire) !=
               ring.tail.load(std::memory_order_relaxed);
      },
      waiter);
  if (!try_pop(ring, msg)) throw ProtocolError("ring empty after wait (two consumers?)");
  return msg;
}

void reset(Ring& ring) {
  ring.head.store(0, std::memory_order_relaxed);
  ring.tail.store(0, std::memory_order_relaxed);
  ring.consumer_waiting.store(0, std::memory_order_relaxed);
  ring.producer_waiting.store(0, std::memory_order_relaxed);
  ring.pushed = 0;
  ring.cached_tail = 0;
  ring.popped = 0;
  std::atomic_thread_fence(std::memory_order_seq_cst);
}

// ---- Heartbeat ----------------------------------------------------------------------------

struct Heartbeat::Impl {
  std::mutex mutex;  // process-local, never in shared memory
  std::condition_variable cv;
  bool stop = false;
  std::thread thread;
};

Heartbeat::Heartbeat(ProcessSlot& slot) : impl_(std::make_unique<Impl>()) {
  Impl* impl = impl_.get();
  impl->thread = std::thread([impl, &slot] {
    std::unique_lock lock(impl->mutex);
    while (!impl->stop) {
      slot.heartbeat.fetch_add(1, std::memory_order_release);
      impl->cv.wait_for(lock, kHeartbeatPeriod, [impl] { return impl->stop; });
    }
  });
}

Heartbeat::~Heartbeat() {
  {
    std::lock_guard lock(impl_->mutex);
    impl_->stop = true;
  }
  impl_->cv.notify_all();
  impl_->thread.join();
}

// ---- Text helpers -------------------------------------------------------------------------

void copy_text(char* dest, std::size_t capacity, const std::string& text, const char* what) {
  if (text.size() >= capacity)
    throw ProtocolError(std::string(what) + " is " + std::to_string(text.size()) +
                        " characters long; at most " + std::to_string(capacity - 1) +
                        " fit in a message: " + text);
  std::memset(dest, 0, capacity);
  std::memcpy(dest, text.data(), text.size());
}

void copy_text_truncated(char* dest, std::size_t capacity, const std::string& text) {
  std::memset(dest, 0, capacity);
  std::memcpy(dest, text.data(), std::min(text.size(), capacity - 1));
}

std::string read_text(const char* src, std::size_t capacity) {
  std::size_t n = 0;
  while (n < capacity && src[n] != '\0') ++n;
  return std::string(src, n);
}

}  // namespace demfem::protocol::shm
