#pragma once
// The in-process API of the DEM engine. dem_server is a thin protocol loop around it; scene
// tools (insertion, sensors, output) and tests drive it directly. The physics behind it
// (contact laws, integrator, wall geometry) lives in __host__ __device__ headers shared by
// the CPU and CUDA backends. Units: SI.

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "demfem/interface/interface_mesh.hpp"

namespace demfem::io {
class H5File;
}

namespace demfem::dem {

/// @brief Elastic properties of one material (particles or walls).
struct Material {
  std::string name;
  double youngs_modulus = 0.0;  ///< Pa
  double poisson_ratio = 0.0;   ///< -
  double density = 0.0;         ///< kg/m^3 (unused for walls)
};

/// @brief Interaction parameters of a pair of materials.
struct MaterialPair {
  double friction = 0.0;          ///< Coulomb sliding friction coefficient
  double restitution = 0.5;       ///< coefficient of restitution, (0, 1]
  double rolling_friction = 0.0;  ///< rolling resistance coefficient (0 = off)
  /// Polyhedra: damping of a face contact's rocking as a ratio to critical (docs/polyhedra.md;
  /// 0 = off). Only with restitution < 1 (no dashpot, no rocking damping).
  double rocking_damping = 1.0;
  /// Polyhedra: the contact law (docs/polyhedra.md): the pressure-centre law, or the smooth
  /// law (the exact gradient of a contact energy: conserves energy; stiffer where features tie).
  enum class PolyLaw { pressure_centre, smooth } poly_law = PolyLaw::pressure_centre;
};

/// The law of a scene's `poly_law` name ("pressure_centre", "smooth"); throws
/// std::invalid_argument for any other name.
MaterialPair::PolyLaw poly_law_from_name(const std::string& name);

/// @brief Where a DEM system steps: the CPU backend (OpenMP) or the CUDA backend (a device).
enum class DemBackendKind { cpu, cuda };

/// The backend of a scene's name ("cpu", "cuda"); throws std::invalid_argument for any other
/// name, naming the accepted ones.
DemBackendKind dem_backend_from_name(const std::string& name);
/// The scene's name of a backend: "cpu" or "cuda".
const char* dem_backend_name(DemBackendKind kind);

/// @brief The periodic directions of a system and their ranges: a particle that leaves
/// [lo, hi) in a periodic direction comes back in at the other side, and pairs interact
/// across the seam. hi - lo must be at least DemSystem::least_period().
struct PeriodicRange {
  std::array<bool, 3> on{};  ///< x, y, z periodic
  std::array<double, 3> lo{}, hi{};  ///< m, where on
  bool any() const { return on[0] || on[1] || on[2]; }
  double period(int d) const { return on[d] ? hi[d] - lo[d] : 0.0; }
};

/// @brief Global settings of a DEM system.
struct DemSettings {
  double dt = 1e-5;                            ///< s
  std::array<double, 3> gravity{0, 0, -9.81};  ///< m/s^2
  std::vector<Material> materials;
  /// Symmetric table, materials.size()^2 entries, row-major: pairs[i * n + j].
  std::vector<MaterialPair> pairs;
  double skin = 0.0;  ///< neighbour-list skin, m; 0 = 0.2 * largest radius
  /// Skin of the pair list refiltered from the grid build's candidates, as a fraction of
  /// `skin` in (0, 1]; 0 = adaptive (docs/dem.md, contact detection); 1 = one level. CPU backend.
  double list_skin = 0.0;
  /// Integrate the orientation quaternion of spheres too. A sphere's orientation enters no
  /// force, so by default it is integrated only when some particle is not a sphere (and the
  /// orientation of a sphere stays as it was set); on for rolling markers, visualisation.
  bool track_orientation = false;
  DemBackendKind backend = DemBackendKind::cpu;
  int threads = 0;  ///< CPU threads; 0 = OpenMP default
  /// Periodic boundaries (docs/dem.md, "Periodic boundaries and tiled beds"; CPU backend).
  PeriodicRange periodic;
};

/// @brief Shape of a particle: a sphere, or a dilated convex polyhedron (thesis §2.1.1: a
/// convex core ⊕ a sphere of radius r_d) from the system's shape table (add_shape()).
enum class ParticleShape : std::uint8_t { sphere = 0, polyhedron = 1 };

/// @brief A dilated convex polyhedron for the shape table (DemSystem::add_shape), at scale 1.
/// Its body frame is the principal frame of the dilated body with the origin at its centre of
/// mass (the shape library, demfem/dem/shapes, computes these). A particle scales it by
/// ParticleInit::scale: core, dilation and size by s, volume by s³, inertia by s⁵.
struct PolyhedronShape {
  std::string name;
  /// Core vertices, body frame, 3 per vertex, m. One vertex is a point core (a sphere of radius
  /// `dilation`), two a segment (a capsule).
  std::vector<double> vertices;
  /// Hull triangles of the core, counter-clockwise seen from outside (outward normals); needed
  /// for four or more vertices (a closed convex surface), empty for fewer.
  std::vector<std::int32_t> triangles;
  double dilation = 0.0;            ///< r_d, m (> 0)
  double volume = 0.0;              ///< volume of the dilated body, m³
  std::array<double, 3> inertia{};  ///< principal moments of the dilated body / density, m⁵
};

/// @brief Initial state of a new particle.
struct ParticleInit {
  std::array<double, 3> position{};
  std::array<double, 3> velocity{};
  std::array<double, 3> angular_velocity{};
  double radius = 0.0;  ///< sphere radius, m (polyhedra: ignored, the bounding radius is used)
  std::int32_t material = 0;
  ParticleShape shape = ParticleShape::sphere;
  std::int32_t shape_id = -1;  ///< polyhedron: index returned by DemSystem::add_shape
  double scale = 1.0;          ///< polyhedron: scale of the shape (> 0)
  /// Orientation quaternion (w, x, y, z), body to world; normalised (|q| must be 1 ± 1e-6).
  std::array<double, 4> orientation{1, 0, 0, 0};
};

/// @brief Force of the particles on one face of a wall (DemSystem::wall_face_load).
struct WallFaceLoad {
  std::array<double, 3> force{};  ///< N, on the wall
  double area = 0.0;              ///< m^2, of the face's triangles
};

/// @brief Host copy of the particle state, structure of arrays (index = particle).
struct ParticleState {
  std::vector<double> px, py, pz;             ///< position, m
  std::vector<double> vx, vy, vz;             ///< velocity, m/s
  std::vector<double> wx, wy, wz;             ///< angular velocity, rad/s
  std::vector<double> qw, qx, qy, qz;         ///< orientation quaternion
  std::vector<double> fx, fy, fz;             ///< force of the last step, N
  std::vector<double> radius, mass, inertia;  ///< m, kg, kg m^2
  std::vector<std::int32_t> material;
  std::vector<std::uint8_t> shape;  ///< ParticleShape
  /// Polyhedra: shape table index and scale; spheres: -1 and 1. A polyhedron's `radius` is
  /// the radius of its bounding sphere (the broad phase), `inertia` the mean of its principal
  /// moments.
  std::vector<std::int32_t> shape_id;
  std::vector<double> scale;
  std::vector<double> ix, iy, iz;  ///< principal moments of inertia (body frame), kg m^2
  std::size_t size() const { return px.size(); }
};

/// @brief Prescribed rigid motion of a wall mesh, active for start_time <= t < end_time
/// (at rest outside it, keeping the pose it reached).
struct WallMotion {
  enum class Kind : std::uint8_t { fixed, translation, rotation, sinusoid };
  Kind kind = Kind::fixed;
  std::array<double, 3> velocity{};     ///< translation: m/s; sinusoid: a steady drift added
  std::array<double, 3> axis_point{};   ///< rotation: a point on the axis, m
  std::array<double, 3> axis{0, 0, 1};  ///< rotation axis (unit) / sinusoid direction (unit)
  double angular_velocity = 0.0;        ///< rotation: rad/s
  double amplitude = 0.0;               ///< sinusoid: m, x(t) = A sin(2 pi f (t - t0) + phase)
  double frequency = 0.0;               ///< sinusoid: Hz
  double phase = 0.0;                   ///< sinusoid: rad
  double start_time = 0.0;              ///< s
  double end_time = 1e300;              ///< s
  /// translation, sinusoid: the drift (velocity) advances in a step at (1 - R / max_force) of
  /// its speed, none at R >= max_force, R the particles' push against it in the step before
  /// (their force on the wall along -velocity), N; 0: no limit. A compaction plate then
  /// presses a jammed bed with a bounded force instead of driving into it (the vibration
  /// goes on). Both backends (CUDA: one device step per wait while such a wall exists).
  double max_force = 0.0;
};

/// @brief Makes a wall a rigid body moved by the particles' contact forces (pressure cells,
/// a rigid sleeper, a loose plate; physics/rigid_mesh_body.hpp) instead of a prescribed
/// motion. Mass properties are given here (the scene computes them from the closed mesh and
/// a density, shapes/mesh_body.hpp). Both backends (the CUDA backend steps once per wait
/// while such a wall exists: the host moves it between the device's steps).
struct RigidBodySpec {
  bool enabled = false;
  double mass = 0.0;                              ///< kg, > 0
  std::array<double, 3> centre{};                 ///< centre of mass at the start, m
  std::array<double, 3> inertia{};                ///< principal moments, kg m², > 0
  std::array<double, 4> orientation{1, 0, 0, 0};  ///< principal frame to world (w, x, y, z)
  std::array<double, 3> velocity{};               ///< m/s, at the start
  std::array<double, 3> angular_velocity{};       ///< rad/s, world frame, at the start
  std::array<double, 3> force{};                  ///< constant applied force, N
  bool gravity = true;                            ///< DemSettings::gravity acts on it
  std::array<bool, 3> fix_translation{};          ///< components of the centre held in place
  bool fix_rotation = false;                      ///< the orientation held in place
};

/// @brief Kinematic state of a rigid mesh body and its loads of the last step.
struct RigidBodyState {
  std::array<double, 3> centre{}, velocity{}, angular_velocity{};
  std::array<double, 4> orientation{1, 0, 0, 0};
  std::array<double, 3> force{};   ///< of the particles on the body, N
  std::array<double, 3> torque{};  ///< of the particles, about the centre, N m
};

/// @brief A rigid triangle mesh (from STL or generated).
struct WallMesh {
  std::string name;
  std::vector<double> vertices;         ///< 3 per vertex, m
  std::vector<std::int32_t> triangles;  ///< 3 vertex indices per triangle
  std::int32_t material = 0;
  WallMotion motion;
  RigidBodySpec body;  ///< enabled: moved by its contact forces (motion must be fixed)
};

/// @brief The deepest contact of a system now (DemSystem::deepest_contact): where a run that
/// the overlap guard stopped went wrong.
struct DeepestContact {
  double relative = 0.0;         ///< overlap / the smaller contact radius; 0: none found
  double depth = 0.0;            ///< overlap, m
  std::int64_t particle = -1;    ///< index of the particle
  std::int64_t other = -1;       ///< index of the other particle, or -1: a wall
  std::vector<std::string> walls;  ///< other = -1: the walls the particle touches
};

/// @brief advance() stopped early because its cancellation flag was set (set_cancel_flag()).
/// The system is then between two steps of that advance(): fit to be dropped or restored
/// from a checkpoint, not to be continued.
class Cancelled : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// @brief An in-memory copy of a DemSystem's state (DemSystem::save_state), for going back
/// to the start of a coupling step that is iterated (implicit coupling). Opaque to callers;
/// reuse one object from step to step: its arrays keep their capacity, so a copy allocates
/// nothing once the sizes have settled.
struct DemStateCopy {
  double time = 0.0, flex_tau = 0.0, max_overlap = 0.0, flex_max_overlap = 0.0;
  std::int64_t steps = -1;    ///< -1: nothing saved yet
  std::size_t particles = 0;  ///< particle count (particles are not added within a step)
  std::vector<std::vector<double>> arrays;  ///< the state arrays of save(), constant ones left out
  std::vector<std::int64_t> row, wkey;
  std::vector<std::int32_t> nbr;
  std::vector<double> axis;            ///< polyhedra: the narrow phase's axis cache, 3 per pair
  std::vector<std::int32_t> features;  ///< polyhedra: its closest features, 6 per pair
  std::vector<std::uint8_t> wcount;
  std::vector<double> bodies;  ///< rigid mesh bodies ([dem.walls.body]), 19 per body
  std::vector<double> drift;   ///< force-limited walls: drift time and drifting (0/1), 2 per wall
  std::vector<std::uint8_t> frozen;  ///< DemSystem::frozen()
  std::vector<std::int32_t> image;   ///< DemSystem::images()
};

/// @brief A DEM system of particles, walls and (optionally) the flexible coupled mesh.
class DemSystem {
 public:
  explicit DemSystem(DemSettings settings);
  ~DemSystem();
  DemSystem(DemSystem&&) noexcept;
  DemSystem& operator=(DemSystem&&) noexcept;

  const DemSettings& settings() const;

  /// Adds a dilated convex polyhedron to the shape table; returns its index (ParticleInit::
  /// shape_id). Throws std::invalid_argument naming the field when the shape is not a closed
  /// convex core with positive dilation and mass properties.
  std::int32_t add_shape(const PolyhedronShape& shape);
  std::size_t shape_count() const;
  const PolyhedronShape& shape(std::int32_t id) const;

  /// Adds particles (between steps); returns the index of the first one.
  std::size_t add_particles(std::span<const ParticleInit> particles);
  /// Removes the particles whose keep[i] is false; contact history of the others is kept.
  void remove_particles(std::span<const std::uint8_t> keep);
  /// Host copy of the particle state (synchronises the device on the CUDA backend).
  const ParticleState& particles() const;
  std::size_t particle_count() const;

  /// Adds a rigid wall; returns its index.
  std::int32_t add_wall(WallMesh wall);
  std::size_t wall_count() const;
  /// Total force (N) and torque about the origin (N m) that the particles exert on a wall
  /// in the last step.
  std::array<double, 3> wall_force(std::int32_t wall) const;
  std::array<double, 3> wall_torque(std::int32_t wall) const;
  /// Force of the particles on one face of a wall in the last step, and the face's area: its
  /// triangles normal to `direction` that lie on the `direction` side of the wall's vertex
  /// centroid (the top of a pressure cell for [0, 0, 1], without the rocks under it or at
  /// its sides). Only contacts that press onto the face count (force on the wall against
  /// `direction`): one at its edge from a particle below the face's plane does not.
  WallFaceLoad wall_face_load(std::int32_t wall, const std::array<double, 3>& direction) const;
  /// The deepest contact now, against its contact radius (phys::relative_overlap), computed
  /// again on copies of the contacts' history (the system is left as it is): a blow-up's
  /// report names it. Pairs of two frozen particles are left out, as the steps leave them.
  /// The CPU backend; on the CUDA backend none is found (relative 0).
  DeepestContact deepest_contact() const;
  /// Current vertex positions of a wall (it may move).
  std::vector<double> wall_vertices(std::int32_t wall) const;
  /// Where the wall's motion puts its vertices at the system's clock, with its force-limited
  /// drift as it stands: after a restore that keeps the clock, a wall whose motion differs
  /// from the saving run's is placed there at the first step, not where the state had it
  /// ([dem.load] keep_time compares the two). A fixed wall or a body: its current vertices.
  std::vector<double> wall_vertices_at_clock(std::int32_t wall) const;
  /// State of a wall that is a rigid body (WallMesh::body); throws std::invalid_argument for
  /// any other wall.
  RigidBodyState body_state(std::int32_t wall) const;

  /// Sets the flexible coupled mesh (at most one) and its wall material.
  void set_flexible_mesh(const InterfaceMesh& mesh, std::int32_t material);
  bool has_flexible_mesh() const;
  /// Node kinematics at the start of the next advance(); during the substeps each node moves
  /// as x(tau) = x + v tau + a tau^2 / 2, v(tau) = v + a tau.
  void set_flexible_kinematics(std::span<const double> positions,
                               std::span<const double> velocities,
                               std::span<const double> accelerations);
  /// Per-node forces on the flexible mesh over the last advance(), as its ForceMode asked.
  void flexible_forces(std::span<double> forces) const;
  /// Current node positions of the flexible mesh as the DEM moved them.
  std::vector<double> flexible_positions() const;
  /// Largest particle overlap with the flexible mesh in the last advance(), m.
  double flexible_max_overlap() const;

  /// Runs `substeps` steps of settings().dt. Throws Cancelled when the cancellation flag is
  /// found set (checked before every step; on the CUDA backend every 256 steps).
  void advance(std::int64_t substeps, ForceMode mode = ForceMode::last_substep);
  /// A flag that another thread (or a signal handler) sets to make a running advance() stop
  /// within a step (nullptr = none). Only read, never written: polling it changes no result.
  /// A server sets it when its coupler is gone or a stop signal arrived, so that a long
  /// coupling step (10^6 substeps) does not run on for minutes as an orphan.
  void set_cancel_flag(const std::atomic<bool>* flag);
  double time() const;
  std::int64_t step_count() const;

  /// Periodic systems: per particle 3 image counters (x, y, z): how many periods it has
  /// gone round in each direction since it was added; its unwrapped position is x + n L.
  /// Empty when the system is not periodic.
  std::span<const std::int32_t> images() const;
  /// Least period a periodic direction accepts with the particles and skin of now, m: twice
  /// the neighbour list's cutoff, 2 (2 r_max + skin), so that a pair that can touch has one
  /// image only. advance() throws std::invalid_argument below it.
  double least_period() const;
  /// Tiles a periodic block: the particles, which form a block periodic over the ranges of
  /// `block`, are replicated copies[d] times along each of its periodic directions d (1 in
  /// the others): copy (a, b, c) of particle i becomes particle i + n (a + copies[0] (b +
  /// copies[1] c)) at x + (a Lx, b Ly, c Lz) (copy 0 keeps the indices). The contact history
  /// of every pair goes with it: block pair (i, j), j met at image shift s, becomes in copy c
  /// the pair of c's i with (c + s)'s j, so a pair across the block's seam becomes a pair
  /// between neighbouring copies, and the tiled bed's forces are the block's per copy. Where
  /// this system is periodic its range must be the tiled one, [lo, lo + copies L); where it
  /// is not, the pairs across the tiled bed's outer faces are dropped. Velocities are kept or
  /// zeroed; the last forces, wall contact slots and frozen flags are copied; image counters
  /// start at zero. Throws std::invalid_argument for a copy count < 1, copies in a direction
  /// the block is not periodic in, a system range that is not the tiled one, or a block
  /// period below least_period().
  void tile(const PeriodicRange& block, const std::array<int, 3>& copies, bool keep_velocities);

  /// Smallest radius that a contact's overlap is measured against: a sphere's radius, a
  /// polyhedron's dilation radius (its cores intersect when the overlap exceeds r_i + r_j), m.
  double smallest_contact_radius() const;

  /// Rayleigh time step (thesis eq. 2.27) of the smallest particle, s (polyhedra: the radius
  /// of the sphere of equal volume).
  double rayleigh_time_step() const;
  /// Total kinetic energy (translational + rotational), J.
  double kinetic_energy() const;

  /// Holds the particles with mask[i] != 0 where they are from now on, as EDEM's and Rocky's
  /// "settled" particles (CPU backend; throws std::invalid_argument with CUDA or a mask of
  /// another size): their velocities become and stay zero, their positions and orientations
  /// do not change. The others still feel them (and the walls too: a frozen particle's wall
  /// contacts are computed), but a pair of two frozen polyhedra is not computed (it moves
  /// nothing). Particles frozen earlier stay frozen. The mask is part of the saved state.
  void freeze(std::span<const std::uint8_t> mask);
  /// Frees every frozen particle: each moves again from the pose it was held at, starting at
  /// rest, its springs as they were kept. A scene that loads a state with its history
  /// ([dem.load], load_particles) frees them, so that only its own [dem.freeze] holds particles (a layer frozen while the next
  /// one was poured carries the load case free). Nothing happens when none is frozen.
  void release_frozen();
  /// Per particle: 1 when frozen (empty when none ever was).
  std::span<const std::uint8_t> frozen() const;
  std::size_t frozen_count() const;
  /// The force that holds the frozen particles, N: minus the sum of their forces of the
  /// last step (contacts with particles and walls, and gravity). In a static bed the walls'
  /// reactions and this force together carry the weights and loads.
  std::array<double, 3> frozen_support() const;
  /// Largest particle-particle or particle-wall overlap of the last step, m.
  double max_overlap() const;
  /// Largest particle-particle or particle-wall overlap over all steps of the last
  /// advance(), m (a deep overlap in the middle of an advance() is seen here even when the
  /// bodies have parted again by its end).
  double advance_max_overlap() const;
  /// Largest overlap of a contact against its own scale over all steps of the last
  /// advance(): the overlap over the smaller contact radius of its two bodies (a sphere's
  /// radius, a polyhedron's dilation; at a wall, the particle's), phys::relative_overlap.
  double advance_max_relative_overlap() const;

  /// @brief Wall-clock seconds spent in each phase since construction (for benchmarks).
  struct Timings {
    double detection = 0.0;    ///< neighbour-list and triangle-list rebuilds
    double forces = 0.0;       ///< pair and wall contact forces, gathering
    double integration = 0.0;  ///< kicks, drift, wall motion
  };
  Timings timings() const;
  /// Number of neighbour-list builds from the cell grid so far, of refilters of the pair
  /// list from the build's candidates (one per build included), and pairs in the current list.
  std::int64_t neighbour_rebuilds() const;
  std::int64_t neighbour_refilters() const;
  std::size_t neighbour_pairs() const;
  /// @brief The current neighbour list, for checks of one backend against another.
  struct PairList {
    std::vector<std::int64_t> row;      ///< n + 1: particle i's pairs are row[i] .. row[i + 1]
    std::vector<std::int32_t> partner;  ///< per pair: j > i, ascending within a row
    std::vector<double> spring;         ///< 3 per pair: tangential spring, m (empty: no friction)
    std::vector<double> bx, by, bz;     ///< positions the list was last filtered at, m
    std::vector<std::int64_t> triangle_row;  ///< n + 1 (empty without walls)
    std::vector<std::int32_t> triangles;     ///< per particle: candidate wall triangles
  };
  PairList pair_list() const;
  /// Number of particle-particle pairs in contact in the last step.
  std::size_t contact_count() const;
  /// Per particle: its particle-particle pairs in contact in the last step (coordination).
  std::vector<std::int32_t> contact_counts() const;
  /// @brief A particle-particle contact of the last step and its force.
  struct PairForce {
    std::int32_t i = 0, j = 0;      ///< the pair, i < j
    std::array<double, 3> force{};  ///< on i by j (normal and tangential), N; on j minus it
  };
  /// The pairs in contact in the last step (those contact_counts() counts), in pair-list
  /// order, with their forces (bed statistics: the packing sensor's force distribution).
  std::vector<PairForce> contact_forces() const;
  /// Bytes held by the host state: particle arrays, pair list with its histories and
  /// slots, wall-contact slots, shape table (for benchmarks).
  std::size_t state_bytes() const;

  /// Complete state, contact history included, for a bitwise-identical continuation.
  void save(io::H5File& file, const std::string& group) const;
  void restore(const io::H5File& file, const std::string& group);
  /// The state save() writes, copied in memory: particle kinematics and forces, contact
  /// history (pair springs and wall slots), flexible-mesh and wall state, clock. The particle
  /// properties (radius, mass, inertia, material, shape) are left out: restore_state() is
  /// only for going back within one coupling step, in which no particle is added or removed.
  /// Costs a copy of about 750 B per particle (docs/dem.md, "In-memory save point").
  void save_state(DemStateCopy& copy) const;
  /// Back to the state of save_state(); the neighbour list is rebuilt at the next step, as
  /// after restore() (the springs carry over), so the continuation is bitwise the one that
  /// followed save_state(). Throws std::logic_error when the particle count changed since.
  void restore_state(const DemStateCopy& copy);
  /// Starts the clock anew at t = 0 with no steps taken (a saved state that begins a new
  /// scene, docs/scene_dem.md [dem.load]); moving walls take their pose at t = 0. The
  /// particles and the contact history are left as they are.
  void reset_clock();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// The shape table of a saved DEM state (DemSystem::save) in group `group`, in the state's
/// order (a particle's shape_id indexes it); empty when the state has none. Throws
/// std::invalid_argument when the table is inconsistent.
std::vector<PolyhedronShape> read_state_shapes(const io::H5File& file, const std::string& group);

/// The periodic ranges a saved DEM state (DemSystem::save) was made with, in group `group`
/// (none periodic for a state without periods).
PeriodicRange read_state_periodic(const io::H5File& file, const std::string& group);

/// @brief True when this build has the CUDA backend and a CUDA device is present.
bool cuda_available();

}  // namespace demfem::dem
