#pragma once
// [[dem.shapes]]: reading an entry (scene_shapes.cpp) and building its shape library for a run.

#include <cstdint>
#include <iosfwd>
#include <memory>

#include "demfem/dem/scene/dem_scene.hpp"
#include "demfem/dem/shapes/shape_library.hpp"
#include "demfem/scene/scene_reader.hpp"

namespace demfem::dem {

/// Reads one [[dem.shapes]] table (all keys checked; calls finish()).
ShapeSpec read_shape_spec(const scene::Table& t);

/// The library of a [[dem.shapes]] entry: random rocks (seed: the entry's, or run_seed +
/// entry index), the hulls of STL scans or one simple solid, each at size 1 m of the entry's
/// size definition with r_d = dilation. Throws scene::SceneError naming the entry (its
/// `where`) for shape errors (degenerate cores, an open STL, r_d too large); notes a
/// concave STL scan on `log`.
std::unique_ptr<shapes::ShapeLibrary> build_shape_library(const ShapeSpec& spec,
                                                          std::uint64_t run_seed, std::size_t entry,
                                                          std::ostream* log);

}  // namespace demfem::dem
