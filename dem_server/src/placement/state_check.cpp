#include "demfem/dem/placement/state_check.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace demfem::dem {

void check_particle_state(const ParticleState& st, const std::string& where,
                          const std::string& remedy) {
  const std::size_t n = st.size();
  // Every per-particle number, and what a scene would give it: finite, or finite and > 0.
  struct Quantity {
    const char* what;
    const std::vector<double>* values;
    bool positive;
  };
  const Quantity quantities[] = {{"position x", &st.px, false},
                                 {"position y", &st.py, false},
                                 {"position z", &st.pz, false},
                                 {"velocity x", &st.vx, false},
                                 {"velocity y", &st.vy, false},
                                 {"velocity z", &st.vz, false},
                                 {"angular velocity x", &st.wx, false},
                                 {"angular velocity y", &st.wy, false},
                                 {"angular velocity z", &st.wz, false},
                                 {"orientation w", &st.qw, false},
                                 {"orientation x", &st.qx, false},
                                 {"orientation y", &st.qy, false},
                                 {"orientation z", &st.qz, false},
                                 {"force x", &st.fx, false},
                                 {"force y", &st.fy, false},
                                 {"force z", &st.fz, false},
                                 {"radius", &st.radius, true},
                                 {"mass", &st.mass, true},
                                 {"moment of inertia", &st.inertia, true}};
  for (const auto& q : quantities) {
    if (q.values->size() != n) {
      throw std::runtime_error(where + ": " + q.what + " has " + std::to_string(q.values->size()) +
                               " entries for " + std::to_string(n) + " particles");
    }
  }
  if (st.material.size() != n || st.shape.size() != n) {
    throw std::runtime_error(where + ": material or shape arrays do not match the " +
                             std::to_string(n) + " particles");
  }
  auto bad = [&](std::size_t i, const std::string& what, double value, const char* rule) {
    std::ostringstream m;
    m << where << ": particle " << i << ": " << what << " is " << value << " (" << rule << "); "
      << remedy;
    throw std::runtime_error(m.str());
  };
  for (std::size_t i = 0; i < n; ++i) {
    for (const auto& q : quantities) {
      const double v = (*q.values)[i];
      if (!std::isfinite(v))
        bad(i, q.what, v, q.positive ? "must be finite and > 0" : "must be finite");
      if (q.positive && !(v > 0.0)) bad(i, q.what, v, "must be finite and > 0");
    }
    const double q2 =
        st.qw[i] * st.qw[i] + st.qx[i] * st.qx[i] + st.qy[i] * st.qy[i] + st.qz[i] * st.qz[i];
    if (!(std::abs(q2 - 1.0) < 1e-6)) {
      bad(i, "|orientation|^2", q2, "must be 1 within 1e-6: a unit quaternion");
    }
  }
}

std::string outside_domain(const DemSystem& system, const std::vector<std::int64_t>& ids) {
  if (system.wall_count() == 0) return {};
  double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
  for (std::size_t w = 0; w < system.wall_count(); ++w) {
    const auto v = system.wall_vertices(static_cast<std::int32_t>(w));
    for (std::size_t k = 0; k + 2 < v.size(); k += 3)
      for (int d = 0; d < 3; ++d)
        lo[d] = std::min(lo[d], v[k + d]), hi[d] = std::max(hi[d], v[k + d]);
  }
  if (!(lo[0] <= hi[0])) return {};
  const double margin = std::max({kDomainMarginMin, hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]});
  for (int d = 0; d < 3; ++d) lo[d] -= margin, hi[d] += margin;
  const auto& p = system.particles();
  for (std::size_t i = 0; i < p.size(); ++i) {
    const double x[3] = {p.px[i], p.py[i], p.pz[i]};
    if (x[0] >= lo[0] && x[0] <= hi[0] && x[1] >= lo[1] && x[1] <= hi[1] && x[2] >= lo[2] &&
        x[2] <= hi[2])
      continue;
    std::ostringstream m;
    m.precision(9);
    m << "particle " << (i < ids.size() ? ids[i] : static_cast<std::int64_t>(i))
      << " left the domain at t = " << system.time() << " s: its centre (" << x[0] << ", " << x[1]
      << ", " << x[2] << ") m lies outside [" << lo[0] << ", " << hi[0] << "] x [" << lo[1] << ", "
      << hi[1] << "] x [" << lo[2] << ", " << hi[2] << "] m, the walls' bounding box grown by "
      << margin
      << " m (the larger of 1 m and the box's largest side); the particle was shot away (the DEM "
         "blew up: reduce dt or the speeds of the scene) or falls past every wall (close the "
         "walls under it)";
    return m.str();
  }
  return {};
}

}  // namespace demfem::dem
