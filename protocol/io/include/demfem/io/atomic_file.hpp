#pragma once
// Output that is either whole or absent: write to "<name>.part" and rename on commit, so a
// crash never leaves a half-written file under the final name.

#include <filesystem>

namespace demfem::io {

/// @brief Path of the temporary file that becomes `final_path` on commit.
std::filesystem::path partial_path(const std::filesystem::path& final_path);

/// @brief fsyncs the partial file and atomically renames it to `final_path`.
void commit_partial(const std::filesystem::path& final_path);

/// @brief Writes `text` to `final_path` atomically.
void write_file_atomic(const std::filesystem::path& final_path, const std::string& text);

}  // namespace demfem::io
