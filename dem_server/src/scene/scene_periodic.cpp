// [dem.periodic]: the periodic directions of a scene and their ranges (docs/scene_dem.md), and
// the walls they admit: a box wall's faces normal to a periodic direction may not lie in its
// range (they would cut the bed that the period makes endless).

#include <string>

#include "scene_sections.hpp"

namespace demfem::dem {

void read_periodic(const scene::Table& dem, DemScene& s) {
  const auto p = dem.table("periodic");
  if (!p) return;
  PeriodicRange& r = s.settings.periodic;
  for (int d = 0; d < 3; ++d) {
    const std::string key(1, "xyz"[d]);
    if (!p->has(key)) continue;
    const auto range = p->numbers(key, 2);
    if (!(range[1] > range[0]))
      p->fail(key, "must be [lo, hi] with hi > lo, m (the periodic range of " + key + ")");
    r.on[d] = true;
    r.lo[d] = range[0], r.hi[d] = range[1];
    s.periodic_where[d] = p->where(key);
  }
  if (!r.any()) p->fail("x", "[dem.periodic] needs at least one of x, y, z = [lo, hi]");
  p->finish();
}

void check_periodic_walls(const DemScene& s) {
  const PeriodicRange& r = s.settings.periodic;
  for (const WallSpec& w : s.walls) {
    if (w.kind != WallSpec::Kind::box) continue;
    for (int d = 0; d < 3; ++d) {
      if (!r.on[d] || (w.lo[d] < r.lo[d] && w.hi[d] > r.hi[d])) continue;
      throw scene::SceneError(
          w.where + ": box wall '" + w.name + "' has faces normal to " + "xyz"[d] + " at " +
          std::to_string(w.lo[d]) + " and " + std::to_string(w.hi[d]) + " m, which " + "xyz"[d] +
          " is periodic over [" + std::to_string(r.lo[d]) + ", " + std::to_string(r.hi[d]) +
          "] m (" + s.periodic_where[d] + "): a face inside the range would cut the bed. Use a "
          "plane wall (a floor spanning the period), or a box reaching beyond the range by more "
          "than the largest particle on both sides");
    }
  }
}

}  // namespace demfem::dem
