#include "demfem/dem/state_check.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace demfem::dem {

void check_particle_state(const ParticleState& st, const std::string& where) {
  const std::size_t n = st.size();
  const std::pair<const char*, const std::vector<double>*> arrays[] = {
      {"position y", &st.py},
      {"position z", &st.pz},
      {"velocity x", &st.vx},
      {"velocity y", &st.vy},
      {"velocity z", &st.vz},
      {"angular velocity x", &st.wx},
      {"angular velocity y", &st.wy},
      {"angular velocity z", &st.wz},
      {"orientation w", &st.qw},
      {"orientation x", &st.qx},
      {"orientation y", &st.qy},
      {"orientation z", &st.qz},
      {"force x", &st.fx},
      {"force y", &st.fy},
      {"force z", &st.fz},
      {"radius", &st.radius},
      {"mass", &st.mass},
      {"moment of inertia", &st.inertia}};
  for (const auto& [what, v] : arrays) {
    if (v->size() != n) {
      throw std::runtime_error(where + ": " + what + " has " + std::to_string(v->size()) +
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
  const std::pair<const char*, const std::vector<double>*> finite[] = {
      {"position x", &st.px},
      {"position y", &st.py},
      {"position z", &st.pz},
      {"velocity x", &st.vx},
      {"velocity y", &st.vy},
      {"velocity z", &st.vz},
      {"angular velocity x", &st.wx},
      {"angular velocity y", &st.wy},
      {"angular velocity z", &st.wz},
      {"force x", &st.fx},
      {"force y", &st.fy},
      {"force z", &st.fz}};
  for (std::size_t i = 0; i < n; ++i) {
    for (const auto& [what, v] : finite) {
      if (!std::isfinite((*v)[i])) bad(i, what, (*v)[i], "must be finite");
    }
    const std::pair<const char*, double> positive[] = {
        {"radius", st.radius[i]}, {"mass", st.mass[i]}, {"moment of inertia", st.inertia[i]}};
    for (const auto& [what, v] : positive) {
      if (!(std::isfinite(v) && v > 0.0)) bad(i, what, v, "must be finite and > 0");
    }
    const double q2 =
        st.qw[i] * st.qw[i] + st.qx[i] * st.qx[i] + st.qy[i] * st.qy[i] + st.qz[i] * st.qz[i];
    if (!(std::abs(q2 - 1.0) < 1e-6)) {
      bad(i, "|orientation|^2", q2, "must be 1 within 1e-6: a unit quaternion");
    }
  }
}

}  // namespace demfem::dem
