#include "demfem/dem/run/dem_run.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <ostream>
#include <sstream>

#include "demfem/dem/placement/insertion.hpp"
#include "demfem/dem/placement/state_check.hpp"
#include "demfem/dem/run/dem_output.hpp"
#include "demfem/dem/run/wall_output.hpp"
#include "demfem/dem/sensors/sensors.hpp"
#include "demfem/dem/shapes/geometry/stl_reader.hpp"
#include "demfem/dem/shapes/mesh_body.hpp"
#include "demfem/dem/shapes/shape_library.hpp"
#include "scene/scene_shapes.hpp"

namespace demfem::dem {

using scene::SceneError;

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

std::unique_ptr<const DemRun> DemRun::setup(const DemScene& scene, std::uint64_t seed) {
  return std::unique_ptr<const DemRun>(new DemRun(scene, {}, seed, 0.0, nullptr, true, true));
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
  place_packs(walls, seed);
  seed_ = seed;
  repeats_.assign(scene_.inserts.size(), 0);
  if (scene_.freeze) next_freeze_ = scene_.freeze->time;
  pour();  // every insertion once at t = 0
  setup_particles_ = system_->particle_count();
  check_periods();
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
      for (int d = 0; d < 3; ++d) {  // the seam: images of the particles on the other side
        q.period[d] = scene_.settings.periodic.period(d);
        q.period_lo[d] = scene_.settings.periodic.lo[d];
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

void DemRun::check_periods() const {
  const PeriodicRange& r = scene_.settings.periodic;
  const double least = system_->least_period();
  for (int d = 0; d < 3; ++d) {
    if (!r.on[d] || r.period(d) >= least) continue;
    std::ostringstream m;
    m << scene_.periodic_where[d] << ": the period " << r.period(d)
      << " m is shorter than twice the neighbour list's cutoff, 2 (2 r_max + skin) = " << least
      << " m, for the particles of this scene (a pair would meet two images of the other); "
      << "use a range of at least " << least << " m";
    throw SceneError(m.str());
  }
}

void DemRun::write_snapshot(double label) {
  if (!output_) return;
  const std::span<const std::int32_t> image = system_->images();
  if (scene_.output_unwrapped && !image.empty()) {
    // periodic: x + n L, the path each particle took (docs/scene_dem.md, [dem.output])
    ParticleState p = system_->particles();
    std::vector<double>* x[3] = {&p.px, &p.py, &p.pz};
    for (int d = 0; d < 3; ++d) {
      const double L = scene_.settings.periodic.period(d);
      for (std::size_t i = 0; L > 0.0 && i < p.size(); ++i) (*x[d])[i] += image[3 * i + d] * L;
    }
    output_->write(p, ids_, label, system_->time());
  } else {
    output_->write(system_->particles(), ids_, label, system_->time());
  }
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

// Where the guard's overlap is: the deepest contact of the state the run stopped in, by
// particle (its index, its id in the output, its centre) and the particle or walls it
// touches. Empty where none is found (the CUDA backend).
std::string DemRun::deepest_contact_text() const {
  const DeepestContact c = system_->deepest_contact();
  if (!(c.relative > 0.0)) return {};
  const ParticleState& p = system_->particles();
  auto particle = [&](std::int64_t i) {
    std::ostringstream m;
    m << "particle " << i;
    if (static_cast<std::size_t>(i) < ids_.size()) m << " (id " << ids_[i] << " in the output)";
    m << " at [" << p.px[i] << ", " << p.py[i] << ", " << p.pz[i] << "] m";
    return m.str();
  };
  std::ostringstream m;
  m << "; the deepest contact after the step, " << c.relative << " of its contact radius ("
    << c.depth << " m): " << particle(c.particle) << " and ";
  if (c.other >= 0) {
    m << particle(c.other);
  } else {
    m << (c.walls.size() == 1 ? "the wall " : "the walls ");
    for (std::size_t k = 0; k < c.walls.size(); ++k) m << (k ? ", '" : "'") << c.walls[k] << "'";
  }
  return m.str();
}

void DemRun::check_stable() const {
  const auto& radius = system_->particles().radius;
  if (radius.empty()) return;
  const double ke = system_->kinetic_energy();
  // each contact against the smaller contact radius of its two bodies (a polyhedron's:
  // its dilation, its cores intersect at an overlap of r_i + r_j)
  const double rel = system_->advance_max_relative_overlap();
  if (std::isfinite(ke) && rel <= scene_.guard_overlap) {
    // a particle far from every wall (after the overlap check: an exploded contact is
    // reported as such, with its overlap)
    const std::string away = outside_domain(*system_, ids_);
    if (away.empty()) return;
    std::ostringstream m;
    m << "DEM run stopped: " << away << " (dt = " << scene_.settings.dt << " s, " << scene_.dt_where
      << ")";
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
      << scene_.guard_overlap << ", " << scene_.guard_overlap_where
      << "); the largest overlap was " << system_->advance_max_overlap()
      << " m, the smallest contact radius in the bed " << system_->smallest_contact_radius()
      << " m; the particles' kinetic energy " << ke << " J" << deepest_contact_text();
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

}  // namespace demfem::dem
