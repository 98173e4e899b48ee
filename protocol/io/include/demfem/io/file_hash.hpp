#pragma once
// A checksum of a file's bytes: checkpoint manifests (coupler) and the scene hash of a saved
// DEM state (particle_source.hpp) use it.

#include <cstdint>
#include <filesystem>
#include <string_view>

namespace demfem::io {

/// @brief FNV-1a 64 over the bytes of a file. Throws std::runtime_error naming the file.
std::uint64_t fnv1a64_file(const std::filesystem::path& file);

/// @brief FNV-1a 64 over the bytes of `bytes` (the same value as a file holding them).
std::uint64_t fnv1a64(std::string_view bytes);

}  // namespace demfem::io
