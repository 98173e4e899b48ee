#pragma once
// One [[dem.materials]] entry and one [[dem.pairs]] entry of a scene text, as the DEM tests
// write them: every material of the tests has Poisson's ratio 0.3, and a wall material no
// density. Tests edit their texts by searching for lines ("density = 1242.0",
// "friction = 0.22\nrestitution = 0.4"), so the keys keep this order and the values are
// written as given.

#include <string>

namespace demfem::test {

/// [[dem.materials]]: `name`, Young's modulus (Pa) and, for a particle material, density
/// (kg/m³; empty: none, a wall material).
inline std::string dem_material(const std::string& name, const std::string& youngs_modulus,
                                const std::string& density = "") {
  std::string t = "[[dem.materials]]\nname = \"" + name + "\"\nyoungs_modulus = " +
                  youngs_modulus + "\npoisson_ratio = 0.3\n";
  if (!density.empty()) t += "density = " + density + "\n";
  return t;
}

/// [[dem.pairs]] of materials `a` and `b`: friction and restitution, then `extra` lines
/// (each ending in '\n': rolling_friction, poly_law, ...).
inline std::string dem_pair(const std::string& a, const std::string& b,
                            const std::string& friction, const std::string& restitution,
                            const std::string& extra = "") {
  return "[[dem.pairs]]\na = \"" + a + "\"\nb = \"" + b + "\"\nfriction = " + friction +
         "\nrestitution = " + restitution + "\n" + extra;
}

/// The materials of particles of one kind among walls: `grain` (Young's modulus, Pa;
/// density, kg/m³) and the wall material `wall` (Young's modulus), with the grain-grain and
/// the grain-wall pair alike (friction, restitution).
inline std::string grain_and_wall(const std::string& grain, const std::string& grain_youngs,
                                  const std::string& grain_density, const std::string& wall,
                                  const std::string& wall_youngs, const std::string& friction,
                                  const std::string& restitution) {
  return dem_material(grain, grain_youngs, grain_density) + dem_material(wall, wall_youngs) +
         dem_pair(grain, grain, friction, restitution) +
         dem_pair(grain, wall, friction, restitution);
}

}  // namespace demfem::test
