// [[dem.lattice]], [[dem.insert]] and [[dem.pack]]: the particle fills of a scene, read in the
// order of the scene, and the up-front check that the particles they ask for can be held.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <sstream>
#include <string>
#include <vector>

#include <sys/resource.h>
#include <unistd.h>

#include "scene_sections.hpp"

namespace demfem::dem {

using scene::Range;
using scene::SceneError;
using scene::Table;

namespace {

SizeDistribution read_distribution(const Table& d) {
  const std::string kind = d.choice("kind", {"constant", "uniform", "normal", "gradation"});
  SizeDistribution s;
  try {
    if (kind == "constant") {
      s = SizeDistribution::constant(d.number("diameter", Range::positive()));
    } else if (kind == "uniform") {
      const double lo = d.number("d_min", Range::positive());
      const double hi = d.number("d_max", Range::positive());
      if (hi < lo) d.fail("d_max", "must be >= d_min");
      s = SizeDistribution::uniform(lo, hi);
    } else if (kind == "normal") {
      const double mean = d.number("mean", Range::positive());
      const double sd = d.number("stddev", Range::positive());
      const double lo = d.number("d_min", Range::positive());
      const double hi = d.number("d_max", Range::positive());
      if (hi < lo) d.fail("d_max", "must be >= d_min");
      s = SizeDistribution::normal(mean, sd, lo, hi);
    } else {
      auto sieves = d.numbers("sieves", 0, Range::positive());
      auto fractions = d.numbers("mass_fractions", 0, Range::closed(0, 1));
      if (fractions.size() + 1 != sieves.size()) {
        d.fail("mass_fractions",
               "needs one entry per sieve class: " + std::to_string(sieves.size() - 1) + " for " +
                   std::to_string(sieves.size()) + " sieve sizes, found " +
                   std::to_string(fractions.size()));
      }
      s = SizeDistribution::gradation(std::move(sieves), std::move(fractions));
    }
  } catch (const std::invalid_argument& e) {
    d.fail("kind", e.what());
  }
  d.finish();
  return s;
}

// An entry's own `seed` in [0, 2^63 - 1], when it has one (its draws then do not follow
// run.seed): true and `seed` set, else false and `seed` untouched.
bool read_seed(const Table& t, std::uint64_t& seed) {
  if (!t.has("seed")) return false;
  seed = static_cast<std::uint64_t>(t.integer("seed", 0, INT64_MAX));
  return true;
}

// The density of a particle material (which must have one); notes that particles use it.
double particle_density(const Table& t, std::int32_t m, const std::vector<Material>& materials,
                        FillKeys& keys) {
  if (!(materials[m].density > 0)) {
    t.fail("material",
           "material \"" + materials[m].name + "\" is used for particles but has no density > 0");
  }
  keys.particle_materials[std::size_t(m)] = 1;
  return materials[m].density;
}

// The [[dem.shapes]] entry that `t` names by 'shape'; -1 (spheres) when it names none.
std::int32_t shape_index(const Table& t, const std::vector<ShapeSpec>& shapes) {
  if (!t.has("shape")) return -1;
  const std::string name = t.string("shape");
  std::string list;
  for (std::size_t k = 0; k < shapes.size(); ++k) {
    if (shapes[k].name == name) return static_cast<std::int32_t>(k);
    list += (list.empty() ? "\"" : ", \"") + shapes[k].name + "\"";
  }
  t.fail("shape",
         "names \"" + name + "\", which [[dem.shapes]] does not define" +
             (list.empty() ? std::string(" (none is defined)") : " (defined: " + list + ")"));
}

// What a lattice, an insertion and a pack read alike, in this order (the first bad key is
// the one an error names): the particle material into `q.material` and the region lo .. hi
// into `q.region`. Returns the material's density.
template <class FillRequest>
double read_material_and_region(const Table& t, const DemScene& s, FillKeys& keys,
                                FillRequest& q) {
  q.material = material_index(t, "material", s.settings.materials);
  const double density = particle_density(t, q.material, s.settings.materials, keys);
  q.region.lo = t.vec3("lo");
  q.region.hi = checked_hi(t, q.region.lo);
  return density;
}

LatticeSpec read_lattice(const Table& l, const DemScene& s, FillKeys& keys) {
  LatticeSpec ls;
  ls.where = l.where("lo");
  auto& q = ls.request;
  read_material_and_region(l, s, keys, q);
  if (!l.has("diameter") && !l.has("distribution")) {
    l.fail_missing("diameter", "or 'distribution'");
  }
  if (l.has("diameter") && l.has("distribution")) {
    l.fail("diameter", "give exactly one of 'diameter' (one size) and 'distribution'");
  }
  if (l.has("diameter")) {
    q.diameter = l.number("diameter", Range::positive());
    keys.size_keys.push_back(l.where("diameter"));
  } else {
    q.sizes = read_distribution(l.required_table("distribution"));
    q.has_sizes = true;
    q.diameter = q.sizes.largest();
    keys.size_keys.push_back(l.where("distribution"));
  }
  q.spacing = l.number("spacing", 0.0, Range::non_negative());
  if (q.spacing > 0 && q.spacing < q.diameter) {
    l.fail("spacing", q.has_sizes ? "must be >= the largest diameter of the distribution, " +
                                        std::to_string(q.diameter) + " m (or 0)"
                                  : std::string("must be >= diameter (or 0)"));
  }
  q.jitter = l.number("jitter", 0.0, Range{0.0, 1.0, false, true});
  const double a = q.spacing > 0 ? q.spacing : 1.001 * q.diameter;
  if (q.jitter > 0 && !q.has_sizes && a - q.diameter < 0.01 * q.diameter) {
    std::ostringstream m;
    m << "moves each sphere within its gap to the next site, and the spacing " << a
      << " m leaves a gap of " << a - q.diameter << " m (" << (a - q.diameter) / q.diameter
      << " of the diameter): give 'spacing' >= 1.01 x diameter, e.g. 1.2 x diameter = "
      << 1.2 * q.diameter << " m";
    l.fail("jitter", m.str());
  }
  ls.has_seed = read_seed(l, q.seed);
  q.velocity = l.vec3("velocity", std::array<double, 3>{0, 0, 0});
  q.max_count = l.integer("max_count", 0, 0, INT64_MAX);
  ls.shape = shape_index(l, s.shapes);
  l.finish();
  return ls;
}

InsertSpec read_insert(const Table& r, const DemScene& s, FillKeys& keys) {
  InsertSpec is;
  is.where = r.where("lo");
  auto& q = is.request;
  q.density = read_material_and_region(r, s, keys, q);
  q.sizes = read_distribution(r.required_table("distribution"));
  const bool has_count = r.has("count"), has_mass = r.has("mass");
  if (has_count == has_mass) r.fail("count", "give exactly one of 'count' and 'mass'");
  if (has_count) q.count = r.integer("count", 1, INT64_MAX);
  if (has_mass) q.mass = r.number("mass", Range::positive());
  q.velocity = r.vec3("velocity", std::array<double, 3>{0, 0, 0});
  q.max_attempts = r.integer("max_attempts", 2000, 1, INT64_MAX);
  q.accept_shortfall = r.choice("shortfall", "error", {"error", "warn"}) == "warn";
  is.shape = shape_index(r, s.shapes);
  is.every = r.number("every", 0.0, Range::non_negative());
  if (is.every > 0) {
    is.until = r.number("until", Range::non_negative());
  } else if (r.has("until")) {
    r.fail("until", "needs 'every' > 0 (a repeated insertion)");
  }
  is.has_seed = read_seed(r, q.seed);
  keys.size_keys.push_back(r.where(has_count ? "count" : "mass"));
  r.finish();
  return is;
}

PackSpec read_pack(const Table& k, const DemScene& s, FillKeys& keys) {
  PackSpec ps;
  ps.where = k.where("count");
  auto& q = ps.request;
  read_material_and_region(k, s, keys, q);
  q.sizes = read_distribution(k.required_table("distribution"));
  q.count = k.integer("count", 1, INT64_MAX);
  // 1: bounding spheres touching; up to 2 leaves a gap as wide as a particle
  q.gap_factor = k.number("gap_factor", 1.001, Range::closed(1.0, 2.0));
  const std::string method = k.choice("method", "mixed", {"mixed", "layers", "rows"});
  q.method = method == "rows"     ? PackedFill::Method::rows
             : method == "layers" ? PackedFill::Method::layers
                                  : PackedFill::Method::mixed;
  q.velocity = k.vec3("velocity", std::array<double, 3>{0, 0, 0});
  ps.has_seed = read_seed(k, q.seed);
  ps.shape = shape_index(k, s.shapes);
  keys.size_keys.push_back(ps.where);
  k.finish();
  return ps;
}

double repetitions(const InsertSpec& in) {
  return in.every > 0 ? std::floor(in.until / in.every + 1e-9) + 1.0 : 1.0;
}

std::string format_bytes(double b) {
  std::ostringstream s;
  s.precision(3);
  if (b >= 1e12)
    s << b / 1e12 << " TB";
  else if (b >= 1e9)
    s << b / 1e9 << " GB";
  else
    s << b / 1e6 << " MB";
  return s.str();
}

// Refuses, up front, a scene whose particles cannot be held: more than a DEM system indexes,
// or more memory than the machine has. `keys` names, per lattice then per insertion, the key
// that sets its size.
void check_particle_budget(const DemScene& s, const std::vector<std::string>& keys) {
  std::vector<double> counts;
  for (const auto& l : s.lattices) {
    try {
      counts.push_back(lattice_count(l.request));
    } catch (const InsertionError&) {
      counts.push_back(0.0);  // refused with its own message when it is filled
    }
  }
  for (const auto& in : s.inserts) counts.push_back(expected_count(in.request) * repetitions(in));
  for (const auto& p : s.packs) counts.push_back(static_cast<double>(p.request.count));
  double total = 0.0;
  std::size_t largest = 0;
  for (std::size_t i = 0; i < counts.size(); ++i) {
    total += counts[i];
    if (counts[i] > counts[largest]) largest = i;
  }
  const std::string excess = particle_budget_excess(total);
  if (excess.empty()) return;
  std::ostringstream m;
  m.precision(3);
  if (!std::isfinite(total)) {
    m << keys[largest]
      << ": the scene asks for more particles than can be counted (spheres so small that their "
         "volume is 0 in double precision); use larger particles";
    throw SceneError(m.str());
  }
  m << keys[largest] << ": the scene asks for about " << total << " particles (" << counts[largest]
    << " from this entry), " << excess << "; use larger particles, a smaller region, or fewer "
    << "of them";
  throw SceneError(m.str());
}

}  // namespace

FillKeys read_fills(const Table& dem, DemScene& s) {
  FillKeys keys;
  keys.particle_materials.assign(s.settings.materials.size(), 0);
  for (const auto& l : dem.tables("lattice")) s.lattices.push_back(read_lattice(l, s, keys));
  for (const auto& r : dem.tables("insert")) s.inserts.push_back(read_insert(r, s, keys));
  for (const auto& k : dem.tables("pack")) s.packs.push_back(read_pack(k, s, keys));
  check_particle_budget(s, keys.size_keys);
  return keys;
}

std::string particle_budget_excess(double count) {
  const double bytes = count * kBytesPerParticle;
  const double pages = static_cast<double>(sysconf(_SC_PHYS_PAGES));
  double memory = pages * static_cast<double>(sysconf(_SC_PAGE_SIZE));
  // a limit on this process's address space (ulimit -v, a batch job's) counts too
  rlimit as{};
  const bool limited = getrlimit(RLIMIT_AS, &as) == 0 && as.rlim_cur != RLIM_INFINITY &&
                       !(memory > 0 && static_cast<double>(as.rlim_cur) >= memory);
  if (limited) memory = static_cast<double>(as.rlim_cur);
  std::ostringstream m;
  m.precision(3);
  if (count > kMaxParticles)
    m << "more than the " << std::int64_t(kMaxParticles)
      << " a DEM system can index (32-bit particle indices)";
  else if (memory > 0 && bytes > memory)
    m << "about " << format_bytes(bytes) << " of memory at " << kBytesPerParticle / 1024
      << " kB per particle, more than "
      << (limited ? "this process's address-space limit (ulimit -v) of " : "this machine's ")
      << format_bytes(memory);
  return m.str();
}

double estimated_particle_count(const DemScene& s) {
  double total = 0.0;
  for (const auto& l : s.lattices) total += lattice_count(l.request);
  for (const auto& in : s.inserts) total += expected_count(in.request) * repetitions(in);
  for (const auto& p : s.packs) total += static_cast<double>(p.request.count);
  return total;
}

}  // namespace demfem::dem
