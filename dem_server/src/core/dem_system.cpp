// DemSystem: the public face of the DEM engine (settings, particles, run control). The
// engine itself, DemSystem::Impl, is described in dem_system_impl.hpp.

#include "dem_system_impl.hpp"

#include <omp.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace demfem::dem {

using detail::bad;
using detail::kMaxWallContacts;
using phys::Vec3;

namespace {

bool finite3(const std::array<double, 3>& a) {
  return std::isfinite(a[0]) && std::isfinite(a[1]) && std::isfinite(a[2]);
}

void validate(const DemSettings& s) {
  if (!(s.dt > 0.0) || !std::isfinite(s.dt))
    bad("settings.dt = " + std::to_string(s.dt) + " must be finite and > 0 s");
  if (!finite3(s.gravity)) bad("settings.gravity must be finite");
  if (s.materials.empty()) bad("settings.materials is empty (need at least one material)");
  const std::size_t n = s.materials.size();
  for (std::size_t i = 0; i < n; ++i) {
    const auto& m = s.materials[i];
    const std::string where = "settings.materials[" + std::to_string(i) + "] ('" + m.name + "')";
    if (!(m.youngs_modulus > 0.0) || !std::isfinite(m.youngs_modulus))
      bad(where + ".youngs_modulus = " + std::to_string(m.youngs_modulus) + " must be > 0 Pa");
    if (!(m.poisson_ratio >= 0.0 && m.poisson_ratio < 0.5))
      bad(where + ".poisson_ratio = " + std::to_string(m.poisson_ratio) + " outside [0, 0.5)");
    if (!(m.density >= 0.0) || !std::isfinite(m.density))
      bad(where + ".density = " + std::to_string(m.density) + " must be >= 0 kg/m^3");
  }
  if (s.pairs.size() != n * n)
    bad("settings.pairs has " + std::to_string(s.pairs.size()) +
        " entries, need materials^2 = " + std::to_string(n * n));
  for (std::size_t k = 0; k < s.pairs.size(); ++k) {
    const auto& p = s.pairs[k];
    const std::string where = "settings.pairs[" + std::to_string(k) + "]";
    if (!(p.restitution > 0.0 && p.restitution <= 1.0))
      bad(where + ".restitution = " + std::to_string(p.restitution) + " outside (0, 1]");
    if (!(p.friction >= 0.0) || !std::isfinite(p.friction))
      bad(where + ".friction = " + std::to_string(p.friction) + " must be >= 0");
    if (!(p.rolling_friction >= 0.0) || !std::isfinite(p.rolling_friction))
      bad(where + ".rolling_friction = " + std::to_string(p.rolling_friction) + " must be >= 0");
    if (!(p.rocking_damping >= 0.0 && p.rocking_damping <= 10.0))
      bad(where + ".rocking_damping = " + std::to_string(p.rocking_damping) +
          " must be in [0, 10]");
  }
  if (!(s.list_skin >= 0.0 && s.list_skin <= 1.0))
    bad("settings.list_skin = " + std::to_string(s.list_skin) +
        " must be in [0, 1] (fraction of the skin; 0 = adaptive)");
  if (!(s.skin >= 0.0) || !std::isfinite(s.skin))
    bad("settings.skin = " + std::to_string(s.skin) + " must be >= 0 m");
  if (s.threads < 0) bad("settings.threads = " + std::to_string(s.threads) + " must be >= 0");
  for (int d = 0; d < 3; ++d) {
    const auto& p = s.periodic;
    if (p.on[d] && !(std::isfinite(p.lo[d]) && std::isfinite(p.hi[d]) && p.hi[d] > p.lo[d]))
      bad(std::string("settings.periodic: the range in ") + "xyz"[d] +
          " must be finite with hi > lo");
  }
}
}  // namespace

DemBackendKind dem_backend_from_name(const std::string& name) {
  if (name == "cpu") return DemBackendKind::cpu;
  if (name == "cuda") return DemBackendKind::cuda;
  throw std::invalid_argument("backend '" + name + "', accepted: 'cpu', 'cuda'");
}

const char* dem_backend_name(DemBackendKind kind) {
  return kind == DemBackendKind::cuda ? "cuda" : "cpu";
}

MaterialPair::PolyLaw poly_law_from_name(const std::string& name) {
  if (name == "pressure_centre") return MaterialPair::PolyLaw::pressure_centre;
  if (name == "smooth") return MaterialPair::PolyLaw::smooth;
  throw std::invalid_argument("poly_law '" + name + "', accepted: 'pressure_centre', 'smooth'");
}

void DemSystem::Impl::setup_pairs() {
  material_count = s.materials.size();
  pair_table.resize(material_count * material_count);
  friction = rolling = false;
  for (std::size_t a = 0; a < material_count; ++a)
    for (std::size_t b = 0; b < material_count; ++b) {
      const auto& ma = s.materials[a];
      const auto& mb = s.materials[b];
      const auto& p = s.pairs[a * material_count + b];
      pair_table[a * material_count + b] = phys::pair_constants(
          ma.youngs_modulus, ma.poisson_ratio, mb.youngs_modulus, mb.poisson_ratio, p.restitution,
          p.friction, p.rolling_friction, p.rocking_damping,
          p.poly_law == MaterialPair::PolyLaw::smooth ? phys::kLawSmooth
                                                      : phys::kLawPressureCentre);
      friction = friction || p.friction > 0.0 || p.rolling_friction > 0.0;
      rolling = rolling || p.rolling_friction > 0.0;
    }
}

void DemSystem::Impl::refresh_particle_derived() {
  rmax = 0.0;
  for (double r : st.radius) rmax = std::max(rmax, r);
  list.skin = s.skin > 0.0 ? s.skin : 0.2 * rmax;
  orientation = s.track_orientation;
  poly_count = 0;
  for (std::uint8_t shape : st.shape)
    poly_count += shape != static_cast<std::uint8_t>(ParticleShape::sphere) ? 1 : 0;
  poly = poly_count > 0;
  orientation = orientation || poly;
  // The CUDA backend checks the list against the whole skin on the device: one level.
  list.inner_skin =
      gpu != nullptr
          ? list.skin
          : (s.list_skin > 0.0 ? s.list_skin : detail::NeighbourList::kInnerSkin) * list.skin;
}

// =========================================================================================
DemSystem::DemSystem(DemSettings settings) : impl_(std::make_unique<Impl>()) {
  validate(settings);
  impl_->s = std::move(settings);
  impl_->threads = impl_->s.threads > 0 ? impl_->s.threads : omp_get_max_threads();
  impl_->setup_pairs();
  if (impl_->s.periodic.any()) {
    impl_->periodic = true;
    for (int d = 0; d < 3; ++d) {
      if (!impl_->s.periodic.on[d]) continue;
      impl_->pbox.period[d] = impl_->s.periodic.period(d);
      impl_->pbox.half[d] = 0.5 * impl_->pbox.period[d];
      impl_->pbox.lo[d] = impl_->s.periodic.lo[d];
    }
  }
  if (impl_->s.backend == DemBackendKind::cuda) {
    if (!cuda_available())
      throw std::runtime_error(
          "DemSystem: settings.backend = 'cuda' but this build has no CUDA backend or no CUDA "
          "device is present; use backend = 'cpu'");
    impl_->gpu = cuda_backend_create();
  }
}
DemSystem::~DemSystem() = default;
DemSystem::DemSystem(DemSystem&&) noexcept = default;
DemSystem& DemSystem::operator=(DemSystem&&) noexcept = default;

const DemSettings& DemSystem::settings() const {
  return impl_->s;
}

std::int32_t DemSystem::add_shape(const PolyhedronShape& shape) {
  return impl_->shapes.add(shape);
}
std::size_t DemSystem::shape_count() const {
  return impl_->shapes.size();
}
const PolyhedronShape& DemSystem::shape(std::int32_t id) const {
  if (id < 0 || static_cast<std::size_t>(id) >= impl_->shapes.size())
    throw std::out_of_range("DemSystem: shape index " + std::to_string(id) + " outside [0, " +
                            std::to_string(impl_->shapes.size()) + ")");
  return impl_->shapes.shape(id);
}

std::size_t DemSystem::add_particles(std::span<const ParticleInit> particles) {
  auto& I = *impl_;
  auto& st = I.st;
  const std::size_t first = st.size();
  for (std::size_t k = 0; k < particles.size(); ++k) {
    const auto& p = particles[k];
    const std::string where = "add_particles: particle " + std::to_string(k);
    if (!finite3(p.position) || !finite3(p.velocity) || !finite3(p.angular_velocity))
      bad(where + " has a non-finite position, velocity or angular velocity");
    if (p.shape == ParticleShape::sphere && (!(p.radius > 0.0) || !std::isfinite(p.radius)))
      bad(where + ".radius = " + std::to_string(p.radius) + " must be > 0 m");
    if (p.material < 0 || static_cast<std::size_t>(p.material) >= I.material_count)
      bad(where + ".material = " + std::to_string(p.material) + " outside [0, " +
          std::to_string(I.material_count) + ")");
    if (!(I.s.materials[p.material].density > 0.0))
      bad(where + ": material '" + I.s.materials[p.material].name +
          "' has density 0 (particles need a density > 0)");
    if (p.shape == ParticleShape::polyhedron) {
      if (p.shape_id < 0 || static_cast<std::size_t>(p.shape_id) >= I.shapes.size())
        bad(where + ".shape_id = " + std::to_string(p.shape_id) + " outside [0, " +
            std::to_string(I.shapes.size()) + ") (add_shape first)");
      if (!(p.scale > 0.0) || !std::isfinite(p.scale))
        bad(where + ".scale = " + std::to_string(p.scale) + " must be > 0");
    } else if (p.shape != ParticleShape::sphere) {
      bad(where + ".shape = " + std::to_string(static_cast<int>(p.shape)) +
          " is not a shape (sphere 0, polyhedron 1)");
    }
    const auto& q = p.orientation;
    const double q2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
    if (!(std::abs(q2 - 1.0) <= 1e-6))
      bad(where + ".orientation is not a unit quaternion (|q|^2 = " + std::to_string(q2) +
          ", accepted 1 +- 1e-6)");
  }
  for (const auto& p : particles) {
    st.px.push_back(p.position[0]), st.py.push_back(p.position[1]), st.pz.push_back(p.position[2]);
    st.vx.push_back(p.velocity[0]), st.vy.push_back(p.velocity[1]), st.vz.push_back(p.velocity[2]);
    st.wx.push_back(p.angular_velocity[0]), st.wy.push_back(p.angular_velocity[1]),
        st.wz.push_back(p.angular_velocity[2]);
    const auto& q0 = p.orientation;
    const double ql = std::sqrt(q0[0] * q0[0] + q0[1] * q0[1] + q0[2] * q0[2] + q0[3] * q0[3]);
    if (ql == 1.0)  // keep the bits of a unit quaternion as given
      st.qw.push_back(q0[0]), st.qx.push_back(q0[1]), st.qy.push_back(q0[2]),
          st.qz.push_back(q0[3]);
    else
      st.qw.push_back(q0[0] / ql), st.qx.push_back(q0[1] / ql), st.qy.push_back(q0[2] / ql),
          st.qz.push_back(q0[3] / ql);
    const double rho = I.s.materials[p.material].density;
    double m, radius, inertia;
    std::array<double, 3> ib;
    if (p.shape == ParticleShape::polyhedron) {
      // the shape at scale s: volume s^3, inertia s^5 (principal frame), bounding radius s
      const PolyhedronShape& sh = I.shapes.shape(p.shape_id);
      const double sc = p.scale;
      m = rho * sc * sc * sc * sh.volume;
      const double s5 = rho * sc * sc * sc * sc * sc;
      ib = {s5 * sh.inertia[0], s5 * sh.inertia[1], s5 * sh.inertia[2]};
      radius = sc * I.shapes.bound(p.shape_id);
      inertia = (ib[0] + ib[1] + ib[2]) / 3.0;
      st.shape_id.push_back(p.shape_id), st.scale.push_back(sc);
    } else {
      m = rho * 4.0 / 3.0 * 3.14159265358979323846 * p.radius * p.radius * p.radius;
      radius = p.radius;
      inertia = 0.4 * m * p.radius * p.radius;
      ib = {inertia, inertia, inertia};
      st.shape_id.push_back(-1), st.scale.push_back(1.0);
    }
    st.ix.push_back(ib[0]), st.iy.push_back(ib[1]), st.iz.push_back(ib[2]);
    st.fx.push_back(m * I.s.gravity[0]), st.fy.push_back(m * I.s.gravity[1]),
        st.fz.push_back(m * I.s.gravity[2]);
    st.radius.push_back(radius), st.mass.push_back(m), st.inertia.push_back(inertia);
    st.material.push_back(p.material);
    st.shape.push_back(static_cast<std::uint8_t>(p.shape));
    I.tx.push_back(0), I.ty.push_back(0), I.tz.push_back(0);
  }
  const std::size_t n = st.size();
  auto& wc = I.wall_contacts;
  wc.key.resize(kMaxWallContacts * n, -1);
  wc.shear.resize(3 * kMaxWallContacts * n, 0.0);
  if (I.rolling) wc.rolling_history.resize(3 * kMaxWallContacts * n, 0.0);
  wc.force.resize(3 * kMaxWallContacts * n), wc.point.resize(3 * kMaxWallContacts * n),
      wc.weights.resize(3 * kMaxWallContacts * n), wc.triangle.resize(kMaxWallContacts * n);
  wc.count.resize(n, 0);
  if (!I.frozen.empty()) I.frozen.resize(n, 0);
  if (I.periodic) I.image.resize(3 * n, 0);
  // keep the pair rows of the old particles (new ones have none yet)
  if (!I.list.row.empty()) I.list.row.resize(n + 1, I.list.row.back());
  I.list.update_x.clear();
  I.refresh_particle_derived();
  I.list.must_build = true;
  return first;
}

void DemSystem::remove_particles(std::span<const std::uint8_t> keep) {
  auto& I = *impl_;
  const std::size_t n = I.n();
  if (keep.size() != n)
    bad("remove_particles: keep has " + std::to_string(keep.size()) + " entries, need " +
        std::to_string(n));
  std::vector<std::int32_t> map(n, -1);
  std::int32_t m = 0;
  for (std::size_t i = 0; i < n; ++i)
    if (keep[i]) map[i] = m++;
  auto compact = [&](auto& v, std::size_t stride) {
    std::size_t o = 0;
    for (std::size_t i = 0; i < n; ++i)
      if (keep[i]) {
        for (std::size_t d = 0; d < stride; ++d) v[stride * o + d] = v[stride * i + d];
        ++o;
      }
    v.resize(stride * o);
  };
  // pair rows: renumber, drop pairs with a removed particle (order i < j is kept)
  if (I.list.row.size() == n + 1) {
    std::vector<std::int64_t> nrow(static_cast<std::size_t>(m) + 1, 0);
    std::vector<std::int32_t> nnbr;
    std::vector<double> nsh, nrh, nax;
    std::vector<std::int32_t> nft;
    for (std::size_t i = 0; i < n; ++i) {
      if (!keep[i]) continue;
      for (std::int64_t p = I.list.row[i]; p < I.list.row[i + 1]; ++p) {
        if (map[I.list.partner[p]] < 0) continue;
        nnbr.push_back(map[I.list.partner[p]]);
        if (!I.slots.shear.empty())
          for (int d = 0; d < 3; ++d) nsh.push_back(I.slots.shear[3 * p + d]);
        if (!I.slots.rolling_history.empty())
          for (int d = 0; d < 3; ++d) nrh.push_back(I.slots.rolling_history[3 * p + d]);
        if (!I.slots.separating_axis.empty())
          for (int d = 0; d < 3; ++d) nax.push_back(I.slots.separating_axis[3 * p + d]);
        if (!I.slots.closest_features.empty())
          for (int d = 0; d < 6; ++d) nft.push_back(I.slots.closest_features[6 * p + d]);
      }
      nrow[map[i] + 1] = static_cast<std::int64_t>(nnbr.size());
    }
    I.list.row.swap(nrow), I.list.partner.swap(nnbr), I.slots.shear.swap(nsh),
        I.slots.rolling_history.swap(nrh);
    I.slots.separating_axis.swap(nax);
    I.slots.closest_features.swap(nft);
  }
  auto& st = I.st;
  for (auto* v :
       {&st.px,      &st.py, &st.pz, &st.vx, &st.vy,    &st.vz, &st.wx, &st.wy,     &st.wz,
        &st.qw,      &st.qx, &st.qy, &st.qz, &st.fx,    &st.fy, &st.fz, &st.radius, &st.mass,
        &st.inertia, &I.tx,  &I.ty,  &I.tz,  &st.scale, &st.ix, &st.iy, &st.iz})
    compact(*v, 1);
  compact(st.material, 1);
  compact(st.shape, 1);
  compact(st.shape_id, 1);
  auto& wc = I.wall_contacts;
  compact(wc.key, kMaxWallContacts), compact(wc.shear, 3 * kMaxWallContacts);
  if (!wc.rolling_history.empty()) compact(wc.rolling_history, 3 * kMaxWallContacts);
  compact(wc.force, 3 * kMaxWallContacts), compact(wc.point, 3 * kMaxWallContacts),
      compact(wc.weights, 3 * kMaxWallContacts), compact(wc.triangle, kMaxWallContacts);
  compact(wc.count, 1);
  if (!I.frozen.empty()) compact(I.frozen, 1);
  if (!I.image.empty()) compact(I.image, 3);
  I.refresh_frozen();
  I.list.update_x.clear();
  I.refresh_particle_derived();
  I.list.must_build = true;
}

const ParticleState& DemSystem::particles() const {
  return impl_->st;
}
std::size_t DemSystem::particle_count() const {
  return impl_->n();
}

void DemSystem::advance(std::int64_t substeps, ForceMode mode) {
  auto& I = *impl_;
  if (substeps < 0) bad("advance: substeps = " + std::to_string(substeps) + " must be >= 0");
  if (substeps == 0) return;
  I.advance_max_overlap = 0.0;
  I.advance_max_relative_overlap = 0.0;
  if (I.gpu) {
    I.advance_gpu(substeps, mode);
    return;
  }
  if (I.walls.has_flexible) {
    std::fill(I.walls.flexible_force.begin(), I.walls.flexible_force.end(), 0.0);
    I.walls.flexible_max_overlap = 0.0;
  }
  if (I.periodic) I.check_periods();
  for (std::int64_t k = 0; k < substeps; ++k) {
    I.check_cancel(k, substeps);
    const bool last = k + 1 == substeps;
    if (I.friction)
      I.step<true>(last, mode, substeps);
    else
      I.step<false>(last, mode, substeps);
  }
}

void DemSystem::set_cancel_flag(const std::atomic<bool>* flag) {
  impl_->cancel = flag;
}

double DemSystem::advance_max_overlap() const {
  return impl_->advance_max_overlap;
}
double DemSystem::advance_max_relative_overlap() const {
  return impl_->advance_max_relative_overlap;
}
double DemSystem::time() const {
  return impl_->t;
}
std::int64_t DemSystem::step_count() const {
  return impl_->steps;
}

double DemSystem::smallest_contact_radius() const {
  const auto& I = *impl_;
  double r = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < I.n(); ++i)
    r = std::min(r, I.st.shape_id[i] >= 0
                        ? I.st.scale[i] * I.shapes.shape(I.st.shape_id[i]).dilation
                        : I.st.radius[i]);
  return r;
}

double DemSystem::rayleigh_time_step() const {
  const auto& I = *impl_;
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < I.n(); ++i) {
    const auto& m = I.s.materials[I.st.material[i]];
    const double g = m.youngs_modulus / (2.0 * (1.0 + m.poisson_ratio));
    // a polyhedron: the radius of the sphere of its volume
    const double r =
        I.st.shape_id[i] >= 0
            ? std::cbrt(3.0 * I.st.mass[i] / (4.0 * 3.14159265358979323846 * m.density))
            : I.st.radius[i];
    best = std::min(best, phys::rayleigh_time_step(r, m.density, g, m.poisson_ratio));
  }
  return best;
}

double DemSystem::kinetic_energy() const {
  const auto& st = impl_->st;
  double e = 0.0;
  for (std::size_t i = 0; i < st.size(); ++i)
    if (st.shape_id[i] >= 0)
      e += 0.5 * st.mass[i] * (st.vx[i] * st.vx[i] + st.vy[i] * st.vy[i] + st.vz[i] * st.vz[i]) +
           phys::rotational_energy(phys::rotation(st.qw[i], st.qx[i], st.qy[i], st.qz[i]),
                                   Vec3{st.ix[i], st.iy[i], st.iz[i]},
                                   Vec3{st.wx[i], st.wy[i], st.wz[i]});
    else
      e += 0.5 * st.mass[i] * (st.vx[i] * st.vx[i] + st.vy[i] * st.vy[i] + st.vz[i] * st.vz[i]) +
           0.5 * st.inertia[i] * (st.wx[i] * st.wx[i] + st.wy[i] * st.wy[i] + st.wz[i] * st.wz[i]);
  return e;
}

void DemSystem::freeze(std::span<const std::uint8_t> mask) {
  auto& I = *impl_;
  if (mask.size() != I.n())
    bad("freeze: the mask has " + std::to_string(mask.size()) + " entries, need " +
        std::to_string(I.n()));
  if (I.frozen.empty()) I.frozen.assign(I.n(), 0);
  for (std::size_t i = 0; i < mask.size(); ++i)
    if (mask[i] != 0 && I.frozen[i] == 0) {
      I.frozen[i] = 1;
      I.st.vx[i] = I.st.vy[i] = I.st.vz[i] = 0.0;
      I.st.wx[i] = I.st.wy[i] = I.st.wz[i] = 0.0;
    }
  I.refresh_frozen();
  if (I.gpu) cuda_set_resident(I.gpu, false);  // the device takes the mask and the rest
}

void DemSystem::release_frozen() {
  auto& I = *impl_;
  if (I.frozen.empty()) return;
  I.frozen.clear();
  I.refresh_frozen();
  if (I.gpu) cuda_set_resident(I.gpu, false);  // the device takes the empty mask
}

std::span<const std::uint8_t> DemSystem::frozen() const {
  return impl_->frozen;
}

std::size_t DemSystem::frozen_count() const {
  return impl_->frozen_idx.size();
}

std::array<double, 3> DemSystem::frozen_support() const {
  const auto& I = *impl_;
  std::array<double, 3> f{0.0, 0.0, 0.0};
  for (const std::int64_t i : I.frozen_idx) {
    const auto k = static_cast<std::size_t>(i);
    f[0] -= I.st.fx[k], f[1] -= I.st.fy[k], f[2] -= I.st.fz[k];
  }
  return f;
}

double DemSystem::max_overlap() const {
  return impl_->max_overlap;
}

DemSystem::Timings DemSystem::timings() const {
  return impl_->timing;
}

// Internal diagnostics for the benchmark and tests (declared in dem_system.hpp).
std::int64_t DemSystem::neighbour_rebuilds() const {
  return impl_->list.builds;
}
std::int64_t DemSystem::neighbour_refilters() const {
  return impl_->list.refilters;
}
std::size_t DemSystem::neighbour_pairs() const {
  return impl_->list.pairs();
}

DemSystem::PairList DemSystem::pair_list() const {
  const Impl& I = *impl_;
  const detail::NeighbourList& L = I.list;
  return PairList{L.row,      L.partner,  I.slots.shear,         L.update_x,
                  L.update_y, L.update_z, I.walls.candidate_row, I.walls.candidate_triangle};
}

std::size_t DemSystem::contact_count() const {
  const auto& pf = impl_->slots.force;
  std::size_t c = 0;
  for (std::size_t p = 0; p + 2 < pf.size(); p += 3)
    if (pf[p] != 0.0 || pf[p + 1] != 0.0 || pf[p + 2] != 0.0) ++c;
  return c;
}
std::vector<std::int32_t> DemSystem::contact_counts() const {
  std::vector<std::int32_t> n(impl_->st.size(), 0);
  for (const PairForce& c : contact_forces()) {
    ++n[static_cast<std::size_t>(c.i)];
    ++n[static_cast<std::size_t>(c.j)];
  }
  return n;
}

std::vector<DemSystem::PairForce> DemSystem::contact_forces() const {
  const auto& I = *impl_;
  const auto& pf = I.slots.force;
  const auto& row = I.list.row;
  std::vector<PairForce> out;
  for (std::size_t i = 0; i + 1 < row.size() && i < I.st.size(); ++i) {
    for (auto k = row[i]; k < row[i + 1]; ++k) {
      const auto p = static_cast<std::size_t>(3 * k);
      if (p + 2 < pf.size() && (pf[p] != 0.0 || pf[p + 1] != 0.0 || pf[p + 2] != 0.0))
        out.push_back(PairForce{static_cast<std::int32_t>(i),
                                I.list.partner[static_cast<std::size_t>(k)],
                                {pf[p], pf[p + 1], pf[p + 2]}});
    }
  }
  return out;
}

std::size_t DemSystem::state_bytes() const {
  const auto& I = *impl_;
  const auto& st = I.st;
  std::size_t b = 0;
  auto add = [&b](const auto& v) { b += v.size() * sizeof(v[0]); };
  for (const auto* v :
       {&st.px,      &st.py,    &st.pz,           &st.vx,           &st.vy,          &st.vz,
        &st.wx,      &st.wy,    &st.wz,           &st.qw,           &st.qx,          &st.qy,
        &st.qz,      &st.fx,    &st.fy,           &st.fz,           &st.radius,      &st.mass,
        &st.inertia, &st.scale, &st.ix,           &st.iy,           &st.iz,          &I.tx,
        &I.ty,       &I.tz,     &I.list.update_x, &I.list.update_y, &I.list.update_z})
    add(*v);
  add(st.material), add(st.shape), add(st.shape_id);
  const auto& L = I.list;
  add(L.row), add(L.partner), add(L.owner), add(L.transposed_row), add(L.transposed_pair),
      add(L.transposed_owner);
  add(L.gather_row), add(L.gather_pair), add(L.gather_sign), add(I.slots.shear),
      add(I.slots.rolling_history);
  add(I.slots.force), add(I.slots.torque), add(I.slots.rolling_torque), add(I.slots.torque_j),
      add(I.slots.separating_axis), add(I.slots.closest_features), add(I.proofs.rotation),
      add(I.proofs.separation_left), add(I.proofs.core_motion), add(I.proofs.position),
      add(L.candidate_row), add(L.candidate_partner);
  const auto& wc = I.wall_contacts;
  add(I.walls.candidate_row), add(I.walls.candidate_triangle), add(wc.key), add(wc.shear),
      add(wc.rolling_history), add(wc.force);
  add(wc.point), add(wc.weights), add(wc.triangle), add(wc.count);
  const auto& a = I.shapes.arrays();
  add(a.vert), add(a.fnormal), add(a.fvert), add(a.edge), add(a.floop), add(a.flen);
  add(a.vsoa), add(a.fsoa);
  return b;
}

}  // namespace demfem::dem
