#pragma once
// The walls at the start of a run, for checking where a scene puts its particles: a sphere
// that overlaps a wall triangle at once is thrown off it with a force the time step was not
// chosen for, and a particle that falls past every wall falls for ever; both are mistakes in
// a scene (a lattice or insertion region placed partly outside the wall box) that would
// otherwise run silently. A bounding-volume tree of all triangles keeps each query at
// O(log triangles).

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "demfem/dem/shapes/geometry/triangle_mesh.hpp"

namespace demfem::dem {

class WallClearance {
 public:
  /// A wall's name and surface where it stands now.
  using Wall = TriangleMesh;
  explicit WallClearance(const std::vector<Wall>& walls);

  bool empty() const { return tris_.empty(); }
  /// Largest overlap (m) of the sphere (centre c, radius r) with a wall triangle, 0 when it
  /// touches none; `wall` (may be null) gets the index of that wall.
  double overlap(const std::array<double, 3>& c, double r, std::size_t* wall = nullptr) const;
  /// Whether a point carried from `p` along `gravity` for ever misses the bounding box of all
  /// walls (enlarged by 1e-9 of its diagonal): it can never land on a wall. False without
  /// walls or without gravity (then nothing says where a particle should land).
  bool falls_past(const std::array<double, 3>& p, const std::array<double, 3>& gravity) const;
  const std::string& name(std::size_t wall) const { return names_[wall]; }
  const std::array<double, 3>& lo() const { return lo_; }
  const std::array<double, 3>& hi() const { return hi_; }

 private:
  struct Triangle {
    std::array<double, 9> v;  ///< a, b, c
    std::size_t wall;
  };
  struct Node {
    std::array<double, 3> lo, hi;
    std::int64_t left = -1, right = -1;  ///< children, or -1 for a leaf
    std::size_t first = 0, count = 0;    ///< leaf: tris_[first .. first + count)
  };
  std::int64_t build(std::size_t first, std::size_t count);
  std::vector<Triangle> tris_;
  std::vector<Node> nodes_;
  std::vector<std::string> names_;
  std::array<double, 3> lo_{}, hi_{};
};

}  // namespace demfem::dem
