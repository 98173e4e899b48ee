// [[dem.pack]] at the start of a run: the packed fills placed after the lattices, each checked
// as a lattice is (walls, particles already there, falling past every wall).

#include <sstream>

#include "demfem/dem/placement/packed_fill.hpp"
#include "demfem/dem/run/dem_run.hpp"
#include "demfem/dem/shapes/shape_library.hpp"

namespace demfem::dem {

using scene::SceneError;

void DemRun::place_packs(const WallClearance& walls, std::uint64_t seed) {
  for (std::size_t i = 0; i < scene_.packs.size(); ++i) {
    const auto& entry = scene_.packs[i];
    PackedFill q = entry.request;
    if (!entry.has_seed) q.seed = seed + kPackSeedOffset + i;
    if (entry.shape >= 0) {
      q.library = libraries_[static_cast<std::size_t>(entry.shape)].get();
      q.shape_base = shape_base_[static_cast<std::size_t>(entry.shape)];
    }
    PackedBed bed;
    try {
      bed = packed_fill(q);
    } catch (const InsertionError& e) {
      throw SceneError(entry.where + ": " + e.what());
    }
    const auto& placed = bed.particles;
    auto particle = [&](const ParticleInit& p) {
      std::ostringstream m;
      m << "particle " << &p - placed.data() << " of " << placed.size() << " (centre ["
        << p.position[0] << ", " << p.position[1] << ", " << p.position[2]
        << "] m, bounding radius " << p.radius << " m)";
      return m.str();
    };
    // A bounding sphere in a wall: the rock might be thrown off it at the first step.
    for (const auto& p : placed) {
      std::size_t wall = 0;
      const double depth = walls.overlap(p.position, p.radius, &wall);
      if (depth > 1e-9 * p.radius) {
        std::ostringstream m;
        m << entry.where << ": " << particle(p) << " overlaps wall '" << walls.name(wall) << "' by "
          << depth << " m: the pack region reaches into or through the walls; move "
          << "'lo' and 'hi' inside them";
        throw SceneError(m.str());
      }
    }
    if (const auto j = first_overlapping(placed, system_->particles()); j >= 0) {
      throw SceneError(entry.where + ": " + particle(placed[std::size_t(j)]) +
                       " overlaps a particle placed before it ([dem.load], a [[dem.lattice]] "
                       "or an earlier [[dem.pack]]): regions must not overlap");
    }
    for (const auto& p : placed) {
      if (walls.falls_past(p.position, scene_.settings.gravity)) {
        check_falls_past(particle(p), entry.where);  // throws, or warns once for the entry
        break;
      }
    }
    if (log_) {
      *log_ << "dem: [[dem.pack]] " << i << ": " << placed.size() << " particles packed "
            << bed.height << " m high, bounding-sphere fraction " << bed.bounding_fraction << "\n";
    }
    add(placed);
  }
}

}  // namespace demfem::dem
