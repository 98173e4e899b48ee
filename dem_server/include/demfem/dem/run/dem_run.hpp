#pragma once
// DemRun, the run driver: it builds a DemSystem from a scene's [dem] section (walls, shape
// libraries, loaded particles, lattice fills, random insertion, settling, removal above a
// height), carries the sensors and particle output along as the system advances, checks that
// the run stays stable, and saves and restores all of it for checkpoints.

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <iosfwd>
#include <limits>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "demfem/dem/dem_system.hpp"
#include "demfem/dem/placement/wall_clearance.hpp"
#include "demfem/dem/scene/dem_scene.hpp"
#include "demfem/io/output_schedule.hpp"

namespace demfem::io {
class H5File;
}

namespace demfem::dem {

namespace shapes {
class ShapeLibrary;
}

/// @brief Rayleigh time-step check (eq. 2.27): error above 1, warning above this fraction.
inline constexpr double kRayleighWarnFraction = 0.2;

/// @brief The run became unstable (DemRun::check_stable): a blow-up, not a failure.
class Unstable : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// @brief A DEM system built from a scene, with stable particle ids, sensors and output.
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
  /// check_setup()'s set-up, kept for reading: the system as a run of the scene starts
  /// (its [dem.load] state, lattices, insertions at t = 0), nothing run, no file. For a
  /// launcher that places a structure on a prepared bed (fem.mesh.seat). Throws SceneError.
  static std::unique_ptr<const DemRun> setup(const DemScene& scene, std::uint64_t seed);
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
  /// two bodies overlap by more than dem.guard_overlap (kMaxStableOverlap unless the scene
  /// sets it) of the smaller contact radius of the two (the soft contact no longer resolves
  /// them: dt too large for the stiffness, or loads beyond it). Called by after_advance(), so
  /// that no such state is sampled or written.
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
  std::string deepest_contact_text() const;  // for check_stable
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
  /// A period of the scene shorter than DemSystem::least_period(): SceneError naming its key.
  void check_periods() const;

  void add(std::span<const ParticleInit> particles);
  /// [[dem.pack]] entries, in order (seeds from `seed` unless given), checked against the
  /// walls and the particles already placed (dem_run_pack.cpp).
  void place_packs(const WallClearance& walls, std::uint64_t seed);
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
