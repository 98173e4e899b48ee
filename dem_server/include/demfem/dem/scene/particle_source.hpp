#pragma once
// Starting a scene from particles in a file ([dem.load], docs/scene_dem.md): a particle
// snapshot of an earlier run (dem_output.hpp's particles_NNNNNN.h5), a saved DEM state (the
// end state a run writes with [dem.output] state = true, or a checkpoint's dem.h5:
// DemSystem::save's group, with contact history), or a CSV of x, y, z, r [, vx, vy, vz].
// Loaded particles are checked (finite, r > 0, their overlaps with each other and with the
// walls, their place inside the walls' bounding box) before the run starts. A state loaded
// with its contact history continues bit for bit as the saved run would have.

#include <array>
#include <cstdint>
#include <filesystem>
#include <iosfwd>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "demfem/dem/dem_system.hpp"
#include "demfem/scene/scene_reader.hpp"

namespace demfem::dem {

/// @brief The file a run writes with [dem.output] state = true: DemRun::save's groups "dem"
/// and "dem_tools", and on "/" the attributes scene_file, scene_hash (scene_text_hash of
/// the scene that made it), time and count.
inline constexpr const char* kStateFileName = "dem_state.h5";

/// @brief One [dem.load] table.
struct ParticleSource {
  enum class Format : std::uint8_t { snapshot, state, csv };
  /// Centres outside the walls' bounding box: an error, removed, kept; crop: removed, and
  /// so are particles whose bounding sphere crosses a face of that box in a direction that
  /// `tile` replicates (a tiled bed cut to its box, docs/dem.md "Periodic boundaries and tiled
  /// beds").
  enum class Outside : std::uint8_t { error, remove, keep, crop };
  std::filesystem::path file;           ///< resolved path
  std::filesystem::path prepare_scene;  ///< `scene` key: the run that makes `file`; empty if none
  /// Overrides the prepare scene runs with: `set`, then this run's overrides whose keys
  /// `pass` names, then (when there are any and none sets it) run.output_dir =
  /// "<its output folder>/set-<hash>", so that each variant of a bed has a folder of its own.
  std::vector<scene::Override> prepare_overrides;
  Format format = Format::csv;
  std::string group = "dem";               ///< state: the DemSystem group
  std::int32_t material = -1;              ///< every particle gets this material (-1: not given)
  std::vector<std::int32_t> material_map;  ///< file material index -> scene material
  bool history = false;                    ///< state: restore the contact history too
  bool velocities = true;                  ///< take velocities from the file (else at rest)
  bool keep_time = false;                  ///< history: continue at the state's time
  std::array<double, 3> shift{};           ///< m, added to every position
  double max_overlap = 0.05;               ///< refuse above this fraction of the smaller radius
  Outside outside = Outside::error;        ///< centres outside the walls' bounding box
  /// State of a periodic block: copies along its periodic directions (DemSystem::tile),
  /// before the checks and the `outside` rule; 1 1 1 = as it is.
  std::array<int, 3> tile{1, 1, 1};
  std::string tile_where;  ///< "file:line: key 'dem.load.tile'"
  std::string where;                       ///< "file:line: key 'dem.load.file'" (or .scene)
};

/// @brief Reads [dem.load]. `materials` are the scene's [[dem.materials]]. A `file` must
/// exist; the state of a `scene` need not exist yet (demfem run makes it first).
ParticleSource read_particle_source(const scene::Table& load,
                                    const std::vector<Material>& materials);

/// @brief Where the state of a prepare scene run with `overrides` lands: <its
/// run.output_dir>/dem_state.h5 (run.output_dir relative to the current directory, as for
/// any run). Throws SceneError (naming `where`) when the scene cannot be read, an override
/// does not apply to it, or it does not write its state.
std::filesystem::path prepared_state_path(const std::filesystem::path& prepare_scene,
                                          const std::vector<scene::Override>& overrides,
                                          const std::string& where);

/// @brief FNV-1a (64 bit) of a scene's content with `overrides` applied
/// (scene::Document::canonical_text: comments, layout, key order and number spelling do not
/// count), as 16 hex digits: tells whether a state file was made by this version of a scene
/// and these overrides. Throws SceneError when it cannot be read.
std::string scene_text_hash(const std::filesystem::path& file,
                            const std::vector<scene::Override>& overrides = {});

/// @brief True when `state` exists and was made by the current text of `scene` with
/// `overrides`.
bool state_is_current(const std::filesystem::path& state, const std::filesystem::path& scene,
                      const std::vector<scene::Override>& overrides = {});

/// @brief Loads the particles of `source` into `system`, which has its walls (`walls`, the
/// same meshes at t = 0) and no particles yet. Prints what it loaded and the largest overlap
/// to `log` (may be null). Throws scene::SceneError naming `source.where` and the file
/// (line or particle index) for bad data, overlaps beyond source.max_overlap, particles
/// outside the walls' bounding box (with Outside::error), or a state whose walls or masses
/// do not match this scene when the history is loaded. Returns the number of particles.
std::size_t load_particles(const ParticleSource& source, DemSystem& system,
                           std::span<const WallMesh> walls, std::ostream* log);

/// @brief Largest overlap of the particles [first, n) with any particle and with the walls,
/// as a fraction of the smaller radius of each pair (0 when none touch), with the two
/// indices (second = -1 for a wall).
struct OverlapReport {
  double fraction = 0.0;  ///< overlap / min(r_i, r_j) (walls: / r_i)
  double depth = 0.0;     ///< m
  std::int64_t i = -1, j = -1;
  std::size_t touching = 0;   ///< pairs that touch at all
  std::size_t unchecked = 0;  ///< polyhedra, left out (see largest_overlap)
};
/// Spheres only: polyhedra (from a state with history, which ran with them) are skipped.
OverlapReport largest_overlap(const ParticleState& particles, std::span<const WallMesh> walls);

}  // namespace demfem::dem
