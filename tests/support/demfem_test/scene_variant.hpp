#pragma once
// A copy of a scene file with some texts replaced, for tests that run a case with one key
// changed.

#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "demfem_test/temp_dir.hpp"

namespace demfem::test {

/// Writes `scene` to `dest` with the first occurrence of each `from` replaced by its `to`;
/// throws when a `from` does not occur (the case changed under the test). Returns `dest`.
inline std::filesystem::path write_variant(
    const std::filesystem::path& scene, const std::filesystem::path& dest,
    const std::vector<std::pair<std::string, std::string>>& subs) {
  std::string text = read_text(scene);
  for (const auto& [from, to] : subs) {
    const auto at = text.find(from);
    if (at == std::string::npos) {
      throw std::runtime_error(scene.string() + " has no '" + from + "' to replace");
    }
    text.replace(at, from.size(), to);
  }
  std::ofstream(dest) << text;
  return dest;
}

}  // namespace demfem::test
