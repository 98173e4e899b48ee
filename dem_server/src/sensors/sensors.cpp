#include "demfem/dem/sensors/sensors.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

#include "demfem/dem/physics/rigid_body.hpp"
#include "demfem/dem/sensors/packing.hpp"
#include "demfem/io/csv_writer.hpp"

namespace demfem::dem {

MassFlowCounter::MassFlowCounter(std::array<double, 3> point, std::array<double, 3> direction,
                                 double radius)
    : point_(point), radius_(radius) {
  const double l = std::sqrt(direction[0] * direction[0] + direction[1] * direction[1] +
                             direction[2] * direction[2]);
  if (!(l > 0)) throw std::invalid_argument("mass flow sensor: direction must not be zero");
  dir_ = {direction[0] / l, direction[1] / l, direction[2] / l};
}

double MassFlowCounter::update(const ParticleState& p, std::span<const std::int64_t> ids) {
  if (ids.size() != p.size()) throw std::logic_error("mass flow sensor: ids and particles differ");
  double mass = 0.0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    const std::int64_t id = ids[i];
    if (id < 0) continue;
    if (std::size_t(id) >= side_.size()) side_.resize(std::size_t(id) + 1, 0);
    const double rx = p.px[i] - point_[0], ry = p.py[i] - point_[1], rz = p.pz[i] - point_[2];
    const double s = rx * dir_[0] + ry * dir_[1] + rz * dir_[2];
    const std::int8_t now = s >= 0 ? 1 : -1;
    const std::int8_t before = side_[std::size_t(id)];
    side_[std::size_t(id)] = now;
    if (before == 0 || before == now) continue;
    if (radius_ > 0) {
      // Distance from the axis through `point` along the direction.
      const double qx = rx - s * dir_[0], qy = ry - s * dir_[1], qz = rz - s * dir_[2];
      if (qx * qx + qy * qy + qz * qz > radius_ * radius_) continue;
    }
    mass += now > 0 ? p.mass[i] : -p.mass[i];
  }
  return mass;
}

std::vector<double> particle_tops(const DemSystem& system) {
  std::vector<double> tops(system.particles().size());
  for (std::size_t i = 0; i < tops.size(); ++i) tops[i] = particle_top(system, i);
  return tops;
}

ReposeResult angle_of_repose(const ParticleState& p, const ReposeOptions& o,
                             std::span<const double> tops) {
  if (!tops.empty() && tops.size() != p.size())
    throw std::logic_error("angle of repose: one top per particle expected");
  auto top_of = [&](std::size_t i) { return tops.empty() ? p.pz[i] + p.radius[i] : tops[i]; };
  std::size_t counted = 0;
  double mean_d = 0.0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    if (p.pz[i] > o.top) continue;
    mean_d += 2.0 * (top_of(i) - p.pz[i]);
    ++counted;
  }
  if (counted == 0) throw std::runtime_error("angle of repose: there are no particles below 'top'");
  mean_d /= double(counted);
  const double w = o.bin_width > 0 ? o.bin_width : 2.0 * mean_d;
  double r_max = 0.0;
  std::vector<double> dist(p.size());
  for (std::size_t i = 0; i < p.size(); ++i) {
    if (p.pz[i] > o.top) continue;
    const double dx = p.px[i] - o.centre[0], dy = p.py[i] - o.centre[1];
    dist[i] = o.planar ? std::abs(dx) : std::sqrt(dx * dx + dy * dy);
    r_max = std::max(r_max, dist[i]);
  }
  const auto nbins = std::size_t(r_max / w) + 1;
  std::vector<double> top(nbins, -std::numeric_limits<double>::infinity());
  for (std::size_t i = 0; i < p.size(); ++i) {
    if (p.pz[i] > o.top) continue;
    const auto b = std::size_t(dist[i] / w);
    top[b] = std::max(top[b], top_of(i));
  }
  ReposeResult res;
  // Heap radius: walk outwards until the surface is less than 1.5 diameters above the floor.
  const double toe = o.base + 1.5 * mean_d;
  std::size_t edge = 0;
  while (edge < nbins && top[edge] >= toe) ++edge;
  res.heap_radius = double(edge) * w;
  for (std::size_t b = 0; b < nbins; ++b) {
    if (!std::isfinite(top[b])) continue;
    res.bin_r.push_back((double(b) + 0.5) * w);
    res.bin_z.push_back(top[b]);
    if (b < edge) res.heap_height = std::max(res.heap_height, top[b] - o.base);
  }
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  int n = 0;
  for (std::size_t b = 0; b < edge; ++b) {
    const double rc = (double(b) + 0.5) * w;
    if (rc < o.flank_lo * res.heap_radius || rc > o.flank_hi * res.heap_radius) continue;
    sx += rc;
    sy += top[b];
    sxx += rc * rc;
    sxy += rc * top[b];
    ++n;
  }
  res.fitted_bins = n;
  if (n < 3) {
    throw std::runtime_error("angle of repose: only " + std::to_string(n) +
                             " profile bins on the heap flank (heap radius " +
                             std::to_string(res.heap_radius) + " m, bin width " +
                             std::to_string(w) + " m); the heap is too small to fit a slope");
  }
  res.slope = (n * sxy - sx * sy) / (n * sxx - sx * sx);
  res.angle_deg = std::atan(-res.slope) * 180.0 / std::numbers::pi;
  return res;
}

struct SensorSet::Entry {
  SensorSpec spec;
  std::unique_ptr<io::CsvWriter> csv;
  std::filesystem::path csv_path;
  std::unique_ptr<MassFlowCounter> counter;
  double next = 0.0;
  double last_time = -1.0;
  double cumulative = 0.0;
  std::vector<double> last;
};

namespace {
std::vector<std::string> columns_of(const SensorSpec& spec) {
  switch (spec.kind) {
    case SensorSpec::Kind::mass_flow:
      return {"time", "mass_flow", "mass_crossed"};
    case SensorSpec::Kind::wall_force:
      return {"time", "fx", "fy", "fz", "force", "pressure"};
    case SensorSpec::Kind::kinetic_energy:
      return {"time", "kinetic_energy"};
    case SensorSpec::Kind::frozen:
      return {"time", "frozen", "fx", "fy", "fz"};
    case SensorSpec::Kind::repose:
      return {"time", "angle_deg", "heap_radius", "heap_height"};
    case SensorSpec::Kind::packing:
      if (spec.contacts)
        return {"time",       "particles",         "solid_fraction",           "coordination",
                "top",        "rattlers",          "coordination_no_rattlers", "contacts",
                "force_mean", "force_above_2mean", "force_tail_decay",         "stress_zz"};
      return {"time", "particles", "solid_fraction", "coordination", "top"};
  }
  return {};
}
}  // namespace

SensorSet::SensorSet(std::vector<SensorSpec> specs, const std::filesystem::path& dir,
                     const DemSystem& system, bool create_files) {
  for (auto& s : specs) {
    if (!(s.interval > 0))
      throw std::invalid_argument("sensor '" + s.name + "': interval must be > 0");
    auto e = std::make_unique<Entry>();
    e->spec = std::move(s);
    e->next = system.time();
    if (e->spec.kind == SensorSpec::Kind::mass_flow) {
      e->counter =
          std::make_unique<MassFlowCounter>(e->spec.point, e->spec.direction, e->spec.radius);
    }
    if (e->spec.kind == SensorSpec::Kind::wall_force) {
      if (e->spec.wall < 0 || std::size_t(e->spec.wall) >= system.wall_count()) {
        throw std::invalid_argument("sensor '" + e->spec.name + "': no wall " +
                                    std::to_string(e->spec.wall));
      }
    }
    if (!dir.empty()) {
      e->csv_path = dir / ("sensor_" + e->spec.name + ".csv");
      if (create_files) {
        e->csv = std::make_unique<io::CsvWriter>(e->csv_path, columns_of(e->spec));
      }
    }
    entries_.push_back(std::move(e));
  }
}

SensorSet::~SensorSet() = default;
SensorSet::SensorSet(SensorSet&&) noexcept = default;
SensorSet& SensorSet::operator=(SensorSet&&) noexcept = default;

std::size_t SensorSet::size() const {
  return entries_.size();
}
const std::vector<double>& SensorSet::last(std::size_t i) const {
  return entries_.at(i)->last;
}

double SensorSet::next_time() const {
  double t = std::numeric_limits<double>::infinity();
  for (const auto& e : entries_) t = std::min(t, e->next);
  return t;
}

std::vector<std::size_t> SensorSet::rows() const {
  std::vector<std::size_t> r;
  for (const auto& e : entries_) r.push_back(e->csv ? e->csv->rows() : 0);
  return r;
}

void SensorSet::resume(const std::vector<std::size_t>& rows, double time) {
  for (std::size_t i = 0; i < entries_.size(); ++i) {
    auto& e = *entries_[i];
    if (!e.csv_path.empty()) {
      e.csv.reset();
      e.csv = std::make_unique<io::CsvWriter>(io::CsvWriter::resume(e.csv_path, rows.at(i)));
    }
    e.next = time;
    e.last_time = -1.0;
    if (e.counter) {
      e.counter = std::make_unique<MassFlowCounter>(e.spec.point, e.spec.direction, e.spec.radius);
    }
  }
}

std::vector<double> SensorSet::schedule() const {
  std::vector<double> s;
  for (const auto& e : entries_) {
    s.push_back(e->next);
    s.push_back(e->last_time);
  }
  return s;
}

void SensorSet::resume(const std::vector<std::size_t>& rows, double time,
                       const std::vector<double>& schedule) {
  if (schedule.size() != 2 * entries_.size()) {
    throw std::runtime_error("sensor schedule of " + std::to_string(schedule.size() / 2) +
                             " sensors for " + std::to_string(entries_.size()));
  }
  resume(rows, time);
  for (std::size_t i = 0; i < entries_.size(); ++i) {
    entries_[i]->next = schedule[2 * i];
    entries_[i]->last_time = schedule[2 * i + 1];
  }
}

std::vector<SensorSet::CounterState> SensorSet::counter_states() const {
  std::vector<CounterState> out(entries_.size());
  for (std::size_t i = 0; i < entries_.size(); ++i) {
    if (!entries_[i]->counter) continue;
    out[i].present = true;
    out[i].cumulative = entries_[i]->cumulative;
    out[i].sides = entries_[i]->counter->sides();
  }
  return out;
}

void SensorSet::restore_counter_states(const std::vector<CounterState>& states) {
  for (std::size_t i = 0; i < entries_.size() && i < states.size(); ++i) {
    if (!entries_[i]->counter || !states[i].present) continue;
    entries_[i]->cumulative = states[i].cumulative;
    entries_[i]->counter->set_sides(states[i].sides);
  }
}

void SensorSet::sample(const DemSystem& system, std::span<const std::int64_t> ids) {
  const double t = system.time();
  // A tolerance of a tenth of a step absorbs the round-off of t = n * dt.
  const double eps = 0.1 * system.settings().dt;
  for (auto& ep : entries_) {
    Entry& e = *ep;
    if (t + eps < e.next) continue;
    std::vector<double> v;
    switch (e.spec.kind) {
      case SensorSpec::Kind::mass_flow: {
        const double dm = e.counter->update(system.particles(), ids);
        e.cumulative += dm;
        // The first sample only records sides: no interval yet.
        const double rate = e.last_time >= 0 && t > e.last_time ? dm / (t - e.last_time) : 0.0;
        v = {rate, e.cumulative};
        break;
      }
      case SensorSpec::Kind::wall_force: {
        double area = e.spec.area;
        std::array<double, 3> f{};
        if (e.spec.face) {
          const auto load = system.wall_face_load(e.spec.wall, e.spec.face_direction);
          f = load.force, area = load.area;
        } else {
          f = system.wall_force(e.spec.wall);
        }
        const double mag = std::sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
        v = {f[0], f[1], f[2], mag, area > 0 ? mag / area : 0.0};
        break;
      }
      case SensorSpec::Kind::kinetic_energy:
        v = {system.kinetic_energy()};
        break;
      case SensorSpec::Kind::frozen: {
        const auto f = system.frozen_support();
        v = {static_cast<double>(system.frozen_count()), f[0], f[1], f[2]};
        break;
      }
      case SensorSpec::Kind::repose: {
        try {
          const auto r = angle_of_repose(system.particles(), e.spec.repose, particle_tops(system));
          v = {r.angle_deg, r.heap_radius, r.heap_height};
        } catch (const std::runtime_error&) {
          // No heap yet (still pouring): record NaN rather than stop the run.
          const double nan = std::numeric_limits<double>::quiet_NaN();
          v = {nan, nan, nan};
        }
        break;
      }
      case SensorSpec::Kind::packing: {
        const auto r = packing_in_box(system, e.spec.box_lo, e.spec.box_hi);
        v = {double(r.particles), r.solid_fraction, r.coordination, r.top};
        if (e.spec.contacts) {
          const auto c = contact_statistics_in_box(system, e.spec.box_lo, e.spec.box_hi);
          v.insert(v.end(),
                   {double(c.rattlers), c.coordination_no_rattlers, double(c.force.contacts),
                    c.force.mean, c.force.above_two_mean, c.force.tail_decay, c.stress_zz});
        }
        break;
      }
    }
    e.last = v;
    if (e.csv) {
      std::vector<double> row{t};
      row.insert(row.end(), v.begin(), v.end());
      e.csv->row(row);
      e.csv->flush();
    }
    e.last_time = t;
    // Next sample on the regular grid of interval multiples after t. An interval below the
    // resolution of the time (1e-300 s: next + interval == next) made this loop endless
    // (issue 19); such an interval, or a grid far behind, jumps to the first multiple after t
    // instead (a sample every step), the usual short walk keeps the grid bit for bit.
    const double after = t + eps;
    if (e.next + e.spec.interval > e.next && (after - e.next) / e.spec.interval < 1e6) {
      while (e.next <= after) e.next += e.spec.interval;
    } else {
      e.next = std::max(std::nextafter(after, INFINITY),
                        (std::floor(after / e.spec.interval) + 1.0) * e.spec.interval);
    }
  }
}

}  // namespace demfem::dem
