// libFuzzer harness for the scene reader: any bytes must give either a scene or a
// SceneError, never a crash, hang or sanitizer report.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "demfem/scene/scene_reader.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  try {
    auto doc = demfem::scene::Document::parse(text, "fuzz.toml");
    (void)demfem::scene::read_run_settings(doc);
  } catch (const demfem::scene::SceneError&) {
  }
  return 0;
}
