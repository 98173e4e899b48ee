#include "demfem/dem/state_check.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace demfem::dem {

void check_particle_state(const ParticleState& st, const std::string& where) {
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
    m << where << ": particle " << i << ": " << what << " is " << value << " (" << rule
      << "); the state cannot be continued: resume from an earlier checkpoint";
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

}  // namespace demfem::dem
