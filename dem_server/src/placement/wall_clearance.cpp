#include "demfem/dem/placement/wall_clearance.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "demfem/dem/physics/geometry.hpp"

namespace demfem::dem {

namespace {

constexpr std::size_t kLeafSize = 4;

double centroid(const std::array<double, 9>& v, int k) {
  return (v[std::size_t(k)] + v[std::size_t(3 + k)] + v[std::size_t(6 + k)]) / 3.0;
}

}  // namespace

WallClearance::WallClearance(const std::vector<Wall>& walls) {
  lo_ = {std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
         std::numeric_limits<double>::infinity()};
  hi_ = {-lo_[0], -lo_[1], -lo_[2]};
  for (std::size_t w = 0; w < walls.size(); ++w) {
    names_.push_back(walls[w].name);
    const auto& v = walls[w].vertices;
    const auto& t = walls[w].triangles;
    for (std::size_t i = 0; i + 2 < t.size(); i += 3) {
      Triangle tri{{}, w};
      for (int c = 0; c < 3; ++c) {
        const auto vi = static_cast<std::size_t>(t[i + std::size_t(c)]);
        for (int k = 0; k < 3; ++k) {
          const double x = v[3 * vi + std::size_t(k)];
          tri.v[std::size_t(3 * c + k)] = x;
          lo_[std::size_t(k)] = std::min(lo_[std::size_t(k)], x);
          hi_[std::size_t(k)] = std::max(hi_[std::size_t(k)], x);
        }
      }
      tris_.push_back(tri);
    }
  }
  if (!tris_.empty()) build(0, tris_.size());
}

std::int64_t WallClearance::build(std::size_t first, std::size_t count) {
  Node node;
  node.lo = {std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
             std::numeric_limits<double>::infinity()};
  node.hi = {-node.lo[0], -node.lo[1], -node.lo[2]};
  std::array<double, 3> clo = node.lo, chi = node.hi;  // bounds of the centroids
  for (std::size_t i = first; i < first + count; ++i) {
    for (int k = 0; k < 3; ++k) {
      const auto kk = std::size_t(k);
      for (int c = 0; c < 3; ++c) {
        node.lo[kk] = std::min(node.lo[kk], tris_[i].v[std::size_t(3 * c + k)]);
        node.hi[kk] = std::max(node.hi[kk], tris_[i].v[std::size_t(3 * c + k)]);
      }
      clo[kk] = std::min(clo[kk], centroid(tris_[i].v, k));
      chi[kk] = std::max(chi[kk], centroid(tris_[i].v, k));
    }
  }
  const auto index = static_cast<std::int64_t>(nodes_.size());
  nodes_.push_back(node);
  if (count <= kLeafSize) {
    nodes_[std::size_t(index)].first = first;
    nodes_[std::size_t(index)].count = count;
    return index;
  }
  // Split at the median centroid along the longest extent of the centroids.
  int axis = 0;
  for (int k = 1; k < 3; ++k)
    if (chi[std::size_t(k)] - clo[std::size_t(k)] > chi[std::size_t(axis)] - clo[std::size_t(axis)])
      axis = k;
  const auto begin = tris_.begin() + std::ptrdiff_t(first);
  const auto mid = begin + std::ptrdiff_t(count / 2);
  std::nth_element(begin, mid, begin + std::ptrdiff_t(count),
                   [axis](const Triangle& a, const Triangle& b) {
                     return centroid(a.v, axis) < centroid(b.v, axis);
                   });
  const std::int64_t left = build(first, count / 2);
  const std::int64_t right = build(first + count / 2, count - count / 2);
  nodes_[std::size_t(index)].left = left;
  nodes_[std::size_t(index)].right = right;
  return index;
}

double WallClearance::overlap(const std::array<double, 3>& c, double r, std::size_t* wall) const {
  double best = 0.0;
  if (tris_.empty()) return best;
  const phys::Vec3 p{c[0], c[1], c[2]};
  std::vector<std::int64_t> stack{0};
  while (!stack.empty()) {
    const Node& n = nodes_[std::size_t(stack.back())];
    stack.pop_back();
    bool apart = false;
    for (std::size_t k = 0; k < 3; ++k) apart = apart || c[k] + r < n.lo[k] || c[k] - r > n.hi[k];
    if (apart) continue;
    if (n.left >= 0) {
      stack.push_back(n.left);
      stack.push_back(n.right);
      continue;
    }
    for (std::size_t i = n.first; i < n.first + n.count; ++i) {
      const auto& v = tris_[i].v;
      const auto cp =
          phys::closest_point_triangle(p, phys::Vec3{v[0], v[1], v[2]},
                                       phys::Vec3{v[3], v[4], v[5]}, phys::Vec3{v[6], v[7], v[8]});
      const phys::Vec3 d = p - cp.point;
      const double depth = r - std::sqrt(phys::dot(d, d));
      if (depth > best) {
        best = depth;
        if (wall) *wall = tris_[i].wall;
      }
    }
  }
  return best;
}

bool WallClearance::falls_past(const std::array<double, 3>& p,
                               const std::array<double, 3>& gravity) const {
  // Without walls or without gravity nothing says where a particle should land.
  if (tris_.empty() || (gravity[0] == 0.0 && gravity[1] == 0.0 && gravity[2] == 0.0)) return false;
  double diag = 0.0;
  for (std::size_t k = 0; k < 3; ++k) diag += (hi_[k] - lo_[k]) * (hi_[k] - lo_[k]);
  const double pad = 1e-9 * std::sqrt(diag);
  // Slab test of the ray p + s g, s >= 0, against the padded box.
  double s0 = 0.0, s1 = std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k < 3; ++k) {
    const double lo = lo_[k] - pad, hi = hi_[k] + pad;
    if (gravity[k] == 0.0) {
      if (p[k] < lo || p[k] > hi) return true;
      continue;
    }
    double a = (lo - p[k]) / gravity[k], b = (hi - p[k]) / gravity[k];
    if (a > b) std::swap(a, b);
    s0 = std::max(s0, a);
    s1 = std::min(s1, b);
    if (s0 > s1) return true;
  }
  return false;
}

}  // namespace demfem::dem
