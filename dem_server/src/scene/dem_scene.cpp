#include "demfem/dem/scene/dem_scene.hpp"

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "scene_sections.hpp"
#include "scene_shapes.hpp"

namespace demfem::dem {

using scene::Range;
using scene::Table;

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

std::array<double, 3> checked_hi(const Table& t, const std::array<double, 3>& lo) {
  auto hi = t.vec3("hi");
  for (int k = 0; k < 3; ++k)
    if (!(hi[k] > lo[k])) t.fail("hi", "must be greater than 'lo' in every component");
  return hi;
}

namespace {

// The engine's settings ([dem] itself: backend, threads, dt, gravity, skins), the settling
// and the removal above a height, [dem.freeze].
void read_settings(const Table& dem, DemScene& s) {
  auto& st = s.settings;
  st.backend = dem_backend_from_name(dem.choice("backend", "cpu", {"cpu", "cuda"}));
  s.backend_where = dem.where("backend");
  st.threads = static_cast<int>(dem.integer("threads", 0, 0, 4096));
  st.dt = dem.number("dt", Range::positive());
  s.dt_where = dem.where("dt");
  s.guard_overlap = dem.number("guard_overlap", kMaxStableOverlap,
                               Range::open_closed(0.0, kMaxGuardOverlap));
  s.guard_overlap_where = dem.where("guard_overlap");
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
    if (f.enabled) s.freeze = f;
  }
  if (dem.has("remove_by")) {
    if (!s.remove_above) dem.fail("remove_by", "needs remove_above (the height it applies to)");
    s.remove_by_top = dem.choice("remove_by", {"centre", "top"}) == "top";
  }
}

// [[dem.materials]] and [[dem.pairs]] into st; returns which pairs were given (n x n).
std::vector<std::uint8_t> read_materials(const Table& dem, DemSettings& st) {
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
  return given;
}

// [[dem.shapes]]: the shape libraries that fills and insertions name.
void read_shapes(const Table& dem, DemScene& s) {
  for (const auto& t : dem.tables("shapes")) {
    ShapeSpec sp = read_shape_spec(t);
    for (const auto& other : s.shapes)
      if (other.name == sp.name) t.fail("name", "shape \"" + sp.name + "\" is defined twice");
    s.shapes.push_back(std::move(sp));
  }
}

// Every pair that involves a particle material must be given: a silent default friction
// would change results without anyone noticing.
void check_pairs_given(const Table& dem, const DemScene& s, const std::vector<std::uint8_t>& given,
                       const std::vector<std::uint8_t>& particle_materials) {
  const std::size_t n = s.settings.materials.size();
  for (std::size_t a = 0; a < n; ++a) {
    if (!particle_materials[a]) continue;
    for (std::size_t b = 0; b < n; ++b) {
      bool touches = particle_materials[b] || std::int32_t(b) == s.interface_material;
      for (const auto& w : s.walls) touches = touches || std::size_t(w.material) == b;
      if (touches && !given[a * n + b]) {
        dem.fail("pairs", "no [[dem.pairs]] entry for materials \"" + s.settings.materials[a].name +
                              "\" and \"" + s.settings.materials[b].name +
                              "\", which come into contact (particles and walls)");
      }
    }
  }
}

// [dem.output]: what the run writes, and how often.
void read_output(const Table& dem, DemScene& s) {
  if (auto o = dem.table("output")) {
    if (o->has("interval")) s.output_interval = o->number("interval", Range::non_negative());
    s.output_particles = o->boolean("particles", true);
    s.output_walls = o->boolean("walls", true);
    s.output_state = o->boolean("state", false);
    s.output_unwrapped = o->choice("positions", "wrapped", {"wrapped", "unwrapped"}) == "unwrapped";
    o->finish();
  }
}

}  // namespace

DemScene read_dem_scene(const Table& dem) {
  DemScene s;
  s.file = dem.file();
  s.overrides = dem.overrides();
  read_settings(dem, s);
  const std::vector<std::uint8_t> given = read_materials(dem, s.settings);
  read_periodic(dem, s);
  s.walls = read_walls(dem, s.settings.materials);
  check_periodic_walls(s);
  read_shapes(dem, s);
  const FillKeys fills = read_fills(dem, s);
  if (dem.has("interface_material")) {
    s.interface_material = material_index(dem, "interface_material", s.settings.materials);
    s.interface_material_where = dem.where("interface_material");
  }
  check_pairs_given(dem, s, given, fills.particle_materials);
  s.sensors = read_sensors(dem, s.walls);
  if (auto l = dem.table("load")) s.load = read_particle_source(*l, s.settings.materials);
  read_output(dem, s);
  dem.finish();
  return s;
}

}  // namespace demfem::dem
