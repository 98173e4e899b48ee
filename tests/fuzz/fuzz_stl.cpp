// libFuzzer harness for the STL reader (ASCII and binary): any bytes give a mesh or an
// StlError. The reader takes a path, so the bytes go through an in-memory file (memfd).
#include <sys/mman.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <string>

#include "demfem/dem/shapes/geometry/stl_reader.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const int fd = memfd_create("fuzz.stl", 0);
  if (fd < 0) return 0;
  if (size > 0 && write(fd, data, size) != static_cast<ssize_t>(size)) {
    close(fd);
    return 0;
  }
  try {
    (void)demfem::dem::read_stl("/proc/self/fd/" + std::to_string(fd));
  } catch (const demfem::dem::StlError&) {
  }
  close(fd);
  return 0;
}
