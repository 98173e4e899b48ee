#include "demfem/dem/placement/insertion.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <sstream>
#include <stdexcept>
#include <unordered_map>
#include <vector>

#include "demfem/dem/physics/grid_cell.hpp"
#include "demfem/dem/shapes/shape_library.hpp"

namespace demfem::dem {

std::string Box::describe() const {
  std::ostringstream s;
  s << "box [" << lo[0] << ", " << hi[0] << "] x [" << lo[1] << ", " << hi[1] << "] x [" << lo[2]
    << ", " << hi[2] << "] m";
  return s.str();
}

double sphere_mass(double diameter, double density) {
  return density * std::numbers::pi / 6.0 * diameter * diameter * diameter;
}

PolyhedronShape engine_shape(const shapes::ParticleShape& shape, std::string name) {
  PolyhedronShape e;
  e.name = std::move(name);
  for (const auto& v : shape.core.vertices())
    e.vertices.insert(e.vertices.end(), v.begin(), v.end());
  for (const auto& t : shape.core.triangles())
    e.triangles.insert(e.triangles.end(), t.begin(), t.end());
  e.dilation = shape.dilation_radius;
  e.volume = shape.volume;
  e.inertia = {shape.principal_moments[0], shape.principal_moments[1], shape.principal_moments[2]};
  return e;
}

std::int32_t add_library_shapes(DemSystem& system, const shapes::ShapeLibrary& library,
                                const std::string& name) {
  std::int32_t first = -1;
  for (std::size_t k = 0; k < library.size(); ++k) {
    const std::int32_t id =
        system.add_shape(engine_shape(library.unit(k), name + "[" + std::to_string(k) + "]"));
    if (k == 0) first = id;
  }
  return first;
}

std::array<double, 4> random_orientation(Rng& rng) {
  // Shoemake (Graphics Gems III): uniform on the unit quaternions
  const double u1 = rng.uniform(), u2 = rng.uniform(), u3 = rng.uniform();
  const double a = std::sqrt(1.0 - u1), b = std::sqrt(u1);
  const double t2 = 2.0 * std::numbers::pi * u2, t3 = 2.0 * std::numbers::pi * u3;
  return {b * std::cos(t3), a * std::sin(t2), a * std::cos(t2), b * std::sin(t3)};
}

namespace {

/// Uniform grid of sphere indices over the region (padded by the largest radius): dense while
/// it has at most kMaxDenseCells cells, else hashed (only the cells that hold spheres exist).
/// The dense grid of 200 spheres of 0.2 mm in a 1 m box, or of 10 mm spheres in a 100 m box,
/// had 10^11 to 10^12 cells (bad_alloc, exit 134); the hashed one holds as many cells as
/// spheres. Both answer overlaps() alike, so the insertion does not depend on the choice.
class SphereGrid {
 public:
  static constexpr double kMaxDenseCells = 1 << 22;  // 100 MB of empty cell lists at most

  SphereGrid(const Box& box, double cell) : lo_(box.lo), cell_(cell) {
    double total = 1.0;
    for (int k = 0; k < 3; ++k) {
      const double cells = std::max(1.0, std::ceil((box.hi[k] - box.lo[k]) / cell));
      if (!(cells < 1e15))  // beyond what a cell coordinate holds (a region of 1e300 m)
        throw InsertionError("the region of " + std::to_string(box.hi[k] - box.lo[k]) +
                             " m is too large for particles of " + std::to_string(cell) +
                             " m (more than 10^15 of them along one axis)");
      n_[k] = static_cast<std::int64_t>(cells);
      total *= cells;
    }
    dense_ = total <= kMaxDenseCells;
    if (dense_) cells_.resize(std::size_t(n_[0] * n_[1] * n_[2]));
  }
  void add(double x, double y, double z, double r) {
    const auto id = static_cast<std::int32_t>(r_.size());
    x_.push_back(x);
    y_.push_back(y);
    z_.push_back(z);
    r_.push_back(r);
    const std::array<std::int64_t, 3> c{coord(x, 0), coord(y, 1), coord(z, 2)};
    if (dense_)
      cells_[index(c[0], c[1], c[2])].push_back(id);
    else
      hashed_[c].push_back(id);
  }
  /// True when a sphere (x, y, z, r) overlaps a stored one; stored radii are <= cell / 2 and
  /// r <= cell / 2, so the 27 neighbouring cells hold every candidate.
  bool overlaps(double x, double y, double z, double r) const {
    const std::int64_t cx = coord(x, 0), cy = coord(y, 1), cz = coord(z, 2);
    for (std::int64_t i = std::max<std::int64_t>(0, cx - 1); i <= std::min(n_[0] - 1, cx + 1); ++i)
      for (std::int64_t j = std::max<std::int64_t>(0, cy - 1); j <= std::min(n_[1] - 1, cy + 1);
           ++j)
        for (std::int64_t k = std::max<std::int64_t>(0, cz - 1); k <= std::min(n_[2] - 1, cz + 1);
             ++k) {
          const std::vector<std::int32_t>* in = nullptr;
          if (dense_) {
            in = &cells_[index(i, j, k)];
          } else if (const auto it = hashed_.find({i, j, k}); it != hashed_.end()) {
            in = &it->second;
          }
          if (in == nullptr) continue;
          for (std::int32_t s : *in) {
            const double dx = x - x_[s], dy = y - y_[s], dz = z - z_[s], rr = r + r_[s];
            if (dx * dx + dy * dy + dz * dz < rr * rr) return true;
          }
        }
    return false;
  }

 private:
  struct CellHash {
    std::size_t operator()(const std::array<std::int64_t, 3>& c) const {
      std::uint64_t h = 1469598103934665603ull;  // FNV-1a over the three coordinates
      for (const std::int64_t v : c) h = (h ^ static_cast<std::uint64_t>(v)) * 1099511628211ull;
      return static_cast<std::size_t>(h);
    }
  };
  std::int64_t coord(double v, int k) const {
    return std::clamp<std::int64_t>(phys::saturated_cell((v - lo_[k]) / cell_), 0, n_[k] - 1);
  }
  std::size_t index(std::int64_t i, std::int64_t j, std::int64_t k) const {
    return std::size_t((i * n_[1] + j) * n_[2] + k);
  }
  std::array<double, 3> lo_;
  double cell_;
  std::array<std::int64_t, 3> n_{};
  bool dense_ = true;
  std::vector<std::vector<std::int32_t>> cells_;
  std::unordered_map<std::array<std::int64_t, 3>, std::vector<std::int32_t>, CellHash> hashed_;
  std::vector<double> x_, y_, z_, r_;
};

}  // namespace

std::vector<ParticleInit> insert_random(
    const RandomInsertion& q, const ParticleState* existing,
    const std::function<bool(double, double, double, double)>& blocked, std::string* shortfall) {
  q.sizes.validate();
  const bool by_count = q.count > 0;
  if (by_count == (q.mass > 0)) {
    throw InsertionError("random insertion needs exactly one of a count and a mass");
  }
  if (!(q.density > 0)) throw InsertionError("random insertion needs a density > 0");
  // Polyhedra are placed by their bounding spheres: a library shape k at size s has the
  // bounding radius s b_k (b_k at size 1 m); bmax = max b_k, b3 = mean b_k^3.
  const shapes::ShapeLibrary* lib = q.library;
  double bmax = 0.5, b3 = 0.125, vmean = std::numbers::pi / 6.0;
  if (lib) {
    if (lib->size() == 0) throw InsertionError("random insertion: the shape library is empty");
    bmax = b3 = vmean = 0.0;
    for (std::size_t k = 0; k < lib->size(); ++k) {
      const double b = lib->unit(k).bounding_radius;
      bmax = std::max(bmax, b);
      b3 += b * b * b / double(lib->size());
      vmean += lib->unit(k).volume / double(lib->size());
    }
  }
  const double d_max = 2.0 * bmax * q.sizes.largest();  // the largest bounding diameter
  std::ostringstream asked;
  if (by_count) {
    asked << q.count << " particles";
  } else {
    asked << q.mass << " kg";
  }
  asked << " (" << q.sizes.describe() << ") in " << q.region.describe();
  for (int k = 0; k < 3; ++k) {
    if (!(q.region.hi[k] - q.region.lo[k] >= d_max)) {
      throw InsertionError("cannot insert " + asked.str() + ": the region is narrower than the " +
                           std::string(lib ? "largest bounding diameter " : "largest diameter ") +
                           std::to_string(d_max) + " m");
    }
  }
  // Up-front check of the solid fraction asked for, so an impossible request fails at once
  // with a reason instead of after millions of attempts.
  // (polyhedra: the fraction of their bounding spheres, which are what is placed)
  const double mean_volume = vmean * q.sizes.mean_cube();
  if (!(mean_volume > 0) || !std::isfinite(mean_volume)) {
    // d = 1e-300 m: a mass target would never be reached (each particle weighs 0).
    throw InsertionError("cannot insert " + asked.str() + ": the " +
                         std::string(lib ? "rocks'" : "spheres'") +
                         " volume is not a positive number in double precision "
                         "(sizes too small or too large)");
  }
  const double solid = by_count ? double(q.count) * mean_volume : q.mass / q.density;
  const double bounding = 4.0 / 3.0 * std::numbers::pi * b3 * q.sizes.mean_cube();
  const double fraction = solid / q.region.volume() * (lib ? bounding / mean_volume : 1.0);
  if (fraction > kMaxRandomPackingFraction) {
    std::ostringstream s;
    s << "cannot insert " << asked.str() << ": it needs a solid fraction of about " << fraction
      << (lib ? " (of bounding spheres)" : "") << " of the region, more than the "
      << kMaxRandomPackingFraction
      << " that random non-overlapping insertion reaches; enlarge the region, or insert in "
         "stages with settling in between";
    throw InsertionError(s.str());
  }

  // Grid cell = largest diameter present, so neighbours lie in the 27 surrounding cells.
  double cell = d_max;
  Box padded = q.region;
  std::vector<std::size_t> nearby;
  if (existing) {
    for (std::size_t i = 0; i < existing->size(); ++i) {
      const double r = existing->radius[i];
      const double x = existing->px[i], y = existing->py[i], z = existing->pz[i];
      if (x + r < q.region.lo[0] || x - r > q.region.hi[0] || y + r < q.region.lo[1] ||
          y - r > q.region.hi[1] || z + r < q.region.lo[2] || z - r > q.region.hi[2])
        continue;
      nearby.push_back(i);
      cell = std::max(cell, 2.0 * r);
    }
  }
  for (int k = 0; k < 3; ++k) {
    padded.lo[k] -= cell;
    padded.hi[k] += cell;
  }
  SphereGrid grid(padded, cell);
  for (std::size_t i : nearby) {
    grid.add(existing->px[i], existing->py[i], existing->pz[i], existing->radius[i]);
  }

  // Periodic directions: a region spanning the period draws centres over all of it, and a
  // place must be free of the particles' images one period away (images[] lists the shifts
  // to try, 0 first; a spanning region lies within the grid's padding of both ends).
  std::array<double, 3> lo = q.region.lo, hi = q.region.hi, inset{1.0, 1.0, 1.0};
  std::vector<std::array<double, 3>> images{{0.0, 0.0, 0.0}};
  for (int k = 0; k < 3; ++k) {
    const double L = q.period[k];
    if (!(L > 0.0)) continue;
    if (lo[k] <= q.period_lo[k] && hi[k] >= q.period_lo[k] + L) {
      lo[k] = q.period_lo[k], hi[k] = q.period_lo[k] + L, inset[k] = 0.0;
    }
    const std::size_t m = images.size();
    for (std::size_t e = 0; e < m; ++e)
      for (double s : {-L, L}) {
        auto shifted = images[e];
        shifted[k] = s;
        images.push_back(shifted);
      }
  }
  auto overlaps = [&](double x, double y, double z, double r) {
    for (const auto& s : images)
      if (grid.overlaps(x + s[0], y + s[1], z + s[2], r)) return true;
    return false;
  };
  Rng rng(q.seed);
  std::vector<ParticleInit> out;
  double placed_mass = 0.0;
  auto done = [&] {
    return by_count ? std::int64_t(out.size()) >= q.count : placed_mass >= q.mass;
  };
  while (!done()) {
    shapes::ScaledShape shp;
    double d, r;
    if (lib) {
      shp = lib->sample(rng, q.sizes);
      d = shp.scale;
      r = shp.bounding_radius;
    } else {
      d = q.sizes.sample(rng);
      r = 0.5 * d;
    }
    bool ok = false;
    for (std::int64_t a = 0; a < q.max_attempts && !ok; ++a) {
      const double x = rng.uniform(lo[0] + inset[0] * r, hi[0] - inset[0] * r);
      const double y = rng.uniform(lo[1] + inset[1] * r, hi[1] - inset[1] * r);
      const double z = rng.uniform(lo[2] + inset[2] * r, hi[2] - inset[2] * r);
      if (overlaps(x, y, z, r) || (blocked && blocked(x, y, z, r))) continue;
      grid.add(x, y, z, r);
      ParticleInit p;
      p.position = {x, y, z};
      p.velocity = q.velocity;
      p.radius = r;
      p.material = q.material;
      if (lib) {
        p.shape = ParticleShape::polyhedron;
        p.shape_id = q.shape_base + static_cast<std::int32_t>(shp.shape);
        p.scale = shp.scale;
        p.orientation = random_orientation(rng);
        placed_mass += q.density * shp.volume;
      } else {
        placed_mass += sphere_mass(d, q.density);
      }
      out.push_back(p);
      ok = true;
    }
    if (!ok) {
      std::ostringstream s;
      s << "cannot insert " << asked.str() << ": placed only " << out.size() << " particles ("
        << placed_mass << " kg, solid fraction " << placed_mass / q.density / q.region.volume()
        << ") before particle " << out.size() + 1 << " found no free place in " << q.max_attempts
        << " attempts";
      if (!q.accept_shortfall) {
        s << "; enlarge the region or insert in stages";
        throw InsertionError(s.str());
      }
      if (shortfall) *shortfall = s.str();
      break;
    }
  }
  // Store the particles in cell order (z, then y, then x; cell = largest diameter), not in the
  // random order they were placed: the pair loop reads the state of each particle's
  // neighbours, and neighbours close in memory share cache lines. A stable sort keeps the
  // result deterministic.
  auto cell_of = [&](const ParticleInit& p) {
    std::array<std::int64_t, 3> c{};
    for (int k = 0; k < 3; ++k)
      c[k] = static_cast<std::int64_t>(std::floor((p.position[k] - q.region.lo[k]) / d_max));
    return std::array<std::int64_t, 3>{c[2], c[1], c[0]};
  };
  std::stable_sort(out.begin(), out.end(), [&](const ParticleInit& a, const ParticleInit& b) {
    return cell_of(a) < cell_of(b);
  });
  return out;
}

namespace {

// The sites of a lattice fill: centre distance a, first centre `inset` inside the box, n sites
// per axis (in double: a typo can ask for more than an integer holds).
struct LatticeLayout {
  double a = 0.0;
  double inset = 0.0;
  std::array<double, 3> n{};
  double count() const { return n[0] * n[1] * n[2]; }
};

// Bounding diameter per unit size: 1 for spheres, 2 max b_k for a shape library.
double lattice_bound(const LatticeFill& q) {
  if (!q.library) return 1.0;
  if (q.library->size() == 0) throw InsertionError("lattice fill: the shape library is empty");
  double bmax = 0.0;
  for (std::size_t k = 0; k < q.library->size(); ++k)
    bmax = std::max(bmax, q.library->unit(k).bounding_radius);
  return 2.0 * bmax;
}

LatticeLayout layout(const LatticeFill& q) {
  if (!(q.diameter > 0)) throw InsertionError("lattice fill needs a diameter > 0");
  // polyhedra: the bounding diameter of the largest library shape at the size plays the
  // diameter's part
  const double bd = lattice_bound(q) * q.diameter;
  LatticeLayout l;
  l.a = q.spacing > 0 ? q.spacing : 1.001 * bd;
  if (l.a < bd) {
    throw InsertionError("lattice spacing " + std::to_string(l.a) + " m is below the " +
                         std::string(q.library ? "largest bounding diameter " : "diameter ") +
                         std::to_string(bd) + " m: the " + (q.library ? "particles" : "spheres") +
                         " would overlap");
  }
  if (!(q.jitter >= 0.0 && q.jitter < 1.0)) {
    throw InsertionError("lattice jitter " + std::to_string(q.jitter) + " is outside [0, 1)");
  }
  // A sphere of diameter d moves up to jitter (a - d) / 2 from its site: its far side is at most
  // (1 - jitter) d / 2 + jitter a / 2 away, largest for the largest diameter.
  l.inset = 0.5 * bd + 0.5 * q.jitter * (l.a - bd);
  for (int k = 0; k < 3; ++k) {
    const double free = q.region.hi[k] - q.region.lo[k] - 2.0 * l.inset;
    l.n[k] = free < 0 ? 0.0 : std::floor(free / l.a + 1e-9) + 1.0;
  }
  return l;
}

}  // namespace

double lattice_count(const LatticeFill& q) {
  const double n = layout(q).count();
  return q.max_count > 0 ? std::min(n, double(q.max_count)) : n;
}

double expected_count(const RandomInsertion& q) {
  if (q.count > 0) return double(q.count);
  const double mean_mass = q.density * std::numbers::pi / 6.0 * q.sizes.mean_cube();
  if (!(q.mass > 0)) return 0.0;
  // Spheres so small that their mass underflows to 0 (d = 1e-300 m) would never make up the
  // mass: unbounded (the budget check refuses it; insertion would loop for ever).
  return mean_mass > 0 ? std::ceil(q.mass / mean_mass) : INFINITY;
}

std::vector<ParticleInit> lattice_fill(const LatticeFill& q) {
  const LatticeLayout l = layout(q);
  if (l.count() == 0) {
    throw InsertionError("lattice fill of " + q.region.describe() + " with diameter " +
                         std::to_string(lattice_bound(q) * q.diameter) + " m: not one " +
                         (q.library ? "particle" : "sphere") + " fits");
  }
  if (lattice_count(q) > kMaxParticles) {
    std::ostringstream s;
    s << "lattice fill of " << q.region.describe() << " with diameter " << q.diameter
      << " m asks for " << lattice_count(q) << " spheres, more than the " << kMaxParticles
      << " a DEM system holds";
    throw InsertionError(s.str());
  }
  if (q.has_sizes) q.sizes.validate();
  const auto n =
      std::array<std::int64_t, 3>{std::int64_t(l.n[0]), std::int64_t(l.n[1]), std::int64_t(l.n[2])};
  Rng rng(q.seed);
  std::vector<ParticleInit> out;
  for (std::int64_t k = 0; k < n[2]; ++k)
    for (std::int64_t j = 0; j < n[1]; ++j)
      for (std::int64_t i = 0; i < n[0]; ++i) {
        if (q.max_count > 0 && std::int64_t(out.size()) >= q.max_count) return out;
        // Draws in a fixed order per sphere (diameter, then x, y, z), so a seed gives the
        // same bed on any platform; none without a distribution and jitter.
        const double d = q.has_sizes ? std::min(q.sizes.sample(rng), q.diameter) : q.diameter;
        ParticleInit p;
        p.position = {q.region.lo[0] + l.inset + double(i) * l.a,
                      q.region.lo[1] + l.inset + double(j) * l.a,
                      q.region.lo[2] + l.inset + double(k) * l.a};
        const double bd = lattice_bound(q) * d;
        if (q.jitter > 0) {
          const double amplitude = 0.5 * q.jitter * (l.a - bd);
          for (double& c : p.position) c += amplitude * (2.0 * rng.uniform() - 1.0);
        }
        p.velocity = q.velocity;
        p.radius = 0.5 * d;
        p.material = q.material;
        if (q.library) {  // then a shape and an orientation
          const auto shape = q.library->pick(rng);
          const auto sc = q.library->scaled(shape, d);
          p.shape = ParticleShape::polyhedron;
          p.shape_id = q.shape_base + static_cast<std::int32_t>(shape);
          p.scale = sc.scale;
          p.radius = sc.bounding_radius;
          p.orientation = random_orientation(rng);
        }
        out.push_back(p);
      }
  return out;
}

std::int64_t first_overlapping(const std::vector<ParticleInit>& added,
                               const ParticleState& existing) {
  if (added.empty() || existing.size() == 0) return -1;
  Box box{{added[0].position}, {added[0].position}};
  double cell = 0.0;
  for (const auto& p : added) {
    for (std::size_t k = 0; k < 3; ++k) {
      box.lo[k] = std::min(box.lo[k], p.position[k] - p.radius);
      box.hi[k] = std::max(box.hi[k], p.position[k] + p.radius);
    }
    cell = std::max(cell, 2.0 * p.radius);
  }
  std::vector<std::size_t> nearby;
  for (std::size_t i = 0; i < existing.size(); ++i) {
    const double r = existing.radius[i];
    if (existing.px[i] + r < box.lo[0] || existing.px[i] - r > box.hi[0] ||
        existing.py[i] + r < box.lo[1] || existing.py[i] - r > box.hi[1] ||
        existing.pz[i] + r < box.lo[2] || existing.pz[i] - r > box.hi[2])
      continue;
    nearby.push_back(i);
    cell = std::max(cell, 2.0 * r);
  }
  if (nearby.empty()) return -1;
  for (std::size_t k = 0; k < 3; ++k) box.lo[k] -= cell, box.hi[k] += cell;
  SphereGrid grid(box, cell);
  for (std::size_t i : nearby) {
    // shrunk by 1e-9: spheres that only touch do not count
    grid.add(existing.px[i], existing.py[i], existing.pz[i], existing.radius[i] * (1 - 1e-9));
  }
  for (std::size_t i = 0; i < added.size(); ++i) {
    const auto& p = added[i];
    if (grid.overlaps(p.position[0], p.position[1], p.position[2], p.radius * (1 - 1e-9)))
      return std::int64_t(i);
  }
  return -1;
}

std::vector<std::uint8_t> keep_at_or_below(const ParticleState& particles, double height,
                                           std::span<const double> tops) {
  if (!tops.empty() && tops.size() != particles.size())
    throw std::logic_error("keep_at_or_below: one top per particle expected");
  std::vector<std::uint8_t> keep(particles.size());
  for (std::size_t i = 0; i < keep.size(); ++i)
    keep[i] = (tops.empty() ? particles.pz[i] : tops[i]) <= height ? 1 : 0;
  return keep;
}

std::size_t remove_above(DemSystem& system, double height) {
  const auto keep = keep_at_or_below(system.particles(), height);
  const auto removed = static_cast<std::size_t>(std::count(keep.begin(), keep.end(), 0));
  if (removed > 0) system.remove_particles(keep);
  return removed;
}

}  // namespace demfem::dem
