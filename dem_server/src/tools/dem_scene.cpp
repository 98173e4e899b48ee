#include "demfem/dem/dem_scene.hpp"
#include "demfem/dem/state_check.hpp"

#include "scene_shapes.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <ostream>
#include <sstream>

#include <sys/resource.h>
#include <unistd.h>

#include "demfem/dem/dem_output.hpp"
#include "demfem/dem/shapes/geometry/stl_reader.hpp"
#include "demfem/dem/shapes/mesh_body.hpp"
#include "demfem/dem/wall_output.hpp"
#include "demfem/io/checkpoint_file.hpp"
#include "demfem/io/h5_file.hpp"

namespace demfem::dem {

using scene::Range;
using scene::SceneError;
using scene::Table;

namespace {

std::int32_t material_index(const Table& t, std::string_view key,
                            const std::vector<Material>& materials) {
  const std::string name = t.string(key);
  for (std::size_t i = 0; i < materials.size(); ++i)
    if (materials[i].name == name) return static_cast<std::int32_t>(i);
  std::string list;
  for (const auto& m : materials) list += (list.empty() ? "\"" : ", \"") + m.name + "\"";
  t.fail(key, "names material \"" + name +
                  "\", which [[dem.materials]] does not define (defined: " + list + ")");
}

WallMotion read_motion(const Table& m) {
  WallMotion w;
  const std::string kind =
      m.choice("kind", "fixed", {"fixed", "translation", "rotation", "sinusoid"});
  w.start_time = m.number("start_time", 0.0, Range::non_negative());
  w.end_time = m.number("end_time", 1e300, Range::positive());
  if (w.end_time <= w.start_time) m.fail("end_time", "must be greater than start_time");
  auto unit = [&](std::string_view key) {
    auto a = m.vec3(key);
    const double l = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
    if (!(l > 0)) m.fail(key, "must not be the zero vector");
    return std::array<double, 3>{a[0] / l, a[1] / l, a[2] / l};
  };
  if (kind == "fixed") {
    w.kind = WallMotion::Kind::fixed;
  } else if (kind == "translation") {
    w.kind = WallMotion::Kind::translation;
    w.velocity = m.vec3("velocity");
  } else if (kind == "rotation") {
    w.kind = WallMotion::Kind::rotation;
    w.axis_point = m.vec3("axis_point");
    w.axis = unit("axis");
    w.angular_velocity = m.number("angular_velocity");
  } else {
    w.kind = WallMotion::Kind::sinusoid;
    w.axis = unit("direction");
    w.amplitude = m.number("amplitude", Range::non_negative());
    w.frequency = m.number("frequency", Range::positive());
    w.phase = m.number("phase", 0.0);
    w.velocity = m.vec3("velocity", std::array<double, 3>{0, 0, 0});
  }
  if (m.has("max_force")) {
    if (w.kind != WallMotion::Kind::translation && w.kind != WallMotion::Kind::sinusoid)
      m.fail("max_force", "limits a drift: only a translation or a sinusoid with a velocity");
    w.max_force = m.number("max_force", Range::positive());
    if (w.velocity == std::array<double, 3>{0, 0, 0})
      m.fail("max_force", "needs a non-zero velocity (the drift it limits)");
  }
  m.finish();
  return w;
}

// [dem.walls.body]: mass properties from a density (the closed mesh's, computed when the mesh
// is read) or given, constraints, applied force, initial velocities.
void read_body(const Table& b, WallSpec& ws) {
  RigidBodySpec& r = ws.body;
  r.enabled = true;
  ws.body_where = b.where(b.has("density") ? "density" : "mass");
  if (b.has("density") == b.has("mass"))
    b.fail("density",
           "a body needs exactly one of 'density' (mass properties from the closed "
           "mesh) and 'mass' (with 'inertia')");
  if (b.has("density")) {
    ws.body_density = b.number("density", Range::positive());
  } else {
    r.mass = b.number("mass", Range::positive());
    r.inertia = b.vec3("inertia", Range::positive());
    if (b.has("centre")) {
      r.centre = b.vec3("centre");
      ws.has_body_centre = true;
    }
  }
  r.velocity = b.vec3("velocity", std::array<double, 3>{0, 0, 0});
  r.angular_velocity = b.vec3("angular_velocity", std::array<double, 3>{0, 0, 0});
  r.force = b.vec3("force", std::array<double, 3>{0, 0, 0});
  r.gravity = b.boolean("gravity", true);
  if (b.has("fixed")) {
    for (const auto& f : b.strings("fixed")) {
      if (f == "x" || f == "y" || f == "z") {
        r.fix_translation[std::size_t(f[0] - 'x')] = true;
      } else if (f == "rotation") {
        r.fix_rotation = true;
      } else {
        b.fail("fixed",
               "unknown entry \"" + f + "\" (accepted: \"x\", \"y\", \"z\", \"rotation\")");
      }
    }
  }
  b.finish();
}

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

std::array<double, 3> checked_hi(const Table& t, const std::array<double, 3>& lo) {
  auto hi = t.vec3("hi");
  for (int k = 0; k < 3; ++k)
    if (!(hi[k] > lo[k])) t.fail("hi", "must be greater than 'lo' in every component");
  return hi;
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
  return total;
}

DemScene read_dem_scene(const Table& dem) {
  DemScene s;
  s.file = dem.file();
  s.overrides = dem.overrides();
  auto& st = s.settings;
  st.backend = dem.choice("backend", "cpu", {"cpu", "cuda"});
  s.backend_where = dem.where("backend");
  st.threads = static_cast<int>(dem.integer("threads", 0, 0, 4096));
  st.dt = dem.number("dt", Range::positive());
  s.dt_where = dem.where("dt");
  st.gravity = dem.vec3("gravity", std::array<double, 3>{0.0, 0.0, -9.81});
  st.skin = dem.number("skin", 0.0, Range::non_negative());
  st.list_skin = dem.number("list_skin", 0.0, Range::closed(0.0, 1.0));
  st.track_orientation = dem.boolean("track_orientation", false);
  s.settle_time = dem.number("settle_time", 0.0, Range::non_negative());
  if (dem.has("remove_above")) s.remove_above = dem.number("remove_above");
  if (auto fz = dem.table("freeze")) {
    FreezeSpec f;
    f.enabled = fz->boolean("enabled", true);
    f.time = fz->number("time", Range::non_negative());
    f.interval = fz->number("interval", 0.0, Range::non_negative());
    const Table box = fz->required_table("active");
    f.active_lo = box.vec3("lo");
    f.active_hi = box.vec3("hi");
    for (int k = 0; k < 3; ++k)
      if (!(f.active_hi[static_cast<std::size_t>(k)] > f.active_lo[static_cast<std::size_t>(k)]))
        fz->fail("active", "needs hi > lo in x, y and z (the box whose particles stay free)");
    box.finish();
    f.max_speed = fz->number("max_speed", 0.01, Range::positive());
    fz->finish();
    if (f.enabled && st.backend == "cuda")
      fz->fail("enabled", "frozen particles are held by the CPU backend only (dem.backend)");
    if (f.enabled) s.freeze = f;
  }
  if (dem.has("remove_by")) {
    if (!s.remove_above) dem.fail("remove_by", "needs remove_above (the height it applies to)");
    s.remove_by_top = dem.choice("remove_by", {"centre", "top"}) == "top";
  }

  // Materials.
  const auto mats = dem.tables("materials");
  if (mats.empty()) dem.fail("materials", "at least one [[dem.materials]] is required");
  for (const auto& m : mats) {
    Material mat;
    mat.name = m.string("name");
    if (mat.name.empty()) m.fail("name", "must not be empty");
    for (const auto& other : st.materials)
      if (other.name == mat.name) m.fail("name", "\"" + mat.name + "\" is defined twice");
    mat.youngs_modulus = m.number("youngs_modulus", Range::positive());
    mat.poisson_ratio = m.number("poisson_ratio", Range{0.0, 0.5, false, true});
    mat.density = m.number("density", 0.0, Range::non_negative());
    m.finish();
    st.materials.push_back(mat);
  }
  const std::size_t n = st.materials.size();
  st.pairs.assign(n * n, MaterialPair{});
  std::vector<std::uint8_t> given(n * n, 0);
  for (const auto& p : dem.tables("pairs")) {
    const auto a = material_index(p, "a", st.materials);
    const auto b = material_index(p, "b", st.materials);
    if (given[std::size_t(a) * n + std::size_t(b)]) {
      p.fail("b", "the pair (" + st.materials[a].name + ", " + st.materials[b].name +
                      ") is defined twice");
    }
    MaterialPair mp;
    mp.friction = p.number("friction", Range::non_negative());
    mp.restitution = p.number("restitution", Range::open_closed(0.0, 1.0));
    mp.rolling_friction = p.number("rolling_friction", 0.0, Range::non_negative());
    mp.rocking_damping = p.number("rocking_damping", 1.0, Range::closed(0.0, 10.0));
    mp.poly_law =
        poly_law_from_name(p.choice("poly_law", "pressure_centre", {"pressure_centre", "smooth"}));
    p.finish();
    st.pairs[std::size_t(a) * n + std::size_t(b)] = mp;
    st.pairs[std::size_t(b) * n + std::size_t(a)] = mp;
    given[std::size_t(a) * n + std::size_t(b)] = given[std::size_t(b) * n + std::size_t(a)] = 1;
  }

  // Walls.
  const auto walls = dem.tables("walls");
  for (std::size_t i = 0; i < walls.size(); ++i) {
    const Table& w = walls[i];
    WallSpec ws;
    ws.where = w.where("material");
    ws.name = w.string("name", "wall" + std::to_string(i));
    for (const auto& other : s.walls)
      if (other.name == ws.name) w.fail("name", "wall \"" + ws.name + "\" is defined twice");
    ws.material = material_index(w, "material", st.materials);
    const int shapes = int(w.has("stl")) + int(w.has("box")) + int(w.has("plane"));
    if (shapes != 1) {
      w.fail("stl", "a wall needs exactly one of 'stl', 'box' and 'plane' (found " +
                        std::to_string(shapes) + ")");
    }
    if (w.has("stl")) {
      ws.kind = WallSpec::Kind::stl;
      ws.stl = w.path("stl");
      ws.where = w.where("stl");
      ws.weld_tolerance = w.number("weld_tolerance", -1.0, Range::non_negative());
    } else if (auto b = w.table("box")) {
      ws.kind = WallSpec::Kind::box;
      ws.lo = b->vec3("lo");
      ws.hi = checked_hi(*b, ws.lo);
      ws.open_top = b->boolean("open_top", false);
      b->finish();
    } else if (auto pl = w.table("plane")) {
      ws.kind = WallSpec::Kind::plane;
      ws.point = pl->vec3("point");
      ws.normal = pl->vec3("normal");
      if (ws.normal == std::array<double, 3>{0, 0, 0}) pl->fail("normal", "must not be zero");
      ws.size = pl->number("size", Range::positive());
      pl->finish();
    }
    if (auto m = w.table("motion")) ws.motion = read_motion(*m);
    if (auto b = w.table("body")) {
      if (ws.motion.kind != WallMotion::Kind::fixed)
        w.fail("body", "a wall moved by its contact forces cannot also have a 'motion'");
      read_body(*b, ws);
    }
    w.finish();
    s.walls.push_back(std::move(ws));
  }

  std::vector<std::uint8_t> particle_material(n, 0);
  auto particle_density = [&](const Table& t, std::int32_t m) {
    if (!(st.materials[m].density > 0)) {
      t.fail("material", "material \"" + st.materials[m].name +
                             "\" is used for particles but has no density > 0");
    }
    particle_material[std::size_t(m)] = 1;
    return st.materials[m].density;
  };

  // Particle shapes (dilated polyhedra).
  for (const auto& t : dem.tables("shapes")) {
    ShapeSpec sp = read_shape_spec(t);
    for (const auto& other : s.shapes)
      if (other.name == sp.name) t.fail("name", "shape \"" + sp.name + "\" is defined twice");
    s.shapes.push_back(std::move(sp));
  }
  auto shape_index = [&](const Table& t) -> std::int32_t {
    if (!t.has("shape")) return -1;
    const std::string name = t.string("shape");
    std::string list;
    for (std::size_t k = 0; k < s.shapes.size(); ++k) {
      if (s.shapes[k].name == name) return static_cast<std::int32_t>(k);
      list += (list.empty() ? "\"" : ", \"") + s.shapes[k].name + "\"";
    }
    t.fail("shape",
           "names \"" + name + "\", which [[dem.shapes]] does not define" +
               (list.empty() ? std::string(" (none is defined)") : " (defined: " + list + ")"));
  };

  // Lattice fills.
  std::vector<std::string> size_keys;  // per lattice, then per insertion: where its size is set
  for (const auto& l : dem.tables("lattice")) {
    LatticeSpec ls;
    ls.where = l.where("lo");
    auto& q = ls.request;
    q.material = material_index(l, "material", st.materials);
    particle_density(l, q.material);
    q.region.lo = l.vec3("lo");
    q.region.hi = checked_hi(l, q.region.lo);
    if (!l.has("diameter") && !l.has("distribution")) {
      l.fail_missing("diameter", "or 'distribution'");
    }
    if (l.has("diameter") && l.has("distribution")) {
      l.fail("diameter", "give exactly one of 'diameter' (one size) and 'distribution'");
    }
    if (l.has("diameter")) {
      q.diameter = l.number("diameter", Range::positive());
      size_keys.push_back(l.where("diameter"));
    } else {
      q.sizes = read_distribution(l.required_table("distribution"));
      q.has_sizes = true;
      q.diameter = q.sizes.largest();
      size_keys.push_back(l.where("distribution"));
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
    if (l.has("seed")) {
      q.seed = static_cast<std::uint64_t>(l.integer("seed", 0, INT64_MAX));
      ls.has_seed = true;
    }
    q.velocity = l.vec3("velocity", std::array<double, 3>{0, 0, 0});
    q.max_count = l.integer("max_count", 0, 0, INT64_MAX);
    ls.shape = shape_index(l);
    l.finish();
    s.lattices.push_back(ls);
  }

  // Random insertions.
  for (const auto& r : dem.tables("insert")) {
    InsertSpec is;
    is.where = r.where("lo");
    auto& q = is.request;
    q.material = material_index(r, "material", st.materials);
    q.density = particle_density(r, q.material);
    q.region.lo = r.vec3("lo");
    q.region.hi = checked_hi(r, q.region.lo);
    q.sizes = read_distribution(r.required_table("distribution"));
    const bool has_count = r.has("count"), has_mass = r.has("mass");
    if (has_count == has_mass) r.fail("count", "give exactly one of 'count' and 'mass'");
    if (has_count) q.count = r.integer("count", 1, INT64_MAX);
    if (has_mass) q.mass = r.number("mass", Range::positive());
    q.velocity = r.vec3("velocity", std::array<double, 3>{0, 0, 0});
    q.max_attempts = r.integer("max_attempts", 2000, 1, INT64_MAX);
    q.accept_shortfall = r.choice("shortfall", "error", {"error", "warn"}) == "warn";
    is.shape = shape_index(r);
    is.every = r.number("every", 0.0, Range::non_negative());
    if (is.every > 0) {
      is.until = r.number("until", Range::non_negative());
    } else if (r.has("until")) {
      r.fail("until", "needs 'every' > 0 (a repeated insertion)");
    }
    if (r.has("seed")) {
      q.seed = static_cast<std::uint64_t>(r.integer("seed", 0, INT64_MAX));
      is.has_seed = true;
    }
    size_keys.push_back(r.where(has_count ? "count" : "mass"));
    r.finish();
    s.inserts.push_back(is);
  }
  check_particle_budget(s, size_keys);

  // Every pair that involves a particle material must be given: a silent default friction
  // would change results without anyone noticing.
  if (dem.has("interface_material")) {
    s.interface_material = material_index(dem, "interface_material", st.materials);
    s.interface_material_where = dem.where("interface_material");
  }
  for (std::size_t a = 0; a < n; ++a) {
    if (!particle_material[a]) continue;
    for (std::size_t b = 0; b < n; ++b) {
      bool touches = particle_material[b] || std::int32_t(b) == s.interface_material;
      for (const auto& w : s.walls) touches = touches || std::size_t(w.material) == b;
      if (touches && !given[a * n + b]) {
        dem.fail("pairs", "no [[dem.pairs]] entry for materials \"" + st.materials[a].name +
                              "\" and \"" + st.materials[b].name +
                              "\", which come into contact (particles and walls)");
      }
    }
  }

  // Sensors.
  for (const auto& t : dem.tables("sensors")) {
    SensorSpec ss;
    ss.name = t.string("name");
    if (ss.name.empty() || ss.name.find_first_of("/\\ ") != std::string::npos) {
      t.fail("name", "must be a non-empty name without spaces or slashes (it names a file)");
    }
    for (const auto& other : s.sensors)
      if (other.name == ss.name) t.fail("name", "sensor \"" + ss.name + "\" is defined twice");
    const std::string kind = t.choice(
        "kind", {"mass_flow", "wall_force", "kinetic_energy", "repose", "packing", "frozen"});
    ss.interval = t.number("interval", Range::positive());
    if (kind == "mass_flow") {
      ss.kind = SensorSpec::Kind::mass_flow;
      ss.point = t.vec3("point");
      ss.direction = t.vec3("direction", std::array<double, 3>{0, 0, -1});
      if (ss.direction == std::array<double, 3>{0, 0, 0}) t.fail("direction", "must not be zero");
      ss.radius = t.number("radius", 0.0, Range::non_negative());
    } else if (kind == "wall_force") {
      ss.kind = SensorSpec::Kind::wall_force;
      const std::string wall = t.string("wall");
      auto it = std::find_if(s.walls.begin(), s.walls.end(),
                             [&](const WallSpec& w) { return w.name == wall; });
      if (it == s.walls.end()) t.fail("wall", "names wall \"" + wall + "\", which is not defined");
      ss.wall = static_cast<std::int32_t>(it - s.walls.begin());
      if (t.has("face")) {
        ss.face = true;
        ss.face_direction = t.vec3("face");
        if (ss.face_direction == std::array<double, 3>{0, 0, 0}) t.fail("face", "must not be zero");
      }
    } else if (kind == "kinetic_energy") {
      ss.kind = SensorSpec::Kind::kinetic_energy;
    } else if (kind == "frozen") {
      ss.kind = SensorSpec::Kind::frozen;
    } else if (kind == "packing") {
      ss.kind = SensorSpec::Kind::packing;
      ss.box_lo = t.vec3("lo");
      ss.box_hi = t.vec3("hi");
      for (int k = 0; k < 3; ++k)
        if (!(ss.box_hi[k] > ss.box_lo[k])) t.fail("hi", "must exceed 'lo' in x, y and z");
    } else {
      ss.kind = SensorSpec::Kind::repose;
      auto c = t.numbers("centre", 2);
      ss.repose.centre = {c[0], c[1]};
      ss.repose.planar = t.choice("profile", "radial", {"radial", "planar"}) == "planar";
      ss.repose.base = t.number("base", 0.0);
      ss.repose.top = t.number("top", 1e300);
      if (ss.repose.top <= ss.repose.base) t.fail("top", "must be above 'base'");
      ss.repose.bin_width = t.number("bin_width", 0.0, Range::non_negative());
      if (t.has("flank")) {
        auto f = t.numbers("flank", 2, Range::closed(0.0, 1.0));
        if (!(f[1] > f[0])) t.fail("flank", "must be [lo, hi] with lo < hi");
        ss.repose.flank_lo = f[0];
        ss.repose.flank_hi = f[1];
      }
    }
    t.finish();
    s.sensors.push_back(ss);
  }

  if (auto l = dem.table("load")) s.load = read_particle_source(*l, st.materials);

  if (auto o = dem.table("output")) {
    if (o->has("interval")) s.output_interval = o->number("interval", Range::non_negative());
    s.output_particles = o->boolean("particles", true);
    s.output_walls = o->boolean("walls", true);
    s.output_state = o->boolean("state", false);
    o->finish();
  }
  dem.finish();
  return s;
}

namespace {
// The engine's body of a wall: mass properties from its closed mesh and density, or the given
// ones (centre: the mesh's volume centroid unless given; principal axes = the world axes).
RigidBodySpec body_spec(const WallSpec& w, const WallMesh& mesh) {
  RigidBodySpec r = w.body;
  try {
    const auto p = shapes::closed_mesh_properties(
        mesh.vertices, mesh.triangles, w.body_density > 0 ? w.body_density : 1.0, w.name);
    if (w.body_density > 0) {
      r.mass = p.mass;
      r.inertia = p.moments;
      r.orientation = p.orientation;
      r.centre = p.centre;
    } else if (!w.has_body_centre) {
      r.centre = p.centre;
    }
  } catch (const std::invalid_argument& e) {
    throw SceneError(w.body_where + ": " + e.what());
  }
  return r;
}
}  // namespace

DemRun::DemRun(const DemScene& scene, const std::filesystem::path& output_dir, std::uint64_t seed,
               double run_output_interval, std::ostream* log, bool defer_output)
    : DemRun(scene, output_dir, seed, run_output_interval, log, defer_output, false) {}

std::size_t DemRun::check_setup(const DemScene& scene, std::uint64_t seed) {
  const DemRun setup(scene, {}, seed, 0.0, nullptr, true, true);
  return setup.setup_particles_;
}

DemRun::DemRun(const DemScene& scene, const std::filesystem::path& output_dir, std::uint64_t seed,
               double run_output_interval, std::ostream* log, bool defer_output, bool setup_only)
    : scene_(scene), output_dir_(output_dir), run_output_interval_(run_output_interval), log_(log) {
  try {
    system_ = std::make_unique<DemSystem>(scene_.settings);
  } catch (const std::exception& e) {
    // The reader checked every value; what the engine can still refuse is the backend (CUDA
    // absent, or a feature it lacks).
    throw SceneError(scene_.backend_where + ": " + e.what());
  }
  std::vector<WallMesh> meshes;  // as added, for the checks of loaded particles
  for (auto& w : scene_.walls) {
    TriangleMesh surface;
    switch (w.kind) {
      case WallSpec::Kind::stl:
        try {
          surface = read_stl(w.stl, w.weld_tolerance);
        } catch (const StlError& e) {
          throw SceneError(w.where + ": " + e.what());
        }
        break;
      case WallSpec::Kind::box:
        surface = make_box_mesh(w.lo, w.hi, w.open_top);
        break;
      case WallSpec::Kind::plane:
        surface = make_plane_mesh(w.point, w.normal, w.size);
        break;
    }
    WallMesh mesh;
    mesh.name = w.name;
    mesh.vertices = std::move(surface.vertices);
    mesh.triangles = std::move(surface.triangles);
    mesh.material = w.material;
    mesh.motion = w.motion;
    if (w.body.enabled) mesh.body = body_spec(w, mesh);
    wall_shapes_.push_back({w.name, mesh.vertices, mesh.triangles});
    // The pressure sensors need the area of their wall.
    const double area = mesh_area(mesh.vertices, mesh.triangles);
    if (scene_.load) meshes.push_back(mesh);
    std::int32_t index = 0;
    try {
      index = system_->add_wall(std::move(mesh));
    } catch (const std::invalid_argument& e) {  // a body the engine refuses (backend, mass)
      throw SceneError((w.body.enabled ? w.body_where : w.where) + ": " + e.what());
    }
    for (auto& s : scene_.sensors)
      if (s.kind == SensorSpec::Kind::wall_force && s.wall == index) s.area = area;
  }
  for (std::size_t k = 0; k < scene_.shapes.size(); ++k) {
    libraries_.push_back(build_shape_library(scene_.shapes[k], seed, k, log));
    shape_base_.push_back(add_library_shapes(*system_, *libraries_.back(), scene_.shapes[k].name));
  }
  // A check (setup_only) of a scene whose prepare scene has not made its state yet checks
  // all but the loaded particles: `demfem run --check` checks the prepare scene itself.
  const bool state_to_come = setup_only && scene_.load && !scene_.load->prepare_scene.empty() &&
                             !state_is_current(scene_.load->file, scene_.load->prepare_scene,
                                               scene_.load->prepare_overrides);
  if (scene_.load && !state_to_come) {
    const std::size_t n = load_particles(*scene_.load, *system_, meshes, log);
    for (std::size_t i = 0; i < n; ++i) ids_.push_back(next_id_++);
  }
  const WallClearance walls = wall_clearance();
  for (std::size_t i = 0; i < scene_.lattices.size(); ++i) {
    const auto& l = scene_.lattices[i];
    LatticeFill q = l.request;
    if (!l.has_seed) q.seed = seed + kLatticeSeedOffset + i;
    if (l.shape >= 0) {
      q.library = libraries_[static_cast<std::size_t>(l.shape)].get();
      q.shape_base = shape_base_[static_cast<std::size_t>(l.shape)];
    }
    std::vector<ParticleInit> spheres;
    try {
      spheres = lattice_fill(q);
    } catch (const InsertionError& e) {
      throw SceneError(l.where + ": " + e.what());
    }
    auto sphere = [&](const ParticleInit& p) {
      std::ostringstream m;
      m << "sphere " << &p - spheres.data() << " of " << spheres.size() << " (centre ["
        << p.position[0] << ", " << p.position[1] << ", " << p.position[2] << "] m, radius "
        << p.radius << " m)";
      return m.str();
    };
    // At start, no sphere may sit in a wall (it would be thrown off it) ...
    for (const auto& p : spheres) {
      std::size_t wall = 0;
      const double depth = walls.overlap(p.position, p.radius, &wall);
      if (depth > 1e-9 * p.radius) {
        std::ostringstream m;
        m << l.where << ": " << sphere(p) << " overlaps wall '" << walls.name(wall) << "' by "
          << depth << " m: the lattice region reaches into or through the walls; move 'lo' and "
          << "'hi' inside them";
        throw SceneError(m.str());
      }
    }
    // ... nor in another lattice's sphere ...
    if (const auto j = first_overlapping(spheres, system_->particles()); j >= 0) {
      throw SceneError(l.where + ": " + sphere(spheres[std::size_t(j)]) +
                       " overlaps a sphere of an earlier [[dem.lattice]]: lattice regions must "
                       "not overlap");
    }
    // ... nor where it falls past every wall.
    for (const auto& p : spheres) {
      if (walls.falls_past(p.position, scene_.settings.gravity)) {
        check_falls_past(sphere(p), l.where);  // throws, or warns once for the entry
        break;
      }
    }
    add(spheres);
  }
  seed_ = seed;
  repeats_.assign(scene_.inserts.size(), 0);
  if (scene_.freeze) next_freeze_ = scene_.freeze->time;
  pour();  // every insertion once at t = 0
  setup_particles_ = system_->particle_count();
  if (system_->particle_count() > 0) {
    const double tr = system_->rayleigh_time_step();
    const double dt = scene_.settings.dt;
    if (log) {
      *log << "dem: " << system_->particle_count() << " particles, " << system_->wall_count()
           << " walls; Rayleigh time step " << tr << " s, dt = " << dt << " s (" << dt / tr
           << " of it)\n";
    }
    if (dt > tr) {
      std::ostringstream m;
      m << scene_.dt_where << ": dt = " << dt << " s exceeds the Rayleigh time step " << tr
        << " s (thesis eq. 2.27) of the smallest particle; the integration would be unstable. "
        << "Use dt <= " << kRayleighWarnFraction * tr << " s";
      throw SceneError(m.str());
    }
    if (dt > kRayleighWarnFraction * tr && log) {
      *log << "dem: warning: " << scene_.dt_where << ": dt is " << dt / tr
           << " of the Rayleigh time step, above the safe fraction " << kRayleighWarnFraction
           << "; collisions faster than ~0.1 m/s need a smaller dt\n";
    }
  }
  if (setup_only) return;  // check_setup(): no settling, no output
  if (scene_.settle_time > 0) {
    const auto steps =
        static_cast<std::int64_t>(std::ceil(scene_.settle_time / scene_.settings.dt));
    // in pieces of 0.01 s, each checked: a bed that blows up stops there, naming the time
    // (the same steps as one advance: the particles' bits do not depend on the pieces)
    const auto piece = std::max<std::int64_t>(1, std::llround(0.01 / scene_.settings.dt));
    for (std::int64_t done = 0; done < steps; done += piece) {
      system_->advance(std::min(piece, steps - done));
      check_stable();
    }
    if (log) *log << "dem: settled for " << steps << " steps (" << system_->time() << " s)\n";
  }
  if (scene_.remove_above) {
    const auto keep =
        keep_at_or_below(system_->particles(), *scene_.remove_above,
                         scene_.remove_by_top ? particle_tops(*system_) : std::vector<double>{});
    std::size_t removed = 0;
    std::vector<std::int64_t> kept_ids;
    for (std::size_t i = 0; i < keep.size(); ++i) {
      if (keep[i])
        kept_ids.push_back(ids_[i]);
      else
        ++removed;
    }
    if (removed > 0) {
      system_->remove_particles(keep);
      ids_ = std::move(kept_ids);
    }
    if (log)
      *log << "dem: removed " << removed << " particles "
           << (scene_.remove_by_top ? "reaching " : "") << "above z = " << *scene_.remove_above
           << " m\n";
  }
  output_interval_ = scene_.output_interval.value_or(run_output_interval_);
  if (!defer_output) start_output(false);
}

DemRun::~DemRun() = default;

void DemRun::set_next_freeze() {
  next_freeze_ = std::numeric_limits<double>::infinity();
  if (!scene_.freeze) return;
  const auto& f = *scene_.freeze;
  const double t = system_->time() + 1e-9 * scene_.settings.dt;  // done at the step end at or after
  if (f.time > t) {
    next_freeze_ = f.time;
  } else if (f.interval > 0.0) {
    next_freeze_ = f.time + (std::floor((t - f.time) / f.interval) + 1.0) * f.interval;
  }
}

void DemRun::freeze_due() {
  if (!scene_.freeze || system_->time() + 1e-9 * scene_.settings.dt < next_freeze_) return;
  const auto& f = *scene_.freeze;
  const ParticleState& p = system_->particles();
  const auto already = system_->frozen();
  std::vector<std::uint8_t> mask(p.size(), 0);
  std::size_t added = 0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    if (!already.empty() && already[i] != 0) continue;
    const bool inside = p.px[i] >= f.active_lo[0] && p.px[i] <= f.active_hi[0] &&
                        p.py[i] >= f.active_lo[1] && p.py[i] <= f.active_hi[1] &&
                        p.pz[i] >= f.active_lo[2] && p.pz[i] <= f.active_hi[2];
    if (inside) continue;
    const double v = std::sqrt(p.vx[i] * p.vx[i] + p.vy[i] * p.vy[i] + p.vz[i] * p.vz[i]);
    const double w = std::sqrt(p.wx[i] * p.wx[i] + p.wy[i] * p.wy[i] + p.wz[i] * p.wz[i]);
    if (v + w * p.radius[i] < f.max_speed) mask[i] = 1, ++added;
  }
  if (added > 0) system_->freeze(mask);
  if (log_)
    *log_ << "dem: froze " << added << " particles at t = " << system_->time() << " s ("
          << system_->frozen_count() << " of " << p.size() << " held)\n";
  set_next_freeze();
}

double DemRun::next_pour_time() const {
  double t = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < scene_.inserts.size(); ++i) {
    const auto& in = scene_.inserts[i];
    const double next = in.every > 0 ? double(repeats_[i]) * in.every : 0.0;
    if (repeats_[i] == 0 || (in.every > 0 && next <= in.until + 1e-9 * in.every)) {
      t = std::min(t, next);
    }
  }
  return t;
}

void DemRun::pour() {
  const double eps = 0.1 * scene_.settings.dt;
  const double now = system_->time();
  for (std::size_t i = 0; i < scene_.inserts.size(); ++i) {
    const auto& in = scene_.inserts[i];
    for (;;) {
      const std::int64_t k = repeats_[i];
      const double when = in.every > 0 ? double(k) * in.every : 0.0;
      const bool due = k == 0 || (in.every > 0 && when <= in.until + 1e-9 * in.every);
      if (!due || when > now + eps) break;
      RandomInsertion q = in.request;
      if (in.shape >= 0) {
        q.library = libraries_[static_cast<std::size_t>(in.shape)].get();
        q.shape_base = shape_base_[static_cast<std::size_t>(in.shape)];
      }
      const std::uint64_t base = in.has_seed ? q.seed : seed_ + i;
      // Repetition k draws from its own stream: 1000003 (prime) apart, so it never meets the
      // stream of another entry's first insertion (entries are 1 apart).
      q.seed = base + std::uint64_t(k) * 1000003u;
      // The region must lie over the walls (its corners must not fall past all of them);
      // inside it, positions that overlap a wall are drawn again.
      const WallClearance walls = wall_clearance();
      if (k == 0) {
        for (int c = 0; c < 8; ++c) {
          const std::array<double, 3> corner{c & 1 ? q.region.hi[0] : q.region.lo[0],
                                             c & 2 ? q.region.hi[1] : q.region.lo[1],
                                             c & 4 ? q.region.hi[2] : q.region.lo[2]};
          if (walls.falls_past(corner, scene_.settings.gravity)) {
            std::ostringstream m;
            m << "the region's corner [" << corner[0] << ", " << corner[1] << ", " << corner[2]
              << "] m";
            check_falls_past(m.str(), in.where);
            break;
          }
        }
      }
      auto blocked = [&walls](double x, double y, double z, double r) {
        return walls.overlap({x, y, z}, r) > 1e-9 * r;
      };
      try {
        std::string shortfall;
        add(insert_random(
            q, &system_->particles(),
            walls.empty() ? std::function<bool(double, double, double, double)>{} : blocked,
            &shortfall));
        if (!shortfall.empty() && log_) {
          *log_ << "dem: warning: " << in.where << ": " << shortfall
                << "; the run goes on with these (shortfall = \"warn\")"
                << (in.every > 0 ? " (repetition " + std::to_string(k) + ")" : std::string())
                << "\n";
        }
      } catch (const InsertionError& e) {
        std::ostringstream m;
        m << in.where << ": " << e.what();
        if (in.every > 0) m << " (repetition " << k << " at t = " << now << " s)";
        throw SceneError(m.str());
      }
      ++repeats_[i];
    }
  }
}

WallClearance DemRun::wall_clearance() const {
  std::vector<WallClearance::Wall> now = wall_shapes_;
  for (std::size_t w = 0; w < now.size(); ++w) {
    if (scene_.walls[w].motion.kind != WallMotion::Kind::fixed) {
      now[w].vertices = system_->wall_vertices(static_cast<std::int32_t>(w));
    }
  }
  return WallClearance(now);
}

void DemRun::check_falls_past(const std::string& what, const std::string& where) const {
  std::ostringstream m;
  const WallClearance walls(wall_shapes_);
  m << where << ": " << what << " lies outside the walls: carried along gravity it misses "
    << "the bounding box of all of them ([" << walls.lo()[0] << ", " << walls.lo()[1] << ", "
    << walls.lo()[2] << "] .. [" << walls.hi()[0] << ", " << walls.hi()[1] << ", " << walls.hi()[2]
    << "] m), so it would fall for ever; move 'lo' and 'hi' over the walls";
  if (scene_.interface_material < 0) throw SceneError(m.str());
  // A coupled scene: the structure, which the DEM does not know yet, may catch it.
  if (log_) *log_ << "dem: warning: " << m.str() << " (unless the coupled structure is there)\n";
}

void DemRun::start_output(bool resume) {
  sensors_ = std::make_unique<SensorSet>(scene_.sensors, output_dir_, *system_, !resume);
  if (!output_dir_.empty() && scene_.output_particles) {
    output_ = std::make_unique<ParticleOutput>(output_dir_);
    std::vector<PolyhedronShape> shapes;
    for (std::size_t k = 0; k < system_->shape_count(); ++k)
      shapes.push_back(system_->shape(static_cast<std::int32_t>(k)));
    output_->set_shapes(shapes);
    if (scene_.output_walls && !wall_shapes_.empty()) {
      std::vector<WallOutput::Wall> walls;
      for (const auto& w : wall_shapes_) walls.push_back({w.name, w.triangles});
      wall_output_ = std::make_unique<WallOutput>(output_dir_, std::move(walls));
    }
  }
  schedule_ = io::OutputSchedule(output_interval_);
  // Outputs due before the output starts (during settle_time) are not taken.
  schedule_.skip_to_after(output_clock() - 0.5 * double(chunk_steps_) * scene_.settings.dt);
  if (!resume) after_advance();  // the initial state: first sensor samples and snapshot
}

const SensorSet& DemRun::sensors() const {
  if (!sensors_) throw std::logic_error("DemRun: sensors are created by the first advance()");
  return *sensors_;
}

void DemRun::add(std::span<const ParticleInit> particles) {
  system_->add_particles(particles);
  for (std::size_t i = 0; i < particles.size(); ++i) ids_.push_back(next_id_++);
}

double DemRun::output_clock() const {
  return static_cast<double>(system_->step_count()) * scene_.settings.dt;
}

void DemRun::write_snapshot(double label) {
  if (!output_) return;
  output_->write(system_->particles(), ids_, label, system_->time());
  if (wall_output_) {
    std::vector<std::vector<double>> now(wall_shapes_.size());
    std::vector<WallOutput::Pose> poses(wall_shapes_.size());
    for (std::size_t w = 0; w < wall_shapes_.size(); ++w) {
      const auto id = static_cast<std::int32_t>(w);
      now[w] = system_->wall_vertices(id);  // moving walls and rigid bodies move
      poses[w] = {now[w], system_->wall_force(id), system_->wall_force(id)};
      // what the wall's first wall_force sensor with a face reads (a pressure cell's top)
      for (const auto& s : scene_.sensors)
        if (s.kind == SensorSpec::Kind::wall_force && s.wall == id && s.face) {
          poses[w].sensor_force = system_->wall_face_load(id, s.face_direction).force;
          break;
        }
    }
    wall_output_->write(poses, label, system_->time());
  }
  last_snapshot_step_ = system_->step_count();
}

void DemRun::write_snapshot() {
  write_snapshot(schedule_.label(output_clock(), double(chunk_steps_) * scene_.settings.dt));
}

void DemRun::finish() {
  if (output_ && last_snapshot_step_ != system_->step_count()) write_snapshot();
  write_state();
}

void DemRun::write_state() const {
  if (!scene_.output_state || output_dir_.empty()) return;
  std::filesystem::create_directories(output_dir_);
  const auto file = output_dir_ / kStateFileName;
  io::write_checkpoint_file(file, system_->step_count(), [&](io::H5File& h5) {
    save(h5, "dem");
    h5.set_attribute("/", "scene_file", scene_.file);
    h5.set_attribute("/", "scene_hash", scene_text_hash(scene_.file, scene_.overrides));
    h5.set_attribute("/", "time", system_->time());
    h5.set_attribute("/", "count", static_cast<std::int64_t>(system_->particle_count()));
  });
}

void DemRun::check_stable() const {
  const auto& radius = system_->particles().radius;
  if (radius.empty()) return;
  const double ke = system_->kinetic_energy();
  // each contact against the smaller contact radius of its two bodies (a polyhedron's:
  // its dilation, its cores intersect at an overlap of r_i + r_j)
  const double rel = system_->advance_max_relative_overlap();
  if (std::isfinite(ke) && rel <= kMaxStableOverlap) {
    // a particle far from every wall (after the overlap check: an exploded contact is
    // reported as such, with its overlap)
    const std::string away = outside_domain(*system_, ids_);
    if (away.empty()) return;
    std::ostringstream m;
    m << "DEM run stopped: " << away << " (dt = " << scene_.settings.dt << " s, "
      << scene_.dt_where << ")";
    throw Unstable(m.str());
  }
  std::ostringstream m;
  m << "DEM run unstable in the steps up to t = " << system_->time() << " s: ";
  if (!std::isfinite(ke))
    m << "the kinetic energy is " << ke << " (the particle state is no longer finite)";
  else
    m << "a contact overlapped by " << rel
      << " of the smaller contact radius of its two bodies (a sphere's radius or a "
         "polyhedron's dilation; at most "
      << kMaxStableOverlap << "); the largest overlap was " << system_->advance_max_overlap()
      << " m, the smallest contact radius in the bed " << system_->smallest_contact_radius()
      << " m; the particles' kinetic energy " << ke << " J";
  m << ". dt = " << scene_.settings.dt << " s against a Rayleigh time step of "
    << system_->rayleigh_time_step() << " s; reduce dt (" << scene_.dt_where
    << ") or the velocities of the scene where particles collide fast; where a load presses "
       "a bed at rest, the load is more than its contacts carry within this limit (a smaller "
       "load, stiffer particles or a larger dilation). The output holds the states before it.";
  throw Unstable(m.str());
}

void DemRun::after_advance() {
  check_stable();  // before anything of this state is sampled or written
  take_step_outputs();
}

void DemRun::take_step_outputs() {
  pour();
  freeze_due();
  if (!sensors_) {
    start_output(false);  // samples the current state itself
    return;
  }
  sensors_->sample(*system_, ids_);
  if (!output_) return;
  // Output k is the state at the step end nearest to k * interval (io::OutputSchedule); the
  // first snapshot is the initial state, also with interval 0 (then only it and the end).
  const double t = output_clock();
  const double step = double(chunk_steps_) * scene_.settings.dt;
  if (output_->count() == 0 || schedule_.due(t, step)) write_snapshot(schedule_.take(t, step));
}

void DemRun::start_deferred_output() {
  if (!sensors_) start_output(false);
}

void DemRun::advance(std::int64_t substeps, ForceMode mode) {
  start_deferred_output();
  system_->advance(substeps, mode);
  chunk_steps_ = std::max<std::int64_t>(substeps, 1);  // a coupling step, when coupled
  after_advance();
}

void DemRun::advance_tentative(std::int64_t substeps, ForceMode mode) {
  start_deferred_output();
  held_back_ = false;
  system_->advance(substeps, mode);
  chunk_steps_ = std::max<std::int64_t>(substeps, 1);
  check_stable();
  held_back_ = true;
}

void DemRun::accept_step() {
  if (!held_back_) return;
  held_back_ = false;
  take_step_outputs();
}

void DemRun::take_save_point() {
  accept_step();
  system_->save_state(save_point_);
}

void DemRun::restore_save_point() {
  held_back_ = false;
  system_->restore_state(save_point_);
}

void DemRun::run_to(double end_time, const std::function<void(double)>& progress) {
  start_deferred_output();
  const double dt = scene_.settings.dt;
  while (system_->time() + 0.5 * dt < end_time) {
    double target = std::min({end_time, sensors_->next_time(), next_pour_time(), next_freeze_});
    if (output_ && schedule_.active())
      target = std::min(target, schedule_.nominal(schedule_.next()));
    auto steps = static_cast<std::int64_t>(std::llround((target - system_->time()) / dt));
    steps = std::max<std::int64_t>(steps, 1);
    system_->advance(steps);
    chunk_steps_ = 1;  // any step end can take an output: pieces end on the output times
    after_advance();
    if (progress) progress(system_->time());
  }
  finish();
}

void DemRun::save(io::H5File& file, const std::string& group) const {
  system_->save(file, group);
  const std::string g = group + "_tools";
  file.create_group(g);
  file.write(g + "/ids", std::span<const std::int64_t>(ids_));
  // Before the first advance() (deferred output) no row has been written yet.
  const auto rows =
      sensors_ ? sensors_->rows() : std::vector<std::size_t>(scene_.sensors.size(), 0);
  std::vector<std::int64_t> r(rows.begin(), rows.end());
  r.push_back(0);  // never empty
  file.write(g + "/sensor_rows", std::span<const std::int64_t>(r));
  // The sensors' schedule, so that a restored run samples at the same step ends.
  std::vector<double> sched = sensors_ ? sensors_->schedule() : std::vector<double>{};
  sched.push_back(0.0);  // never empty
  file.write(g + "/sensor_schedule", std::span<const double>(sched));
  // Mass-flow counters: the cumulative mass and the side of every particle id.
  if (sensors_) {
    const auto states = sensors_->counter_states();
    for (std::size_t i = 0; i < states.size(); ++i) {
      if (!states[i].present) continue;
      std::vector<std::uint8_t> sides;
      for (std::int8_t v : states[i].sides) sides.push_back(static_cast<std::uint8_t>(v + 1));
      sides.push_back(1);  // never empty
      const std::string name = g + "/mass_flow_" + std::to_string(i);
      file.write(name + "_sides", std::span<const std::uint8_t>(sides), {sides.size()});
      file.set_attribute(g, "mass_flow_" + std::to_string(i) + "_cumulative", states[i].cumulative);
    }
  }
  file.set_attribute(g, "next_id", next_id_);
  file.set_attribute(g, "setup_particles", static_cast<std::int64_t>(setup_particles_));
  file.set_attribute(g, "snapshots", static_cast<std::int64_t>(output_ ? output_->count() : 0));
  file.set_attribute(g, "wall_snapshots",
                     static_cast<std::int64_t>(wall_output_ ? wall_output_->count() : 0));
  // The output schedule: the next output index and the step of the last snapshot, so that a
  // restored run takes the same states with the same labels.
  const std::vector<std::int64_t> sched_out{schedule_.next(), last_snapshot_step_, chunk_steps_};
  file.write(g + "/output_schedule", std::span<const std::int64_t>(sched_out));
  std::vector<std::int64_t> reps = repeats_;
  reps.push_back(0);  // never empty
  file.write(g + "/insert_repeats", std::span<const std::int64_t>(reps));
}

void DemRun::restore(const io::H5File& file, const std::string& group) {
  held_back_ = false;  // a held-back step is not part of the restored state
  const std::string g = group + "_tools";
  // The scene must be the one the checkpoint was taken with, as far as the particles go: a
  // changed lattice or insertion would be silently replaced by the checkpoint's particles.
  if (file.exists(g) && file.has_attribute(g, "setup_particles")) {
    const auto saved = file.attribute_int64(g, "setup_particles");
    if (saved != static_cast<std::int64_t>(setup_particles_)) {
      throw std::runtime_error(
          file.path().string() + ": the checkpoint's scene made " + std::to_string(saved) +
          " particles at set-up, this scene (" + scene_.file + ") makes " +
          std::to_string(setup_particles_) +
          " ([[dem.lattice]], [[dem.insert]] or run.seed changed); its state cannot be "
          "continued with this scene: resume with the scene it was taken with, or start afresh");
    }
  }
  system_->restore(file, group);
  check_particle_state(system_->particles(), file.path().string() + ":/" + group);
  ids_ = file.read_int64(g + "/ids");
  if (ids_.size() != system_->particle_count()) {
    throw std::runtime_error(file.path().string() + ": " + g + "/ids has " +
                             std::to_string(ids_.size()) + " entries for " +
                             std::to_string(system_->particle_count()) + " particles");
  }
  next_id_ = file.attribute_int64(g, "next_id");
  if (!sensors_) start_output(true);
  auto r = file.read_int64(g + "/sensor_rows");
  r.pop_back();
  if (r.size() != scene_.sensors.size()) {
    throw std::runtime_error(file.path().string() + ": " + g + " has " + std::to_string(r.size()) +
                             " sensor series, the scene " + std::to_string(scene_.sensors.size()));
  }
  std::vector<std::size_t> rows(r.begin(), r.end());
  std::vector<double> sched;
  if (file.exists(g + "/sensor_schedule")) {  // absent in checkpoints of older versions
    sched = file.read_doubles(g + "/sensor_schedule");
    sched.pop_back();
  }
  if (sched.size() == 2 * rows.size() && !rows.empty()) {
    sensors_->resume(rows, system_->time(), sched);
  } else {
    sensors_->resume(rows, system_->time());
  }
  {
    auto states = sensors_->counter_states();
    for (std::size_t i = 0; i < states.size(); ++i) {
      const std::string name = g + "/mass_flow_" + std::to_string(i);
      if (!states[i].present || !file.exists(name + "_sides")) continue;
      auto sides = file.read_uint8(name + "_sides");
      sides.pop_back();
      states[i].sides.clear();
      for (std::uint8_t v : sides) states[i].sides.push_back(static_cast<std::int8_t>(v) - 1);
      states[i].cumulative =
          file.attribute_double(g, "mass_flow_" + std::to_string(i) + "_cumulative");
    }
    sensors_->restore_counter_states(states);
  }
  if (output_) output_->resume(static_cast<std::size_t>(file.attribute_int64(g, "snapshots")));
  // A state saved before walls were written has no count: their series starts again.
  if (wall_output_)
    wall_output_->resume(file.has_attribute(g, "wall_snapshots")
                             ? static_cast<std::size_t>(file.attribute_int64(g, "wall_snapshots"))
                             : 0);
  if (file.exists(g + "/output_schedule")) {
    const auto o = file.read_int64(g + "/output_schedule");
    if (o.size() != 3)
      throw std::runtime_error(file.path().string() + ": " + g +
                               "/output_schedule must have 3 entries");
    schedule_.set_next(o[0]);
    last_snapshot_step_ = o[1];
    chunk_steps_ = std::max<std::int64_t>(o[2], 1);
  } else {  // a checkpoint of an older version: outputs up to the restored time were taken
    schedule_.skip_to_after(output_clock());
    last_snapshot_step_ = -1;
  }
  auto reps = file.read_int64(g + "/insert_repeats");
  reps.pop_back();
  if (reps.size() != repeats_.size()) {
    throw std::runtime_error(file.path().string() + ": " + g + " has " +
                             std::to_string(reps.size()) + " insertion counters, the scene " +
                             std::to_string(repeats_.size()));
  }
  repeats_ = reps;
  set_next_freeze();  // the freezings up to the restored time were done (the mask is state)
}

}  // namespace demfem::dem
