#pragma once
// The readers of [dem]'s sections, one file per concern, which read_dem_scene (dem_scene.cpp)
// calls in the order of its checks: the first error a scene has is the one reported, so that
// order is part of what a user sees. Each reader calls finish() on the tables it reads.

#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "demfem/dem/scene/dem_scene.hpp"
#include "demfem/scene/scene_reader.hpp"

namespace demfem::dem {

/// The index of the material that `key` names; a SceneError listing the defined ones when
/// [[dem.materials]] does not define it (dem_scene.cpp).
std::int32_t material_index(const scene::Table& t, std::string_view key,
                            const std::vector<Material>& materials);
/// t's 'hi', which must exceed `lo` in every component (dem_scene.cpp).
std::array<double, 3> checked_hi(const scene::Table& t, const std::array<double, 3>& lo);

/// [[dem.walls]] (scene_walls.cpp).
std::vector<WallSpec> read_walls(const scene::Table& dem, const std::vector<Material>& materials);

/// What read_fills finds besides the entries: the materials particles are made of (every pair
/// they meet must be given), and per lattice, then per insertion, then per pack the key that sets its size.
struct FillKeys {
  std::vector<std::uint8_t> particle_materials;  ///< 1 per material that particles use
  std::vector<std::string> size_keys;
};
/// [[dem.lattice]], [[dem.insert]] and [[dem.pack]] into s.lattices, s.inserts and s.packs
/// (s.settings.materials and
/// s.shapes read already), then the particle budget (scene_fills.cpp).
FillKeys read_fills(const scene::Table& dem, DemScene& s);

/// [dem.periodic] into s.settings.periodic and s.periodic_where (scene_periodic.cpp).
void read_periodic(const scene::Table& dem, DemScene& s);
/// Refuses a box wall with faces inside a periodic range (scene_periodic.cpp).
void check_periodic_walls(const DemScene& s);

/// [[dem.sensors]]; a wall_force sensor names one of `walls` (scene_sensors.cpp).
std::vector<SensorSpec> read_sensors(const scene::Table& dem, const std::vector<WallSpec>& walls);

}  // namespace demfem::dem
