#pragma once
// Ballast beds for the polyhedron benchmarks (poly_throughput, poly_timestep): rocks of a
// shape library or spheres with sieve sizes from the thesis's ballast distribution (normal,
// mean 40 mm, sd 10 mm, in [20, 80] mm), packed densely by their bounding spheres in a box
// of triangle-mesh walls (floor + 4 sides, open top), to be settled under gravity.

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <vector>

#include "demfem/dem/dem_system.hpp"
#include "demfem/dem/placement/insertion.hpp"
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
  double lx = 0, ly = 0;
};

inline const SizeDistribution kSizes = SizeDistribution::normal(0.04, 0.01, 0.02, 0.08);

// Rocks (library given) or spheres (library null): shapes and sizes drawn as a random
// insertion would (library sample, the ballast distribution), then packed densely by their
// bounding spheres, largest first, in rows along x and layers, over a footprint of about
// `aspect` times the packed height (default 2): the bed then falls little and settles in a
// fraction of a second (random insertion at a safe bounding-sphere fraction left the rocks a
// metre to fall).
inline Bed make_bed(std::size_t n, const shapes::ShapeLibrary* lib, std::int32_t shape_base,
                    std::uint64_t seed = 11, double aspect = 2.0) {
  Bed bed;
  Rng rng(seed);
  struct Item {
    double r, size;
    std::int32_t shape;
  };
  std::vector<Item> items;
  for (std::size_t k = 0; k < n; ++k) {
    if (lib) {
      const auto s = lib->sample(rng, kSizes);
      items.push_back({s.bounding_radius, s.scale, static_cast<std::int32_t>(s.shape)});
    } else {
      const double d = kSizes.sample(rng);
      items.push_back({0.5 * d, d, -1});
    }
  }
  std::stable_sort(items.begin(), items.end(),
                   [](const Item& a, const Item& b) { return a.r > b.r; });
  double vol = 0.0;
  for (const auto& it : items) vol += 8.0 * it.r * it.r * it.r;
  const double side = std::cbrt(aspect * vol) + 0.1;  // footprint: about aspect x height
  bed.lx = bed.ly = side;
  double x = 0.0, y = 0.0, z = 0.0, row = 0.0, layer = 0.0;
  for (const auto& it : items) {
    if (x + 2.0 * it.r > side) {  // next row
      x = 0.0;
      y += row;
      row = 0.0;
    }
    if (y + 2.0 * it.r > side) {  // next layer
      y = 0.0;
      z += layer;
      layer = 0.0;
    }
    ParticleInit p;
    p.position = {x + it.r, y + it.r, z + it.r + 1e-3};
    p.material = 0;
    p.radius = it.r;
    if (lib) {
      p.shape = ParticleShape::polyhedron;
      p.shape_id = shape_base + it.shape;
      p.scale = it.size;
      p.orientation = dem::random_orientation(rng);
    }
    bed.particles.push_back(p);
    x += 2.0 * it.r * 1.0001;
    row = std::max(row, 2.0 * it.r * 1.0001);
    layer = std::max(layer, 2.0 * it.r * 1.0001);
  }
  bed.walls = box_walls(side, side, z + layer + 0.2);
  return bed;
}

}  // namespace demfem::bench
