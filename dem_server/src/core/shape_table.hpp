#pragma once
// Host side of the shape table of dilated convex polyhedra (physics/shape_table.hpp): checks a
// PolyhedronShape and appends it to flat arrays (faces as polygons of merged coplanar
// triangles, edges as their sides) that both backends read.

#include <cstdint>
#include <vector>

#include "demfem/dem/dem_system.hpp"
#include "demfem/dem/physics/shape_table.hpp"

namespace demfem::dem::detail {

class ShapeTable {
 public:
  /// Checks and appends a shape; returns its index. Throws std::invalid_argument naming the
  /// field and the accepted range.
  std::int32_t add(const PolyhedronShape& shape);
  std::size_t size() const { return shapes_.size(); }
  const PolyhedronShape& shape(std::int32_t id) const { return shapes_[id]; }
  /// Bounding radius of the dilated body at scale 1.
  double bound(std::int32_t id) const { return bound_[id]; }
  /// Host view of the arrays (valid until the next add()).
  phys::ShapeTableView view() const;
  /// The arrays (for the device upload).
  struct Arrays {
    std::vector<std::int32_t> vbase, nv, fbase, nf, floop, flen, fvert, ebase, ne, edge;
    std::vector<double> vert, fnormal, dilation, bound;
    std::vector<double> vsoa, fsoa;  // columns (ShapeTableView::vsoa, fsoa)
    std::vector<std::int32_t> vsoa_base, fsoa_base;
  };
  const Arrays& arrays() const { return a_; }
  void clear();

 private:
  std::vector<PolyhedronShape> shapes_;
  std::vector<double> bound_;
  Arrays a_;
};

}  // namespace demfem::dem::detail
