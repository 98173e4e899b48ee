#pragma once
// One solver's part of a checkpoint: an HDF5 file that records the coupling step it belongs
// to, written under a temporary name and renamed when complete, so a crash mid-write never
// leaves a file that looks whole.

#include <cstdint>
#include <filesystem>
#include <functional>

#include "demfem/io/h5_file.hpp"

namespace demfem::io {

/// @brief Creates `file` for checkpoint `step`: `write` fills it, then it is committed.
void write_checkpoint_file(const std::filesystem::path& file, std::int64_t step,
                           const std::function<void(H5File&)>& write);

/// @brief Opens `file` for reading and checks that it belongs to checkpoint `step`; throws
/// std::runtime_error naming the file and both steps otherwise.
H5File open_checkpoint_file(const std::filesystem::path& file, std::int64_t step);

}  // namespace demfem::io
