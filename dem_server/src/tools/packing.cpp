#include "demfem/dem/packing.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <vector>

namespace demfem::dem {

PackingResult packing_in_box(const DemSystem& system, const std::array<double, 3>& lo,
                             const std::array<double, 3>& hi) {
  for (int k = 0; k < 3; ++k) {
    if (!(hi[k] > lo[k])) throw std::invalid_argument("packing box: hi must exceed lo");
  }
  const ParticleState& p = system.particles();
  const std::vector<std::int32_t> contacts = system.contact_counts();
  PackingResult r;
  r.top = std::numeric_limits<double>::quiet_NaN();
  double volume = 0.0;
  std::int64_t contact_sum = 0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    if (p.px[i] < lo[0] || p.px[i] > hi[0] || p.py[i] < lo[1] || p.py[i] > hi[1] ||
        p.pz[i] < lo[2] || p.pz[i] > hi[2])
      continue;
    ++r.particles;
    contact_sum += contacts[i];
    double top = 0.0;
    if (p.shape[i] == static_cast<std::uint8_t>(ParticleShape::polyhedron)) {
      const PolyhedronShape& s = system.shape(p.shape_id[i]);
      const double sc = p.scale[i];
      volume += s.volume * sc * sc * sc;
      // z row of the rotation body -> world of the quaternion (w, x, y, z)
      const double w = p.qw[i], x = p.qx[i], y = p.qy[i], z = p.qz[i];
      const double r0 = 2.0 * (x * z - w * y), r1 = 2.0 * (y * z + w * x),
                   r2 = 1.0 - 2.0 * (x * x + y * y);
      double up = -std::numeric_limits<double>::infinity();
      for (std::size_t v = 0; v + 2 < s.vertices.size(); v += 3) {
        up = std::max(up, r0 * s.vertices[v] + r1 * s.vertices[v + 1] + r2 * s.vertices[v + 2]);
      }
      top = p.pz[i] + sc * (up + s.dilation);
    } else {
      const double rad = p.radius[i];
      volume += 4.0 / 3.0 * std::numbers::pi * rad * rad * rad;
      top = p.pz[i] + rad;
    }
    r.top = r.particles == 1 ? top : std::max(r.top, top);
  }
  r.solid_fraction = volume / ((hi[0] - lo[0]) * (hi[1] - lo[1]) * (hi[2] - lo[2]));
  r.coordination = r.particles > 0 ? double(contact_sum) / double(r.particles) : 0.0;
  return r;
}

}  // namespace demfem::dem
