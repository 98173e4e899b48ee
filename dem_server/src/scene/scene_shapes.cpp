// [[dem.shapes]]: dilated convex polyhedra in a scene (docs/scene_dem.md).

#include "scene_shapes.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ostream>
#include <stdexcept>

#include "demfem/dem/shapes/mesh_hull.hpp"

namespace demfem::dem {

namespace {
constexpr double kMinDilation = 0.01;  // of the size (the thesis and the cases use 0.1)
constexpr double kMaxAspect = 1000.0;  // largest to smallest side of a box, prism height
}  // namespace

using scene::Range;
using scene::SceneError;
using scene::Table;

namespace {

/// STL hulls of this many vertices and more are reported while they are set up (the sieve
/// size costs about a second per 10^4 vertices, more for near-spherical hulls).
constexpr std::size_t kReportHullsFrom = 2000;

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::round(10.0 *
                    std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count()) /
         10.0;
}

/// The sieve-size search with progress lines (every 5 s at most) when a core is large.
shapes::SieveSearch sieve_progress(const ShapeSpec& spec,
                                   const std::vector<shapes::ConvexPolyhedron>& cores,
                                   std::ostream* log) {
  shapes::SieveSearch search;
  std::size_t largest = 0;
  for (const auto& c : cores) largest = std::max(largest, c.vertices().size());
  if (!log || largest < kReportHullsFrom) return search;
  const auto t0 = std::chrono::steady_clock::now();
  auto last = t0;
  search.progress = [log, t0, last, name = spec.name, where = spec.where](
                        std::string_view stage, std::size_t done, std::size_t total,
                        std::size_t evaluations) mutable {
    const auto now = std::chrono::steady_clock::now();
    if (now - last < std::chrono::seconds(5) && done < total) return;
    last = now;
    *log << "dem: " << where << ": shape '" << name << "': sieve size: " << stage << " " << done
         << " of " << total << " (" << evaluations << " projections, " << seconds_since(t0)
         << " s)\n"
         << std::flush;
  };
  return search;
}

}  // namespace

ShapeSpec read_shape_spec(const Table& t) {
  ShapeSpec s;
  s.name = t.string("name");
  if (s.name.empty()) t.fail("name", "must not be empty");
  s.where = t.where("kind");
  const std::string kind = t.choice("kind", {"random_rock", "stl", "box", "cube", "tetrahedron",
                                             "octahedron", "prism", "sphere"});
  using K = ShapeSpec::Kind;
  s.kind = kind == "random_rock"   ? K::random_rock
           : kind == "stl"         ? K::stl
           : kind == "box"         ? K::box
           : kind == "cube"        ? K::cube
           : kind == "tetrahedron" ? K::tetrahedron
           : kind == "octahedron"  ? K::octahedron
           : kind == "prism"       ? K::prism
                                   : K::sphere;
  if (s.kind == K::random_rock) {
    s.count = t.integer("count", 20, 1, 100000);
    s.triangles = static_cast<int>(t.integer("triangles", 30, 4, 100000));
    if (s.triangles % 2 != 0)
      t.fail("triangles", "is " + std::to_string(s.triangles) +
                              ": a closed triangulated convex hull has an even number of "
                              "triangles (2 V - 4), at least 4");
    s.elongation = t.number("elongation", 1.0, Range::open_closed(0.0, 1.0));
    s.flatness = t.number("flatness", 1.0, Range::open_closed(0.0, 1.0));
    if (t.has("seed")) {
      s.seed = static_cast<std::uint64_t>(t.integer("seed", 0, INT64_MAX));
      s.has_seed = true;
    }
  } else if (s.kind == K::stl) {
    if (!t.has("stl"))
      t.fail("stl", "is required for kind = \"stl\" (a file or an array of files)");
    // one path or an array of paths
    try {
      const auto names = t.strings("stl");
      for (std::size_t k = 0; k < names.size(); ++k) {
        std::filesystem::path p = names[k];
        if (p.is_relative()) p = std::filesystem::path(t.file()).parent_path() / p;
        s.stl.push_back(p);
      }
    } catch (const SceneError&) {
      s.stl = {t.path("stl")};
    }
  } else if (s.kind == K::box) {
    s.aspect = t.vec3("aspect", Range::positive());
    // the box is scaled to its size: only the ratios count, and beyond kMaxAspect the hull
    // of a needle or a sheet is within rounding of a line or a plane ([1e300, 1, 1] was
    // refused as "collinear (nan, nan, nan)")
    const double lo = std::min({s.aspect[0], s.aspect[1], s.aspect[2]}),
                 hi = std::max({s.aspect[0], s.aspect[1], s.aspect[2]});
    if (!(hi <= kMaxAspect * lo))
      t.fail("aspect", "has a largest to smallest side of " + std::to_string(hi / lo) +
                           " (accepted: at most " + std::to_string(int(kMaxAspect)) +
                           "; only the ratios count, the box is scaled to its size)");
  } else if (s.kind == K::prism) {
    s.aspect = {1.0, t.number("height", 1.0, Range::closed(1.0 / kMaxAspect, kMaxAspect)), 1.0};
  }
  const std::string size = t.choice("size", "sieve", {"sieve", "volume_equivalent", "bounding"});
  for (auto k : {shapes::SizeKind::sieve, shapes::SizeKind::volume_equivalent,
                 shapes::SizeKind::bounding})
    if (size == shapes::to_string(k)) s.size = k;
  // r_d is the rocks' contact radius: the stability guard stops a run at an overlap of half
  // of it, while the time step is checked against the particle's size, not r_d; a thinner
  // dilation than kMinDilation of the size gives contacts that the guard stops at ordinary
  // impacts (1e-300 was accepted and blew up at the first contact)
  s.dilation = t.number("dilation", 0.1, Range{kMinDilation, 0.5, false, true});
  t.finish();
  return s;
}

std::unique_ptr<shapes::ShapeLibrary> build_shape_library(const ShapeSpec& spec,
                                                          std::uint64_t run_seed, std::size_t entry,
                                                          std::ostream* log) {
  using K = ShapeSpec::Kind;
  try {
    if (spec.kind == K::random_rock) {
      shapes::RockParams p;
      p.triangles = spec.triangles;
      p.elongation = spec.elongation;
      p.flatness = spec.flatness;
      const std::uint64_t seed = spec.has_seed ? spec.seed : run_seed + entry;
      return std::make_unique<shapes::ShapeLibrary>(shapes::ShapeLibrary::random_rocks(
          p, static_cast<std::size_t>(spec.count), seed, spec.size, spec.dilation));
    }
    std::vector<shapes::ConvexPolyhedron> cores;
    switch (spec.kind) {
      case K::stl:
        for (const auto& f : spec.stl) {
          const auto t0 = std::chrono::steady_clock::now();
          shapes::MeshHull h = shapes::hull_of_stl(f);
          if (!h.warning.empty() && log)
            *log << "dem: warning: " << spec.where << ": " << f.string() << ": " << h.warning
                 << "\n";
          if (log && h.core.vertices().size() >= kReportHullsFrom) {
            *log << "dem: " << spec.where << ": shape '" << spec.name << "': " << f.string()
                 << ": convex hull of " << h.core.vertices().size() << " vertices ("
                 << seconds_since(t0) << " s)\n"
                 << std::flush;
          }
          cores.push_back(std::move(h.core));
        }
        return std::make_unique<shapes::ShapeLibrary>(cores, spec.size, spec.dilation,
                                                      sieve_progress(spec, cores, log));
      case K::box:
        cores.push_back(shapes::make_box(spec.aspect[0], spec.aspect[1], spec.aspect[2]));
        break;
      case K::cube:
        cores.push_back(shapes::make_cube(1.0));
        break;
      case K::tetrahedron:
        cores.push_back(shapes::make_regular_tetrahedron(1.0));
        break;
      case K::octahedron:
        cores.push_back(shapes::make_octahedron(1.0));
        break;
      case K::prism:
        cores.push_back(shapes::make_triangular_prism(1.0, spec.aspect[1]));
        break;
      case K::sphere:
        cores.push_back(shapes::ConvexPolyhedron::point());
        break;
      case K::random_rock:
        break;
    }
    return std::make_unique<shapes::ShapeLibrary>(cores, spec.size, spec.dilation);
  } catch (const shapes::ShapeError& e) {
    throw SceneError(spec.where + ": shape '" + spec.name + "': " + e.what());
  } catch (const std::runtime_error& e) {  // an unreadable STL (StlError)
    throw SceneError(spec.where + ": shape '" + spec.name + "': " + e.what());
  }
}

}  // namespace demfem::dem
