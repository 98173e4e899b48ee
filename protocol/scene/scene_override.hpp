#pragma once
// Applying one `--set KEY=VALUE` to a parsed scene tree (used by Document::parse only).

#include <toml++/toml.h>

#include <string>

#include "demfem/scene/scene_reader.hpp"

namespace demfem::scene::detail {

/// Sets `o.key` of `root` to `value` (the parsed VALUE): replaces an existing key or array
/// entry, or adds a key to an existing table. Throws SceneError naming `file` and the
/// override when KEY is malformed or walks through a table or array entry the scene lacks.
void assign_override(toml::table& root, const Override& o, toml::node&& value,
                     const std::string& file);

/// Whether the tables and array entries that the override's key walks through exist in
/// `root` (its last key may be new: assign_override adds it).
bool override_target_exists(const toml::table& root, const Override& o, const std::string& file);

}  // namespace demfem::scene::detail
