#pragma once
// Scene texts for the DEM scene-reader tests: a variant with one text replaced, the line a
// text is on (the errors name it), and the [dem] section read as dem_server reads it.

#include <algorithm>
#include <stdexcept>
#include <string>

#include "demfem/dem/scene/dem_scene.hpp"
#include "demfem/scene/scene_reader.hpp"

namespace demfem::test {

/// `text` with the first `from` replaced by `to`; throws when `from` does not occur (the base
/// scene changed under the test).
inline std::string replace_first(std::string text, const std::string& from,
                                 const std::string& to) {
  const auto p = text.find(from);
  if (p == std::string::npos) throw std::runtime_error("the scene text has no '" + from + "'");
  return text.replace(p, from.size(), to);
}

/// The line (1-based) of the first occurrence of `what` in `text`.
inline int line_of(const std::string& text, const std::string& what) {
  const auto p = text.find(what);
  return 1 + static_cast<int>(std::count(text.begin(), text.begin() + static_cast<long>(p), '\n'));
}

/// The [dem] section of a scene text, read as `name` (the name the errors give).
inline dem::DemScene parse_dem_scene(const std::string& text, const std::string& name) {
  scene::Document d = scene::Document::parse(text, name);
  scene::read_run_settings(d);
  return dem::read_dem_scene(d.root().required_table("dem"));
}

}  // namespace demfem::test
