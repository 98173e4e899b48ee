#include "demfem/dem/sensors/packing.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

#include "demfem/dem/physics/rigid_body.hpp"

namespace demfem::dem {

double particle_top(const DemSystem& system, std::size_t i) {
  const ParticleState& p = system.particles();
  if (p.shape_id.size() != p.size() || p.shape_id[i] < 0) return p.pz[i] + p.radius[i];
  const PolyhedronShape& sh = system.shape(p.shape_id[i]);
  const phys::Rot r = phys::rotation(p.qw[i], p.qx[i], p.qy[i], p.qz[i]);
  double hz = -std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k + 2 < sh.vertices.size(); k += 3)
    hz = std::max(
        hz,
        phys::to_world(r, phys::Vec3{sh.vertices[k], sh.vertices[k + 1], sh.vertices[k + 2]}).z);
  return p.pz[i] + p.scale[i] * (hz + sh.dilation);
}

PackingResult packing_in_box(const DemSystem& system, const std::array<double, 3>& lo,
                             const std::array<double, 3>& hi) {
  for (int k = 0; k < 3; ++k) {
    if (!(hi[k] > lo[k])) throw std::invalid_argument("packing box: hi must exceed lo");
  }
  // Periodic directions: a centre counts at its image nearest the box's middle, so that a box
  // across the seam holds the particles of both sides (it may not be longer than the period).
  const PeriodicRange& periodic = system.settings().periodic;
  for (int k = 0; k < 3; ++k)
    if (periodic.on[k] && hi[k] - lo[k] > periodic.period(k))
      throw std::invalid_argument(std::string("packing box: longer than the period in ") +
                                  "xyz"[k]);
  auto image = [&](double x, int k) {
    if (!periodic.on[k]) return x;
    const double L = periodic.period(k);
    return x - L * std::round((x - 0.5 * (lo[k] + hi[k])) / L);
  };
  const ParticleState& p = system.particles();
  const std::vector<std::int32_t> contacts = system.contact_counts();
  PackingResult r;
  r.top = std::numeric_limits<double>::quiet_NaN();
  double volume = 0.0;
  std::int64_t contact_sum = 0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    const double x = image(p.px[i], 0), y = image(p.py[i], 1), z = image(p.pz[i], 2);
    if (x < lo[0] || x > hi[0] || y < lo[1] || y > hi[1] || z < lo[2] || z > hi[2]) continue;
    ++r.particles;
    contact_sum += contacts[i];
    if (p.shape[i] == static_cast<std::uint8_t>(ParticleShape::polyhedron)) {
      const double sc = p.scale[i];
      volume += system.shape(p.shape_id[i]).volume * sc * sc * sc;
    } else {
      const double rad = p.radius[i];
      volume += 4.0 / 3.0 * std::numbers::pi * rad * rad * rad;
    }
    const double top = particle_top(system, i);
    r.top = r.particles == 1 ? top : std::max(r.top, top);
  }
  r.solid_fraction = volume / ((hi[0] - lo[0]) * (hi[1] - lo[1]) * (hi[2] - lo[2]));
  r.coordination = r.particles > 0 ? double(contact_sum) / double(r.particles) : 0.0;
  return r;
}

}  // namespace demfem::dem
