// Names, exceptions, interface buffer views and stale-segment removal.
#include <dirent.h>
#include <sys/stat.h>

#include <cstring>
#include <ctime>

#include "demfem/protocol/protocol.hpp"
#include "demfem/protocol/segment.hpp"

namespace demfem::protocol {

const char* role_name(Role role) {
  return role == Role::dem ? "dem" : "fem";
}

const char* message_kind_name(MessageKind kind) {
  switch (kind) {
    case MessageKind::hello:
      return "hello";
    case MessageKind::config:
      return "config";
    case MessageKind::mesh:
      return "mesh";
    case MessageKind::step:
      return "step";
    case MessageKind::step_done:
      return "step_done";
    case MessageKind::checkpoint:
      return "checkpoint";
    case MessageKind::checkpoint_done:
      return "checkpoint_done";
    case MessageKind::restore:
      return "restore";
    case MessageKind::restore_done:
      return "restore_done";
    case MessageKind::shutdown:
      return "shutdown";
    case MessageKind::error:
      return "error";
  }
  return "unknown";
}

PeerDied::PeerDied(Role role, const std::string& why)
    : ProtocolError(std::string(role_name(role)) + " solver died: " + why), role_(role) {}

const char* error_kind_name(ErrorKind kind) {
  switch (kind) {
    case ErrorKind::failure:
      return "failure";
    case ErrorKind::bad_input:
      return "bad_input";
    case ErrorKind::blow_up:
      return "blow_up";
  }
  return "failure";
}

SolverError::SolverError(Role role, const std::string& text, ErrorKind kind)
    : ProtocolError(std::string(role_name(role)) + " solver reported " +
                    (kind == ErrorKind::bad_input ? "a bad model"
                     : kind == ErrorKind::blow_up ? "a blow-up"
                                                  : "an error") +
                    ": " + text),
      role_(role),
      text_(text),
      kind_(kind) {}

VersionMismatch::VersionMismatch(Role role, std::uint32_t ours, std::uint32_t theirs)
    : ProtocolError(std::string("protocol version mismatch: the ") + role_name(role) +
                    " solver speaks protocol version " + std::to_string(theirs) +
                    ", the coupler speaks version " + std::to_string(ours)),
      ours_(ours),
      theirs_(theirs) {}

// ---- InterfaceBuffers ---------------------------------------------------------------------

void InterfaceBuffers::bind(std::size_t nodes, std::size_t triangles, double* reference_positions,
                            std::int32_t* triangle_indices, double* arrays) {
  node_count_ = nodes;
  triangle_count_ = triangles;
  reference_positions_ = reference_positions;
  triangles_ = triangle_indices;
  arrays_ = arrays;
}

std::span<double> InterfaceBuffers::array(std::uint32_t buffer, std::size_t which) {
  if (buffer >= kBufferCount)
    throw ProtocolError("interface buffer index " + std::to_string(buffer) +
                        " out of range [0, 1]");
  if (arrays_ == nullptr) return {};
  const std::size_t len = 3 * node_count_;
  return {arrays_ + (buffer * kArraysPerBuffer + which) * len, len};
}

InterfaceMesh InterfaceBuffers::reference_mesh() const {
  InterfaceMesh mesh;
  if (reference_positions_ != nullptr)
    mesh.reference_positions.assign(reference_positions_, reference_positions_ + 3 * node_count_);
  if (triangles_ != nullptr) mesh.triangles.assign(triangles_, triangles_ + 3 * triangle_count_);
  return mesh;
}

// ---- Stale segments -----------------------------------------------------------------------

int remove_stale_segments() {
  int removed = 0;
  DIR* dir = ::opendir("/dev/shm");
  if (dir == nullptr) return 0;
  std::vector<std::string> names;
  while (dirent* entry = ::readdir(dir)) {
    if (std::strncmp(entry->d_name, "demfem-", 7) == 0) names.emplace_back(entry->d_name);
  }
  ::closedir(dir);
  for (const std::string& file : names) {
    const std::string name = "/" + file;
    const std::string path = "/dev/shm/" + file;
    struct stat st {};
    if (::stat(path.c_str(), &st) != 0) continue;
    if (st.st_uid != ::getuid()) continue;  // never touch another user's run
    pid_t owner = 0;
    bool recognised = false;
    try {
      shm::MappedSegment seg = shm::MappedSegment::open(name);
      if (seg.size() >= sizeof(shm::FixedHeader)) {
        const auto* fixed = static_cast<const shm::FixedHeader*>(seg.data());
        const auto* bulk = static_cast<const shm::BulkHeader*>(seg.data());
        if (fixed->magic == shm::kSegmentMagic) {
          recognised = true;
          owner = fixed->owner_pid.load(std::memory_order_acquire);
        } else if (bulk->magic == shm::kBulkMagic) {
          recognised = true;
          owner = bulk->owner_pid;
        }
      }
    } catch (const ProtocolError&) {
      continue;
    }
    bool stale = false;
    if (recognised) {
      stale = !shm::process_alive(owner);
    } else {
      // Not (yet) initialised: a coupler may be creating it right now. Only an old one is a
      // leftover of a crash during creation.
      stale = std::time(nullptr) - st.st_mtime > 30;
    }
    if (stale && shm::MappedSegment::remove(name)) ++removed;
  }
  return removed;
}

}  // namespace demfem::protocol
