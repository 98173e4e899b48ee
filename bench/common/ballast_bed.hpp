#pragma once
// Ballast beds for the polyhedron benchmarks (poly_throughput, poly_timestep): rocks of a
// shape library or spheres with sieve sizes from the thesis's ballast distribution (normal,
// mean 40 mm, sd 10 mm, in [20, 80] mm), packed densely by their bounding spheres in a box
// of triangle-mesh walls (floor + 4 sides, open top), to be settled under gravity.

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "demfem/dem/dem_system.hpp"
#include "demfem/dem/placement/insertion.hpp"
#include "demfem/dem/placement/packed_fill.hpp"
#include "demfem/dem/shapes/shape_library.hpp"

namespace demfem::bench {

using dem::ParticleInit;
using dem::ParticleShape;
using dem::Rng;
using dem::SizeDistribution;
using dem::WallMesh;
namespace shapes = dem::shapes;

inline WallMesh quad(std::array<double, 3> a, std::array<double, 3> b, std::array<double, 3> c,
                     std::array<double, 3> d, const std::string& name) {
  WallMesh w;
  w.name = name;
  w.material = 1;
  for (const auto& p : {a, b, c, d}) w.vertices.insert(w.vertices.end(), p.begin(), p.end());
  w.triangles = {0, 1, 2, 0, 2, 3};
  return w;
}

// Floor and four side walls of the box [0, lx] x [0, ly] x [0, h] (open top).
inline std::vector<WallMesh> box_walls(double lx, double ly, double h) {
  return {quad({0, 0, 0}, {lx, 0, 0}, {lx, ly, 0}, {0, ly, 0}, "floor"),
          quad({0, 0, 0}, {0, ly, 0}, {0, ly, h}, {0, 0, h}, "x0"),
          quad({lx, 0, 0}, {lx, 0, h}, {lx, ly, h}, {lx, ly, 0}, "x1"),
          quad({0, 0, 0}, {0, 0, h}, {lx, 0, h}, {lx, 0, 0}, "y0"),
          quad({0, ly, 0}, {lx, ly, 0}, {lx, ly, h}, {0, ly, h}, "y1")};
}

struct Bed {
  std::vector<ParticleInit> particles;
  std::vector<WallMesh> walls;
  double lx = 0, ly = 0;  // box footprint [0, lx] x [0, ly], floor at z = 0
};

inline const SizeDistribution kSizes = SizeDistribution::normal(0.04, 0.01, 0.02, 0.08);

// Rocks (library given) or spheres (library null): shapes and sizes drawn as a random
// insertion would (library sample, the ballast distribution), then packed densely by their
// bounding spheres, largest first, in rows along x and layers (dem::packed_fill, the scene's
// [[dem.pack]]), over a footprint of about `aspect` times the packed height (default 2): the
// bed then falls little and settles in a fraction of a second (random insertion at a safe
// bounding-sphere fraction left the rocks a metre to fall).
inline Bed make_bed(std::size_t n, const shapes::ShapeLibrary* lib, std::int32_t shape_base,
                    std::uint64_t seed = 11, double aspect = 2.0) {
  // The footprint comes from the bounding cubes' volume, drawn as packed_fill draws (the
  // same stream, so the same sizes) and summed largest first, as the bits have always been.
  std::vector<double> radii;
  {
    Rng rng(seed);
    for (std::size_t k = 0; k < n; ++k)
      radii.push_back(lib ? lib->sample(rng, kSizes).bounding_radius : 0.5 * kSizes.sample(rng));
  }
  std::sort(radii.begin(), radii.end(), std::greater<>());
  double vol = 0.0;
  for (const double r : radii) vol += 8.0 * r * r * r;
  const double side = std::cbrt(aspect * vol) + 0.1;  // footprint: about aspect x height
  dem::PackedFill q;
  q.region.lo = {0.0, 0.0, 1e-3};
  q.region.hi = {side, side, std::numeric_limits<double>::infinity()};
  q.sizes = kSizes;
  q.count = static_cast<std::int64_t>(n);
  q.gap_factor = 1.0001;
  q.seed = seed;
  q.material = 0;
  q.library = lib;
  q.shape_base = shape_base;
  auto packed = dem::packed_fill(q);
  Bed bed;
  bed.lx = bed.ly = side;
  bed.particles = std::move(packed.particles);
  bed.walls = box_walls(side, side, packed.height + 0.2);
  return bed;
}

}  // namespace demfem::bench
