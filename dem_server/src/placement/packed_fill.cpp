// Packed fill (packed_fill.hpp): a dense start for a bed of rocks or spheres.

#include "demfem/dem/placement/packed_fill.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <sstream>

#include "demfem/dem/shapes/shape_library.hpp"

namespace demfem::dem {

namespace {

struct Drawn {
  double radius;  ///< bounding radius, m
  double size;    ///< the library's size (polyhedra), or the diameter (spheres), m
  std::int32_t shape;
};

// Shapes and sizes as insert_random draws them, all before any orientation: the orientations
// then follow in placement order, so the stream does not depend on how the packing sorts.
std::vector<Drawn> draw(const PackedFill& q, Rng& rng) {
  std::vector<Drawn> items;
  items.reserve(static_cast<std::size_t>(q.count));
  for (std::int64_t k = 0; k < q.count; ++k) {
    if (q.library) {
      const auto s = q.library->sample(rng, q.sizes);
      items.push_back({s.bounding_radius, s.scale, static_cast<std::int32_t>(s.shape)});
    } else {
      const double d = q.sizes.sample(rng);
      items.push_back({0.5 * d, d, -1});
    }
  }
  return items;
}

}  // namespace

PackedBed packed_fill(const PackedFill& q) {
  if (q.count <= 0) throw InsertionError("a packed fill needs a count > 0");
  if (!(q.gap_factor >= 1.0)) throw InsertionError("a packed fill needs a gap factor >= 1");
  Rng rng(q.seed);
  auto items = draw(q, rng);
  // rows: largest first, each row and layer then holds spheres of about one size, so few rows
  // are sized for one large rock among small ones; mixed: as drawn, not graded by size;
  // layers: largest first within runs of about one layer, graded over a layer only
  auto larger = [](const Drawn& a, const Drawn& b) { return a.radius > b.radius; };
  if (q.method == PackedFill::Method::rows) {
    std::stable_sort(items.begin(), items.end(), larger);
  } else if (q.method == PackedFill::Method::layers) {
    double steps = 0.0;
    for (const auto& it : items) steps += 2.0 * it.radius * q.gap_factor;
    const double mean_step = steps / static_cast<double>(items.size());
    const double area = (q.region.hi[0] - q.region.lo[0]) * (q.region.hi[1] - q.region.lo[1]);
    const auto run = std::max<std::size_t>(1, std::size_t(area / (mean_step * mean_step)));
    for (std::size_t a = 0; a < items.size(); a += run) {
      const auto b = std::min(items.size(), a + run);
      std::stable_sort(items.begin() + long(a), items.begin() + long(b), larger);
    }
  }
  const double lx = q.region.hi[0] - q.region.lo[0];
  const double ly = q.region.hi[1] - q.region.lo[1];
  const double lz = q.region.hi[2] - q.region.lo[2];
  double largest = 0.0;
  for (const auto& it : items) largest = std::max(largest, 2.0 * it.radius);
  if (largest > lx || largest > ly) {
    std::ostringstream m;
    m << "the largest bounding diameter drawn, " << largest << " m, exceeds the region "
      << q.region.describe() << " across (x " << lx << " m, y " << ly << " m)";
    throw InsertionError(m.str());
  }
  PackedBed bed;
  bed.particles.reserve(items.size());
  double x = 0.0, y = 0.0, z = 0.0, row = 0.0, layer = 0.0, spheres = 0.0;
  std::int64_t fitting = -1;  // index of the first particle above the region, -1: none
  for (const auto& it : items) {
    if (x + 2.0 * it.radius > lx) {  // next row
      x = 0.0;
      y += row;
      row = 0.0;
    }
    if (y + 2.0 * it.radius > ly) {  // next layer
      y = 0.0;
      z += layer;
      layer = 0.0;
    }
    if (fitting < 0 && z + 2.0 * it.radius > lz)
      fitting = static_cast<std::int64_t>(bed.particles.size());
    ParticleInit p;
    // the offset is added last, so that a region at the origin gives the benches' bits
    p.position = {x + it.radius + q.region.lo[0], y + it.radius + q.region.lo[1],
                  z + it.radius + q.region.lo[2]};
    p.velocity = q.velocity;
    p.material = q.material;
    p.radius = it.radius;
    if (q.library) {
      p.shape = ParticleShape::polyhedron;
      p.shape_id = q.shape_base + it.shape;
      p.scale = it.size;
      p.orientation = random_orientation(rng);
    }
    bed.particles.push_back(p);
    const double step = 2.0 * it.radius * q.gap_factor;
    x += step;
    row = std::max(row, step);
    layer = std::max(layer, step);
    spheres += 4.0 / 3.0 * std::numbers::pi * it.radius * it.radius * it.radius;
  }
  bed.height = z + layer;
  bed.bounding_fraction = spheres / (lx * ly * bed.height);
  if (fitting >= 0) {
    std::ostringstream m;
    m << "cannot pack " << q.count << " particles in " << q.region.describe() << ": packed "
      << "in rows and layers they need " << bed.height << " m of height, the "
      << "region has " << lz << " m; " << fitting << " fit (raise hi z or lower the count)";
    throw InsertionError(m.str());
  }
  return bed;
}

}  // namespace demfem::dem
