#include "demfem/dem/shapes/random_rock.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "demfem/dem/shapes/geometry/rng.hpp"
#include "demfem/dem/shapes/mass_properties.hpp"
#include "shape_util.hpp"

namespace demfem::dem::shapes {

using detail::format_number;

namespace {

constexpr int kMaxAttempts = 1000;

Vec3 random_direction(Rng& rng) {
  const double z = 2.0 * rng.uniform() - 1.0;
  const double phi = 2.0 * std::numbers::pi * rng.uniform();
  const double s = std::sqrt(std::max(0.0, 1.0 - z * z));
  return {s * std::cos(phi), s * std::sin(phi), z};
}

/// n directions, pairwise at least min_angle apart (rejection; the bound is relaxed by 10 %
/// after 1000 rejections in a row, which the chosen spacing makes rare).
std::vector<Vec3> spread_directions(Rng& rng, std::size_t n, double min_angle) {
  std::vector<Vec3> d;
  double min_dot = std::cos(min_angle);
  int rejected = 0;
  while (d.size() < n) {
    const Vec3 x = random_direction(rng);
    bool ok = true;
    for (const Vec3& y : d)
      if (dot(x, y) > min_dot) {
        ok = false;
        break;
      }
    if (ok) {
      d.push_back(x);
      rejected = 0;
    } else if (++rejected == 1000) {
      min_angle *= 0.9;
      min_dot = std::cos(min_angle);
      rejected = 0;
    }
  }
  return d;
}

std::string label(const RockParams& p, std::uint64_t seed) {
  return "random rock (" + std::to_string(p.triangles) + " triangles, elongation " +
         format_number(p.elongation) + ", flatness " + format_number(p.flatness) + ", seed " +
         std::to_string(seed) + ")";
}

}  // namespace

void validate(const RockParams& p) {
  if (p.triangles < 4 || p.triangles % 2 != 0) {
    throw ShapeError("rock triangles = " + std::to_string(p.triangles) +
                     ": a closed triangulated convex polyhedron with V vertices has 2V - 4 "
                     "triangles, so the count must be even and >= 4 (e.g. 10, 30, 40)");
  }
  if (p.triangles > 100000) {
    throw ShapeError("rock triangles = " + std::to_string(p.triangles) +
                     ": at most 100000 (a DEM particle needs far fewer)");
  }
  if (!(p.elongation > 0 && p.elongation <= 1)) {
    throw ShapeError("rock elongation = " + format_number(p.elongation) +
                     ": must be in (0, 1] (I / L of the principal extents L >= I >= S)");
  }
  if (!(p.flatness > 0 && p.flatness <= 1)) {
    throw ShapeError("rock flatness = " + format_number(p.flatness) +
                     ": must be in (0, 1] (S / I of the principal extents L >= I >= S)");
  }
}

ConvexPolyhedron random_rock(const RockParams& p, std::uint64_t seed) {
  validate(p);
  const std::string src = label(p, seed);
  const auto nv = std::size_t(p.triangles / 2 + 2);
  Rng rng(seed);
  const double spacing = std::sqrt(4.0 * std::numbers::pi / double(nv));
  for (int attempt = 0; attempt < kMaxAttempts; ++attempt) {
    std::vector<Vec3> pts = spread_directions(rng, nv, 0.5 * spacing);
    for (Vec3& x : pts) x = {x[0], p.elongation * x[1], p.elongation * p.flatness * x[2]};
    ConvexPolyhedron hull = ConvexPolyhedron::hull(pts, src);
    if (hull.vertices().size() != nv || hull.triangles().size() != std::size_t(p.triangles)) {
      continue;
    }
    // Centroid and principal axes; then the axes ordered by extent, longest first.
    const MassProperties mp = core_mass_properties(hull);
    const PrincipalFrame f = principal_frame(mp.inertia);
    Mat3 rt{};  // rows: the principal axes
    for (std::size_t i = 0; i < 3; ++i)
      for (std::size_t j = 0; j < 3; ++j) rt[i][j] = f.axes[j][i];
    Vec3 width{};
    for (std::size_t i = 0; i < 3; ++i) width[i] = hull.width(rt[i]);
    std::array<std::size_t, 3> order{0, 1, 2};
    std::stable_sort(order.begin(), order.end(),
                     [&](std::size_t a, std::size_t b) { return width[a] > width[b]; });
    Mat3 axes{rt[order[0]], rt[order[1]], rt[order[2]]};
    if (dot(cross(axes[0], axes[1]), axes[2]) < 0) axes[2] = -1.0 * axes[2];  // right-handed
    const Vec3 target{1.0, p.elongation, p.elongation * p.flatness};
    Mat3 a{};
    Vec3 t{};
    for (std::size_t i = 0; i < 3; ++i) {
      const double s = target[i] / width[order[i]];
      a[i] = s * axes[i];
      t[i] = -dot(a[i], mp.centroid);
    }
    return hull.transformed(a, t);
  }
  throw ShapeError(src + ": no hull with exactly " + std::to_string(p.triangles) +
                   " triangles in " + std::to_string(kMaxAttempts) + " draws");
}

}  // namespace demfem::dem::shapes
