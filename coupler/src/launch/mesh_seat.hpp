#pragma once
// fem.mesh.seat: the structure placed on a prepared DEM bed by the bed's own top, not by a
// literal in the mesh file, so that every seed (every bed) seats alike. demfem run resolves
// it after the [dem.load] state exists, and hands the result to every process as the
// override fem.mesh.translate = [0, 0, dz] (the FEM reader moves the model after the scene's
// selectors chose their nodes, docs/scene_fem.md).

#include <cstdint>
#include <optional>
#include <string>

#include "demfem/scene/scene_reader.hpp"

namespace demfem::coupling::launch {

/// @brief What resolve_mesh_seat() found.
struct MeshSeat {
  double bed_top = 0.0;      ///< m: the highest particle top under the widened footprint
  double margin = 0.0;       ///< m: the footprint's widening (x and y)
  double mesh_bottom = 0.0;  ///< m: the mesh's lowest node, in the file's coordinates
  double gap = 0.0;          ///< m
  double dz = 0.0;           ///< m: the shift, bed_top + gap - mesh_bottom
  std::int64_t particles = 0;  ///< particles whose centre lies under the widened footprint
  bool computed = false;       ///< false: --check before the state exists (dz = 0)
  /// "fem.mesh.translate=[0, 0, dz]" (dz to 17 digits: every process reads the same number)
  std::string override_text() const;
};

/// @brief Resolves the scene's [fem.mesh.seat] (nullopt without one): the mesh's footprint
/// (the x-y bounding box of its nodes) widened by `margin` (default: the largest particle's
/// bounding radius, so that every particle that can reach under the footprint counts),
/// the highest top (core vertex + dilation, or sphere top) of the prepared state's particles
/// whose centre lies in it, and dz = that top + `gap` - the mesh's lowest z. `seed`: run.seed
/// (the DEM set-up's). Before a [dem.load] scene has made its state (--check) only the keys
/// are checked, and dz = 0. Throws SceneError naming the key for bad input: fem.mesh.translate
/// given as well, no [dem.load], no particle under the footprint.
std::optional<MeshSeat> resolve_mesh_seat(const scene::Document& doc, std::uint64_t seed);

}  // namespace demfem::coupling::launch
