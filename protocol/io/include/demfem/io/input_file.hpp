#pragma once
// Reading a user's input file (scene, mesh, geometry) whole, with a size limit. A path that
// is not a regular file (a directory, a FIFO, a device such as /dev/zero) is refused before a
// byte is read, so no input can make a reader grow without bound or block forever; every
// message names the file, what it is, and what was expected.

#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <string_view>

namespace demfem::io {

/// @brief The file cannot be used as input; what() is "<path>: <problem>; expected <what>".
class InputFileError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Limits of the readers (docs/reliability.md explains the choice). A scene is hand-written
/// TOML of a few kB; 16 MiB is a thousand times the largest in cases/.
inline constexpr std::uint64_t kSceneFileLimit = std::uint64_t{16} << 20;
/// Meshes (.inp, all its *INCLUDE files together) and STL geometry: 1 GiB holds about 8
/// million hexahedra with their nodes (or 21 million binary STL triangles), more than the
/// direct FEM solver can factorise on a workstation (bench/fem_step: 1e5 DOF take minutes).
inline constexpr std::uint64_t kMeshFileLimit = std::uint64_t{1} << 30;

/// @brief Human-readable size, "16 MiB", "1 GiB", "1234 bytes".
std::string describe_size(std::uint64_t bytes);

/// @brief The whole content of the regular file `path`, at most `max_bytes` bytes. `what`
/// says what the file should be ("a scene file (TOML)"). Throws InputFileError when the path
/// does not exist, is not a regular file (directory, FIFO, socket, character or block
/// device), cannot be opened or read, or holds more than `max_bytes` (the limit is stated).
/// Opening never blocks (O_NONBLOCK), and the type is checked on the opened descriptor, so a
/// path swapped for a FIFO between check and read is refused too.
std::string read_regular_file(const std::filesystem::path& path, std::uint64_t max_bytes,
                              std::string_view what);

}  // namespace demfem::io
