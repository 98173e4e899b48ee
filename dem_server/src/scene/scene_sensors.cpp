// [[dem.sensors]]: what a run measures between its steps (mass flow, wall forces, kinetic
// energy, angle of repose, packing, frozen particles), each written as a CSV series.

#include <algorithm>
#include <array>
#include <string>
#include <vector>

#include "scene_sections.hpp"

namespace demfem::dem {

using scene::Range;
using scene::Table;

std::vector<SensorSpec> read_sensors(const Table& dem, const std::vector<WallSpec>& walls) {
  std::vector<SensorSpec> specs;
  for (const auto& t : dem.tables("sensors")) {
    SensorSpec ss;
    ss.name = t.string("name");
    if (ss.name.empty() || ss.name.find_first_of("/\\ ") != std::string::npos) {
      t.fail("name", "must be a non-empty name without spaces or slashes (it names a file)");
    }
    for (const auto& other : specs)
      if (other.name == ss.name) t.fail("name", "sensor \"" + ss.name + "\" is defined twice");
    const std::string kind = t.choice(
        "kind", {"mass_flow", "wall_force", "kinetic_energy", "repose", "packing", "frozen"});
    ss.interval = t.number("interval", Range::positive());
    if (kind == "mass_flow") {
      ss.kind = SensorSpec::Kind::mass_flow;
      ss.point = t.vec3("point");
      ss.direction = t.vec3("direction", std::array<double, 3>{0, 0, -1});
      if (ss.direction == std::array<double, 3>{0, 0, 0}) t.fail("direction", "must not be zero");
      ss.radius = t.number("radius", 0.0, Range::non_negative());
    } else if (kind == "wall_force") {
      ss.kind = SensorSpec::Kind::wall_force;
      const std::string wall = t.string("wall");
      auto it = std::find_if(walls.begin(), walls.end(),
                             [&](const WallSpec& w) { return w.name == wall; });
      if (it == walls.end()) t.fail("wall", "names wall \"" + wall + "\", which is not defined");
      ss.wall = static_cast<std::int32_t>(it - walls.begin());
      if (t.has("face")) {
        ss.face = true;
        ss.face_direction = t.vec3("face");
        if (ss.face_direction == std::array<double, 3>{0, 0, 0}) t.fail("face", "must not be zero");
      }
    } else if (kind == "kinetic_energy") {
      ss.kind = SensorSpec::Kind::kinetic_energy;
    } else if (kind == "frozen") {
      ss.kind = SensorSpec::Kind::frozen;
    } else if (kind == "packing") {
      ss.kind = SensorSpec::Kind::packing;
      ss.box_lo = t.vec3("lo");
      ss.box_hi = t.vec3("hi");
      for (int k = 0; k < 3; ++k)
        if (!(ss.box_hi[k] > ss.box_lo[k])) t.fail("hi", "must exceed 'lo' in x, y and z");
      ss.contacts = t.boolean("contacts", false);
    } else {
      ss.kind = SensorSpec::Kind::repose;
      auto c = t.numbers("centre", 2);
      ss.repose.centre = {c[0], c[1]};
      ss.repose.planar = t.choice("profile", "radial", {"radial", "planar"}) == "planar";
      ss.repose.base = t.number("base", 0.0);
      ss.repose.top = t.number("top", 1e300);
      if (ss.repose.top <= ss.repose.base) t.fail("top", "must be above 'base'");
      ss.repose.bin_width = t.number("bin_width", 0.0, Range::non_negative());
      if (t.has("flank")) {
        auto f = t.numbers("flank", 2, Range::closed(0.0, 1.0));
        if (!(f[1] > f[0])) t.fail("flank", "must be [lo, hi] with lo < hi");
        ss.repose.flank_lo = f[0];
        ss.repose.flank_hi = f[1];
      }
    }
    t.finish();
    specs.push_back(ss);
  }
  return specs;
}

}  // namespace demfem::dem
