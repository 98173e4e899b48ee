#pragma once
// The [dem] section of a scene (docs/scene_dem.md lists every key), read into plain
// specifications: what the walls, shapes, fills, sensors and output of a run are to be.
// Building a DemSystem from them is the run driver's business (run/dem_run.hpp).

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "demfem/dem/dem_system.hpp"
#include "demfem/dem/placement/insertion.hpp"
#include "demfem/dem/placement/packed_fill.hpp"
#include "demfem/dem/scene/particle_source.hpp"
#include "demfem/dem/shapes/particle_shape.hpp"
#include "demfem/dem/sensors/sensors.hpp"
#include "demfem/scene/scene_reader.hpp"

namespace demfem::dem {

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
  std::int64_t count = 20;                      ///< random_rock: shapes in the library
  int triangles = 30;                           ///< random_rock
  double elongation = 1.0;                      ///< random_rock: I / L
  double flatness = 1.0;                        ///< random_rock: S / I
  bool has_seed = false;                        ///< false: run seed + entry index
  std::uint64_t seed = 1;                       ///< random_rock
  std::vector<std::filesystem::path> stl;       ///< stl: the scanned rocks (one shape each)
  std::array<double, 3> aspect{1.0, 1.0, 1.0};  ///< box: side ratios; prism: [1, h/a, -]
  /// size: what the distribution's diameters mean (sieve size, volume-equivalent diameter,
  /// bounding diameter)
  shapes::SizeKind size = shapes::SizeKind::sieve;
  double dilation = 0.1;           ///< r_d as a fraction of the size, (0, 0.5)
  std::string where;               ///< file:line: key of the entry, for errors found later
};

/// @brief One [[dem.insert]] entry (material index and density resolved).
struct InsertSpec {
  RandomInsertion request;
  std::int32_t shape = -1;  ///< index into DemScene::shapes, -1 = spheres
  bool has_seed = false;    ///< false: seed = run seed + entry index
  double every = 0.0;       ///< > 0: repeated every this many seconds (a pour), s
  double until = 0.0;       ///< last time of a repetition, s
  std::string where;
};

/// @brief One [[dem.lattice]] entry.
struct LatticeSpec {
  LatticeFill request;
  std::int32_t shape = -1;  ///< index into DemScene::shapes, -1 = spheres
  bool has_seed = false;    ///< false: seed = run seed + kLatticeSeedOffset + entry index
  std::string where;
};

/// @brief One [[dem.pack]] entry.
struct PackSpec {
  PackedFill request;
  std::int32_t shape = -1;  ///< index into DemScene::shapes, -1 = spheres
  bool has_seed = false;    ///< false: seed = run seed + kPackSeedOffset + entry index
  std::string where;
};

/// @brief Default seed of pack entry i: run.seed + kPackSeedOffset + i (a prime offset apart
/// from the lattices' and the insertions' streams).
inline constexpr std::uint64_t kPackSeedOffset = 700001;

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

/// @brief Default of `dem.guard_overlap`: the largest overlap a DEM run accepts, as a fraction
/// of the smaller contact radius of the two bodies in contact (a sphere's radius, a
/// polyhedron's dilation; at a wall, the particle's): phys::relative_overlap. A Hertz contact
/// of a well-resolved run stays at a few per cent; half a radius means the spheres pass
/// through each other. Each contact is judged by its own bodies: 3 mm between two rocks of
/// 10 mm dilation is 0.3, even where the bed's smallest rock has 6 mm.
inline constexpr double kMaxStableOverlap = 0.5;
/// @brief The largest `dem.guard_overlap` a scene may set: at an overlap of the smaller
/// radius two spheres' centres are inside each other; two dilated polyhedra's cores stay
/// apart until r_i + r_j, but the Hertz law on the dilation is far outside its small-strain
/// range there.
inline constexpr double kMaxGuardOverlap = 1.0;

/// @brief Everything [dem] says.
struct DemScene {
  std::string file;
  std::vector<scene::Override> overrides;  ///< --set overrides of the scene (its state's hash)
  DemSettings settings;
  std::string dt_where;       ///< file:line: key 'dem.dt', for the Rayleigh check
  std::string backend_where;  ///< file:line: key 'dem.backend', for an unavailable backend
  /// [dem] guard_overlap: the stability guard stops a run at a contact deeper than this
  /// fraction of its smaller contact radius (DemRun::check_stable)
  double guard_overlap = kMaxStableOverlap;
  std::string guard_overlap_where;  ///< file:line: key 'dem.guard_overlap' (or the scene's [dem])
  std::vector<WallSpec> walls;
  std::vector<ShapeSpec> shapes;
  std::vector<LatticeSpec> lattices;
  std::vector<InsertSpec> inserts;
  std::vector<PackSpec> packs;  ///< [[dem.pack]], placed after the lattices
  double settle_time = 0.0;               ///< s of settling after insertion (before remove_above)
  std::optional<double> remove_above;     ///< m
  bool remove_by_top = false;             ///< remove_by = "top": the particle's highest point
  std::vector<SensorSpec> sensors;        ///< wall_force: wall = index into walls
  std::optional<double> output_interval;  ///< [dem.output] interval (else the run's)
  bool output_particles = true;
  bool output_walls = true;              ///< [dem.output] walls: with the particle snapshots
  bool output_state = false;             ///< [dem.output] state: write dem_state.h5 at the end
  /// [dem.output] positions = "unwrapped": periodic scenes write x + n L (n: the particle's
  /// image counter), so that ParaView shows the bed as it moved, not folded into the period
  bool output_unwrapped = false;
  std::array<std::string, 3> periodic_where;  ///< file:line: key 'dem.periodic.x' (y, z)
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

}  // namespace demfem::dem
