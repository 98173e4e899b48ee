#pragma once
// The [dem] section of a scene (docs/scene_dem.md lists every key) and DemRun, which builds a
// DemSystem from it (walls, lattice fills, random insertion, settling, removal above a
// height) and carries the sensors and particle output along as the system advances.

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <iosfwd>
#include <limits>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "demfem/dem/dem_system.hpp"
#include "demfem/dem/insertion.hpp"
#include "demfem/dem/particle_source.hpp"
#include "demfem/dem/sensors.hpp"
#include "demfem/dem/wall_clearance.hpp"
#include "demfem/io/output_schedule.hpp"
#include "demfem/scene/scene_reader.hpp"

namespace demfem::dem {

namespace shapes {
class ShapeLibrary;
}

/// @brief One [[dem.walls]] entry.
struct WallSpec {
  enum class Kind { stl, box, plane };
  Kind kind = Kind::stl;
  std::string name;
  std::filesystem::path stl;  ///< stl: resolved path
  double weld_tolerance = -1.0;
  std::array<double, 3> lo{}, hi{};                ///< box
  bool open_top = false;                           ///< box
  std::array<double, 3> point{}, normal{0, 0, 1};  ///< plane
  double size = 0.0;                               ///< plane
  std::int32_t material = 0;
  WallMotion motion;
  /// [dem.walls.body]: a rigid body moved by its contact forces. Mass properties come from
  /// the closed mesh and body_density (> 0), or are given (body.mass, body.inertia, and the
  /// centre unless has_body_centre is false: then the mesh's volume centroid).
  RigidBodySpec body;
  double body_density = 0.0;
  bool has_body_centre = false;
  std::string body_where;
  std::string where;  ///< file:line of the entry, for errors found later (bad STL)
};

/// @brief One [[dem.shapes]] entry: a family of dilated polyhedra (a shape library).
struct ShapeSpec {
  enum class Kind { random_rock, stl, box, cube, tetrahedron, octahedron, prism, sphere };
  Kind kind = Kind::random_rock;
  std::string name;
  std::int64_t count = 20;          ///< random_rock: shapes in the library
  int triangles = 30;               ///< random_rock
  double elongation = 1.0;          ///< random_rock: I / L
  double flatness = 1.0;            ///< random_rock: S / I
  bool has_seed = false;            ///< false: run seed + entry index
  std::uint64_t seed = 1;           ///< random_rock
  std::vector<std::filesystem::path> stl;  ///< stl: the scanned rocks (one shape each)
  std::array<double, 3> aspect{1.0, 1.0, 1.0};  ///< box: side ratios; prism: [1, h/a, -]
  bool volume_equivalent = false;   ///< size: volume-equivalent diameter (else sieve size)
  double dilation = 0.1;            ///< r_d as a fraction of the size, (0, 0.5)
  std::string where;                ///< file:line: key of the entry, for errors found later
};

/// @brief One [[dem.insert]] entry (material index and density resolved).
struct InsertSpec {
  RandomInsertion request;
  std::int32_t shape = -1;  ///< index into DemScene::shapes, -1 = spheres
  bool has_seed = false;  ///< false: seed = run seed + entry index
  double every = 0.0;     ///< > 0: repeated every this many seconds (a pour), s
  double until = 0.0;     ///< last time of a repetition, s
  std::string where;
};

/// @brief One [[dem.lattice]] entry.
struct LatticeSpec {
  LatticeFill request;
  std::int32_t shape = -1;  ///< index into DemScene::shapes, -1 = spheres
  bool has_seed = false;    ///< false: seed = run seed + kLatticeSeedOffset + entry index
  std::string where;
};

/// @brief Default seed of lattice entry i: run.seed + kLatticeSeedOffset + i (a prime offset,
/// so no lattice shares the stream of an insertion: those are run.seed + i + 1000003 k).
inline constexpr std::uint64_t kLatticeSeedOffset = 500009;

/// @brief Memory a DEM particle takes, for the up-front size check: 1.57 kB were measured
/// per sphere of a lattice bed in a box (CPU backend, neighbour lists and contact histories
/// included; docs/scene_dem.md); 2 kB leaves room for denser random packings.
inline constexpr double kBytesPerParticle = 2048.0;

/// @brief [dem.freeze]: particles outside a box around what matters that have come to rest
/// are held there (DemSystem::freeze), at `time` and every `interval` after it.
struct FreezeSpec {
  bool enabled = true;
  double time = 0.0;                               ///< s: the first freezing
  double interval = 0.0;                           ///< s: later ones (0: only the first)
  std::array<double, 3> active_lo{}, active_hi{};  ///< centres in this box are never frozen, m
  double max_speed = 0.01;  ///< m/s: frozen when |v| + |omega| r (r: bounding radius) is below
};

/// @brief Everything [dem] says.
struct DemScene {
  std::string file;
  std::vector<scene::Override> overrides;  ///< --set overrides of the scene (its state's hash)
  DemSettings settings;
  std::string dt_where;       ///< file:line: key 'dem.dt', for the Rayleigh check
  std::string backend_where;  ///< file:line: key 'dem.backend', for an unavailable backend
  std::vector<WallSpec> walls;
  std::vector<ShapeSpec> shapes;
  std::vector<LatticeSpec> lattices;
  std::vector<InsertSpec> inserts;
  double settle_time = 0.0;               ///< s of settling after insertion (before remove_above)
  std::optional<double> remove_above;     ///< m
  bool remove_by_top = false;             ///< remove_by = "top": the particle's highest point
  std::vector<SensorSpec> sensors;        ///< wall_force: wall = index into walls
  std::optional<double> output_interval;  ///< [dem.output] interval (else the run's)
  bool output_particles = true;
  bool output_walls = true;              ///< [dem.output] walls: with the particle snapshots
  bool output_state = false;             ///< [dem.output] state: write dem_state.h5 at the end
  std::optional<ParticleSource> load;    ///< [dem.load]: particles from a file, loaded first
  std::optional<FreezeSpec> freeze;      ///< [dem.freeze] (enabled)
  std::int32_t interface_material = -1;  ///< -1: not given
  std::string interface_material_where;
};

/// @brief Reads and checks [dem] (a Table from the scene's root: root.required_table("dem")).
/// Every table's finish() is called; errors are scene::SceneError naming file, line, key.
/// A scene that asks for more particles than a DEM system holds (kMaxParticles) or than this
/// machine's memory holds at kBytesPerParticle each is refused here, naming the entry that
/// asks for the most, before anything is allocated.
DemScene read_dem_scene(const scene::Table& dem);

/// @brief Why `count` particles cannot be held (more than kMaxParticles, or more than this
/// machine's memory at kBytesPerParticle each), as the end of a sentence; empty when they can.
std::string particle_budget_excess(double count);

/// @brief The particle count a [dem] section asks for up front (lattices, insertions with
/// their repetitions; an insertion by mass counts its mass over the mean particle mass).
double estimated_particle_count(const DemScene& scene);

/// @brief Rayleigh time-step check (eq. 2.27): error above 1, warning above this fraction.
inline constexpr double kRayleighWarnFraction = 0.2;

/// @brief A DEM system built from a scene, with stable particle ids, sensors and output.
/// @brief Largest overlap a DEM run accepts, as a fraction of the smaller contact radius of
/// the two bodies in contact (a sphere's radius, a polyhedron's dilation; at a wall, the
/// particle's): phys::relative_overlap. A Hertz contact of a well-resolved run stays at a few
/// per cent; half a radius means the spheres pass through each other. Each contact is judged
/// by its own bodies: 3 mm between two rocks of 10 mm dilation is 0.3, even where the bed's
/// smallest rock has 6 mm.
inline constexpr double kMaxStableOverlap = 0.5;

/// @brief The run became unstable (DemRun::check_stable): a blow-up, not a failure.
class Unstable : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class DemRun {
 public:
  /// Builds the system: walls, lattice fills (seed: the entry's, or `seed` +
  /// kLatticeSeedOffset + entry index), random insertions (seed: the entry's seed, or `seed` +
  /// entry index), settle_time of settling, remove_above. The particles placed are checked
  /// against the walls (WallClearance): a lattice sphere that overlaps a wall or another
  /// particle is a SceneError naming the entry; so is a lattice sphere or an insertion region
  /// corner that falls past every wall (under gravity; only a warning in a scene with an
  /// interface material, whose structure may catch it); random insertion avoids the walls.
  /// Prints the Rayleigh time
  /// step to `log` (may be nullptr) and warns when dt > 0.2 of it; throws SceneError (naming
  /// dem.dt) when dt exceeds it. `output_dir` empty = no files. With `defer_output` no file
  /// is touched until the first advance() (then created afresh, with the initial state) or
  /// restore() (then the checkpoint's series are continued): a restarted server must not
  /// truncate the series it is about to resume.
  DemRun(const DemScene& scene, const std::filesystem::path& output_dir, std::uint64_t seed,
         double run_output_interval, std::ostream* log, bool defer_output = false);
  ~DemRun();

  /// The checks dem_server makes when it starts, without running anything: builds the
  /// backend, the walls (reading their STL files), the lattice fills and the insertions at
  /// t = 0 and checks dem.dt against the Rayleigh time step, then drops it all (no settling,
  /// no file). For a launcher that checks a whole scene before any process starts. Throws
  /// SceneError naming file, line and key. Returns the particle count of that set-up.
  static std::size_t check_setup(const DemScene& scene, std::uint64_t seed);
  /// Particles the scene's set-up made (lattices and insertions at t = 0, before settling and
  /// removal). Saved in checkpoints: restore() refuses a checkpoint of a scene that made
  /// another number (a changed [[dem.lattice]] or [[dem.insert]]).
  std::size_t setup_particles() const { return setup_particles_; }
  /// DemSystem::set_cancel_flag of the system.
  void set_cancel_flag(const std::atomic<bool>* flag) { system_->set_cancel_flag(flag); }

  DemSystem& system() { return *system_; }
  const DemSystem& system() const { return *system_; }
  std::span<const std::int64_t> ids() const { return ids_; }
  /// The sensors (created by the constructor, or by the first advance()/restore() when
  /// deferred).
  const SensorSet& sensors() const;
  const DemScene& scene() const { return scene_; }

  /// advance(substeps) of the system, then the sensors and output that are due.
  void advance(std::int64_t substeps, ForceMode mode = ForceMode::last_substep);
  /// An iterated coupling step (implicit coupling): advance() whose insertions, sensor
  /// samples and snapshots wait for accept_step(), so that a step that is redone from
  /// restore_save_point() leaves no trace of its earlier tries. The stability check runs at
  /// once, as in advance().
  void advance_tentative(std::int64_t substeps, ForceMode mode = ForceMode::last_substep);
  /// The held-back part of advance_tentative() (insertions, samples, snapshots), for the state
  /// it reached; does nothing when no step is held back.
  void accept_step();
  /// Keeps the system's state in memory (DemSystem::save_state) to return to with
  /// restore_save_point(); the tools' state needs no copy, since a held-back step has not
  /// touched it. Accepts a held-back step first.
  void take_save_point();
  void restore_save_point();
  /// Advances to `end_time` in pieces that end on the sensor and output times;
  /// `progress(time)` is called after each piece.
  void run_to(double end_time, const std::function<void(double)>& progress = {});
  /// Writes a particle snapshot of the current state now (no-op without output), labelled as
  /// io::OutputSchedule::label says.
  void write_snapshot();
  /// The end state: a snapshot unless the last one is of the current time, and the state
  /// file when [dem.output] state asks for it.
  void finish();
  /// Writes <output>/dem_state.h5 (particle_source.hpp) when [dem.output] state asks for it.
  void write_state() const;
  /// Sensor samples and snapshot due at the current time.
  void after_advance();
  /// Throws Unstable naming the time, the deepest contact's overlap against its own radii,
  /// the largest overlap in m, dt and the Rayleigh time step when the state is not finite or
  /// two bodies overlap by more than kMaxStableOverlap of the smaller contact radius of the
  /// two (the soft contact no longer resolves them: dt too large for the stiffness, or loads
  /// beyond it). Called by after_advance(), so that no such state is sampled or written.
  void check_stable() const;
  /// Starts deferred output now (initial sensor samples and snapshot), as the first
  /// advance() would; does nothing when it has started.
  void start_deferred_output();

  /// Checkpoint: the system (DemSystem::save into `group`) and the tools' state (ids, output
  /// and sensor row counts) into `group` + "_tools".
  void save(io::H5File& file, const std::string& group) const;
  /// Restores a checkpoint of save(); refuses (std::runtime_error naming the file) a state
  /// that fails check_particle_state (state_check.hpp) or whose scene made another number of
  /// particles at set-up.
  void restore(const io::H5File& file, const std::string& group);

 private:
  DemRun(const DemScene& scene, const std::filesystem::path& output_dir, std::uint64_t seed,
         double run_output_interval, std::ostream* log, bool defer_output, bool setup_only);

  DemScene scene_;
  std::unique_ptr<DemSystem> system_;
  std::size_t setup_particles_ = 0;
  std::vector<std::int64_t> ids_;
  std::int64_t next_id_ = 0;
  std::unique_ptr<SensorSet> sensors_;
  std::unique_ptr<class ParticleOutput> output_;
  std::unique_ptr<class WallOutput> wall_output_;  ///< with output_, when there are walls
  double output_interval_ = 0.0;
  io::OutputSchedule schedule_;           ///< particle snapshots at k * output_interval_
  std::int64_t last_snapshot_step_ = -1;  ///< DemSystem::step_count() of the last snapshot
  std::int64_t chunk_steps_ = 1;          ///< steps between the chances to take an output

  DemStateCopy save_point_;  ///< take_save_point()
  bool held_back_ = false;   ///< advance_tentative() whose outputs wait for accept_step()
  /// after_advance() without the stability check: insertions, sensor samples, snapshot.
  void take_step_outputs();

  /// The DEM clock for output: step count x dt (not the running sum of dt).
  double output_clock() const;
  void write_snapshot(double label);

  void add(std::span<const ParticleInit> particles);
  void start_output(bool resume);

  /// Per [[dem.shapes]] entry its library and the engine id of its first shape.
  std::vector<std::unique_ptr<shapes::ShapeLibrary>> libraries_;
  std::vector<std::int32_t> shape_base_;

  std::filesystem::path output_dir_;
  double run_output_interval_ = 0.0;
  std::uint64_t seed_ = 1;
  std::vector<std::int64_t> repeats_;  ///< insertions done per [[dem.insert]] entry

  /// Repeated insertions due at the current time.
  void pour();
  std::ostream* log_ = nullptr;
  std::vector<WallClearance::Wall> wall_shapes_;  ///< the walls as added (names, triangles)
  /// The walls where they are now (they may move), for checking placed particles.
  WallClearance wall_clearance() const;
  /// Throws SceneError (or warns, in a coupled scene) when a placed particle falls past every
  /// wall: `what` names it, `where` the scene entry.
  void check_falls_past(const std::string& what, const std::string& where) const;
  double next_pour_time() const;
  /// [dem.freeze]: the particles due to be frozen at the current time, and the next time.
  void freeze_due();
  double next_freeze_ = std::numeric_limits<double>::infinity();
  void set_next_freeze();  ///< the first freezing time after the current time
};

}  // namespace demfem::dem
