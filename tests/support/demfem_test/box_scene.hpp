#pragma once
// The scene text many DEM scene tests start from: a [run] end time, the [dem] step, one grain
// material and the walls' steel, their two pairs, and an open-topped box of walls named "box".
// The defaults are the steel sheet's wheat (docs/cases.md); rock_box() is the ballast rock.
// Tests edit the text by searching for its lines ("density = 1242.0"), so the values are
// written as given.

#include <string>
#include <utility>

#include "demfem_test/dem_material_text.hpp"

namespace demfem::test {

struct BoxScene {
  std::string end_time = "0.01";  // empty: no [run] table (the test writes its own)
  std::string grain = "wheat";
  std::string grain_youngs = "1e8";
  std::string grain_density = "1242.0";
  std::string steel_youngs = "1.85e11";
  std::string grain_friction = "1.0";
  std::string grain_restitution = "0.4";
  std::string wall_friction = "0.22";
  std::string wall_restitution = "0.4";
  std::string box_hi = "[0.04, 0.04, 0.1]";  // m; the box starts at the origin

  std::string text() const {
    std::string t = "\n";
    if (!end_time.empty()) t += "[run]\nend_time = " + end_time + "\n\n";
    t += "[dem]\ndt = 1e-5\nthreads = 1\n\n";
    t += dem_material(grain, grain_youngs, grain_density) + "\n";
    t += dem_material("steel", steel_youngs) + "\n";
    t += dem_pair(grain, grain, grain_friction, grain_restitution) + "\n";
    t += dem_pair(grain, "steel", wall_friction, wall_restitution) + "\n";
    t +=
        "[[dem.walls]]\nname = \"box\"\nmaterial = \"steel\"\nbox = { lo = [0.0, 0.0, 0.0], hi = " +
        box_hi + ", open_top = true }\n";
    return t;
  }
};

/// Ballast rock (2600 kg/m³, μ 0.6, e 0.2; on steel μ 0.5) in a box up to `box_hi`, with the
/// soft wall steel (1e8 Pa) that lets a test step rocks at 1e-5 s.
inline BoxScene rock_box(std::string box_hi) {
  BoxScene b;
  b.grain = "rock";
  b.grain_density = "2600.0";
  b.steel_youngs = "1e8";
  b.grain_friction = "0.6";
  b.grain_restitution = "0.2";
  b.wall_friction = "0.5";
  b.wall_restitution = "0.2";
  b.box_hi = std::move(box_hi);
  return b;
}

}  // namespace demfem::test
