#pragma once
// Measurements taken between DemSystem::advance() calls: mass flow through a plane (thesis
// eq. 2.26), force and mean pressure on a wall, kinetic energy, angle of repose of a heap.
// Each configured sensor writes one CSV series.

#include <array>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "demfem/dem/dem_system.hpp"

namespace demfem::io {
class CsvWriter;
}

namespace demfem::dem {

/// @brief Counts the mass that crosses a plane: a particle whose centre goes from the back
/// side (dot(x - point, direction) < 0) to the front side (>= 0) adds its mass, one going
/// back subtracts it. Each particle's side is remembered by its id, so removals and
/// insertions between updates are harmless; a particle seen for the first time only has its
/// side recorded. Sampled often enough that no particle crosses twice between updates, this
/// is the Δm of eq. 2.26.
class MassFlowCounter {
 public:
  /// `radius` > 0 limits the measuring area to a disc of that radius around `point`
  /// (tested at the particle's position after crossing); 0 = the whole plane.
  MassFlowCounter(std::array<double, 3> point, std::array<double, 3> direction, double radius);
  /// Net mass (kg) that crossed in +direction since the previous update.
  double update(const ParticleState& particles, std::span<const std::int64_t> ids);
  /// The side of every particle id at the last update (0 unknown, -1 back, +1 front): the
  /// counter's state for a checkpoint.
  const std::vector<std::int8_t>& sides() const { return side_; }
  void set_sides(std::vector<std::int8_t> sides) { side_ = std::move(sides); }

 private:
  std::array<double, 3> point_;
  std::array<double, 3> dir_;
  double radius_;
  std::vector<std::int8_t> side_;  // by id: 0 unknown, -1 back, +1 front
};

/// @brief How the angle of repose is measured (see docs/scene_dem.md, "angle of repose").
struct ReposeOptions {
  std::array<double, 2> centre{};  ///< heap axis (x, y), m
  bool planar = false;     ///< false: radial distance from the axis; true: |x - centre.x| (a
                           ///< heap between two walls of constant y)
  double base = 0.0;       ///< floor height, m
  double top = 1e300;      ///< particles whose centre is above this height are ignored (the
                           ///< contents of a funnel above the heap), m
  double bin_width = 0.0;  ///< m; 0 = 2 mean particle diameters
  double flank_lo = 0.2;   ///< fit over bins whose centre lies in [flank_lo, flank_hi] * R,
  double flank_hi = 0.8;   ///< R = heap radius
};

/// @brief Result of angle_of_repose().
struct ReposeResult {
  double angle_deg = 0.0;            ///< atan(-slope) of the fitted flank, degrees
  double slope = 0.0;                ///< dz/dr of the fitted line
  double heap_radius = 0.0;          ///< R, m
  double heap_height = 0.0;          ///< top of the surface above base, m
  std::vector<double> bin_r, bin_z;  ///< surface profile: bin centre, surface height (m)
  int fitted_bins = 0;
};

/// @brief Angle of repose of a heap. The surface profile is the highest particle top
/// (z + radius) per distance bin; the heap radius R is where this profile, walked outwards
/// from the axis, first drops below base + 1.5 mean diameters (single rolled-away particles
/// do not count); a least-squares line through the profile on the flank [flank_lo R,
/// flank_hi R] gives the slope. Throws std::runtime_error when fewer than 3 bins lie on the
/// flank (heap too small for the bin width). `tops`, when given (one per particle), replaces
/// z + radius as a particle's top (a polyhedron's highest surface point: particle_tops), and
/// a particle's diameter is then 2 (top − z).
ReposeResult angle_of_repose(const ParticleState& particles, const ReposeOptions& options,
                             std::span<const double> tops = {});

/// @brief The height of each particle's highest surface point: z + radius for a sphere, the
/// highest vertex of the rotated, scaled core plus the dilation for a polyhedron of `system`.
std::vector<double> particle_tops(const DemSystem& system);

/// @brief A configured sensor.
struct SensorSpec {
  enum class Kind { mass_flow, wall_force, kinetic_energy, repose, packing, frozen };
  Kind kind = Kind::kinetic_energy;
  std::string name;       ///< CSV file: sensor_<name>.csv
  double interval = 0.0;  ///< sampling interval, s (> 0)
  // mass_flow
  std::array<double, 3> point{};
  std::array<double, 3> direction{0, 0, -1};
  double radius = 0.0;
  // wall_force
  std::int32_t wall = 0;
  bool face = false;  ///< only the face of the wall normal to `face_direction` (wall_face_load)
  std::array<double, 3> face_direction{0, 0, 1};
  double area = 0.0;  ///< wall area for the mean pressure |F| / area, m^2 (the scene
                      ///< fills it from the wall mesh); 0 = no pressure column value
  // repose
  ReposeOptions repose;
  // packing (packing.hpp): the control box
  std::array<double, 3> box_lo{}, box_hi{};
  bool contacts = false;  ///< packing: also the contact statistics (contact_statistics_in_box)
};

/// @brief The sensors of a run and their CSV series. sample() is called after each advance()
/// and samples each sensor whose time has come (at the first call with time() >= its next
/// sample time; a rate uses the time actually elapsed since its previous sample).
class SensorSet {
 public:
  /// Creates <dir>/sensor_<name>.csv for each sensor (no files when `dir` is empty). With
  /// `create_files` false the series are only opened by resume() (a restarted process that
  /// continues the files of a checkpoint).
  SensorSet(std::vector<SensorSpec> specs, const std::filesystem::path& dir,
            const DemSystem& system, bool create_files = true);
  ~SensorSet();
  SensorSet(SensorSet&&) noexcept;
  SensorSet& operator=(SensorSet&&) noexcept;

  void sample(const DemSystem& system, std::span<const std::int64_t> ids);
  /// Earliest time at which a sensor wants a sample (infinity when none).
  double next_time() const;
  std::size_t size() const;
  /// The last values sampled by sensor i (the CSV row without time).
  const std::vector<double>& last(std::size_t i) const;
  /// Rows written so far per sensor (for resuming after a checkpoint).
  std::vector<std::size_t> rows() const;
  /// Re-opens the series after a restore, keeping `rows[i]` rows of sensor i, and restarts
  /// the schedule at `time`.
  void resume(const std::vector<std::size_t>& rows, double time);
  /// Each sensor's schedule (next sample time, last sample time), flattened, for a checkpoint:
  /// with it, resume() continues the schedule exactly instead of restarting it at `time`
  /// (which would sample again at the first step after the checkpoint).
  std::vector<double> schedule() const;
  /// State of a mass_flow sensor for a checkpoint (other kinds have none).
  struct CounterState {
    bool present = false;            ///< the sensor is a mass_flow sensor
    double cumulative = 0.0;         ///< mass_crossed, kg
    std::vector<std::int8_t> sides;  ///< MassFlowCounter::sides()
  };
  std::vector<CounterState> counter_states() const;
  /// After resume(): the mass_flow sensors continue from these states (same order).
  void restore_counter_states(const std::vector<CounterState>& states);
  /// resume() with the schedule() of the checkpoint.
  void resume(const std::vector<std::size_t>& rows, double time,
              const std::vector<double>& schedule);

 private:
  struct Entry;
  std::vector<std::unique_ptr<Entry>> entries_;
};

}  // namespace demfem::dem
