#include "demfem/dem/sensors/packing.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

#include "demfem/dem/physics/periodic_image.hpp"
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

namespace {
// The box's checks (hi > lo, no longer than a period) and the image rule of its periodic
// directions: a point counts at its image nearest the box's middle, so that a box across the
// seam holds the particles of both sides.
class BoxImage {
 public:
  BoxImage(const DemSystem& system, const std::array<double, 3>& lo,
           const std::array<double, 3>& hi)
      : lo_(lo), hi_(hi), periodic_(system.settings().periodic) {
    for (int k = 0; k < 3; ++k) {
      if (!(hi[k] > lo[k])) throw std::invalid_argument("packing box: hi must exceed lo");
    }
    for (int k = 0; k < 3; ++k)
      if (periodic_.on[k] && hi[k] - lo[k] > periodic_.period(k))
        throw std::invalid_argument(std::string("packing box: longer than the period in ") +
                                    "xyz"[k]);
  }
  double image(double x, int k) const {
    if (!periodic_.on[k]) return x;
    const double L = periodic_.period(k);
    return x - L * std::round((x - 0.5 * (lo_[k] + hi_[k])) / L);
  }
  bool contains(double x, double y, double z) const {
    x = image(x, 0), y = image(y, 1), z = image(z, 2);
    return !(x < lo_[0] || x > hi_[0] || y < lo_[1] || y > hi_[1] || z < lo_[2] || z > hi_[2]);
  }
  double volume() const { return (hi_[0] - lo_[0]) * (hi_[1] - lo_[1]) * (hi_[2] - lo_[2]); }

 private:
  std::array<double, 3> lo_, hi_;
  const PeriodicRange& periodic_;
};
}  // namespace

PackingResult packing_in_box(const DemSystem& system, const std::array<double, 3>& lo,
                             const std::array<double, 3>& hi) {
  const BoxImage box(system, lo, hi);
  const ParticleState& p = system.particles();
  const std::vector<std::int32_t> contacts = system.contact_counts();
  PackingResult r;
  r.top = std::numeric_limits<double>::quiet_NaN();
  double volume = 0.0;
  std::int64_t contact_sum = 0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    if (!box.contains(p.px[i], p.py[i], p.pz[i])) continue;
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
  r.solid_fraction = volume / box.volume();
  r.coordination = r.particles > 0 ? double(contact_sum) / double(r.particles) : 0.0;
  return r;
}

ForceDistribution force_distribution(std::span<const double> forces) {
  ForceDistribution d;
  d.contacts = static_cast<std::int64_t>(forces.size());
  const double nan = std::numeric_limits<double>::quiet_NaN();
  if (forces.empty()) {
    d.mean = d.above_two_mean = d.tail_decay = nan;
    return d;
  }
  double sum = 0.0;
  for (const double f : forces) sum += f;
  d.mean = sum / double(forces.size());
  std::int64_t above_two = 0, above_mean = 0;
  double excess = 0.0;  // sum of x - 1 over x = f / <f> > 1
  for (const double f : forces) {
    if (f > 2.0 * d.mean) ++above_two;
    if (f > d.mean) ++above_mean, excess += f / d.mean - 1.0;
  }
  d.above_two_mean = double(above_two) / double(forces.size());
  d.tail_decay = above_mean > 0 && excess > 0.0 ? double(above_mean) / excess : nan;
  return d;
}

ContactStatistics contact_statistics_in_box(const DemSystem& system,
                                            const std::array<double, 3>& lo,
                                            const std::array<double, 3>& hi) {
  const BoxImage box(system, lo, hi);
  const ParticleState& p = system.particles();
  const std::vector<DemSystem::PairForce> contacts = system.contact_forces();
  std::vector<std::int32_t> count(p.size(), 0);
  for (const auto& c : contacts) ++count[std::size_t(c.i)], ++count[std::size_t(c.j)];
  std::vector<std::int32_t> kept(p.size(), 0);  // contacts between non-rattlers
  phys::PeriodicBox pbox;
  const PeriodicRange& periodic = system.settings().periodic;
  for (int d = 0; d < 3; ++d)
    if (periodic.on[d])
      pbox.period[d] = periodic.period(d), pbox.half[d] = 0.5 * pbox.period[d],
      pbox.lo[d] = periodic.lo[d];
  ContactStatistics r;
  std::vector<double> magnitudes;
  double moment_zz = 0.0;  // sum of f_z l_z, N m
  for (const auto& c : contacts) {
    const auto i = std::size_t(c.i), j = std::size_t(c.j);
    if (count[i] >= 2 && count[j] >= 2) ++kept[i], ++kept[j];
    const double lx = phys::image_branch(pbox, 0, p.px[i], p.px[j]);
    const double ly = phys::image_branch(pbox, 1, p.py[i], p.py[j]);
    const double lz = phys::image_branch(pbox, 2, p.pz[i], p.pz[j]);
    if (!box.contains(p.px[i] + 0.5 * lx, p.py[i] + 0.5 * ly, p.pz[i] + 0.5 * lz)) continue;
    const auto& f = c.force;
    magnitudes.push_back(std::sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]));
    moment_zz += f[2] * lz;
  }
  std::int64_t members = 0, member_contacts = 0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    if (!box.contains(p.px[i], p.py[i], p.pz[i])) continue;
    if (count[i] < 2) {
      ++r.rattlers;
    } else {
      ++members;
      member_contacts += kept[i];
    }
  }
  r.coordination_no_rattlers = members > 0 ? double(member_contacts) / double(members) : 0.0;
  r.force = force_distribution(magnitudes);
  r.stress_zz = -moment_zz / box.volume();
  return r;
}

}  // namespace demfem::dem
