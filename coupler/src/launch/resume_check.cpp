#include "launch/resume_check.hpp"

#include <cstdio>
#include <string>

#include "demfem/coupling/output_folder.hpp"
#include "demfem/fem/fem_backend.hpp"
#include "demfem/interface/exit_status.hpp"
#include "demfem/io/folder_lock.hpp"
#include "demfem/io/h5_file.hpp"

namespace fs = std::filesystem;

namespace demfem::coupling {

// The checkpoint directory of the run when it is a folder of its own (not inside the output
// folder, whose lock covers it).
bool inside(const fs::path& path, const fs::path& folder) {
  const auto p = fs::weakly_canonical(fs::absolute(path));
  const auto f = fs::weakly_canonical(fs::absolute(folder));
  auto pi = p.begin();
  for (auto fi = f.begin(); fi != f.end(); ++fi, ++pi) {
    if (fi->empty()) continue;  // a trailing separator
    if (pi == p.end() || *pi != *fi) return false;
  }
  return true;
}

bool same_folder(const fs::path& a, const fs::path& b) {
  return fs::weakly_canonical(fs::absolute(a)) == fs::weakly_canonical(fs::absolute(b));
}

// Checks of the checkpoint of --resume against this scene that need no process (exit status
// 2 on refusal), and takes over the series of the checkpoint's run when resuming into another
// output folder (docs/reliability.md, "Resume"). Returns an exit status, or nullopt to go on.
std::optional<int> prepare_resume(const fs::path& checkpoint, const CouplingSettings& settings,
                                  const SolverSections& sections, const fs::path& out_dir,
                                  RunRecord& record) {
  auto refuse = [](const std::string& m) {
    std::fprintf(stderr, "demfem run: --resume: %s\n", m.c_str());
    return demfem::kExitBadInput;
  };
  std::string origin;
  try {
    const io::H5File coupler(checkpoint / "coupler.h5", io::H5File::Mode::read);
    if (coupler.has_attribute("/", "scene_hash")) {
      const std::string then = coupler.attribute_string("/", "scene_hash");
      if (then != record.scene_hash) {
        std::fprintf(stderr,
                     "demfem run: note: the scene differs from the one checkpoint %s was taken "
                     "with (scene hash %s then, %s now); the run continues with this scene. "
                     "Changed end times and output settings continue the same run; other "
                     "changes give results that belong to neither scene\n",
                     checkpoint.c_str(), then.c_str(), record.scene_hash.c_str());
      }
    }
    if (coupler.has_attribute("/", "output_dir"))
      origin = coupler.attribute_string("/", "output_dir");
    // Before any process starts (the run's restore checks it again).
    const std::string clock =
        start_time_mismatch(settings, coupler.has_attribute("/", "start_time")
                                          ? coupler.attribute_double("/", "start_time")
                                          : 0.0);
    if (!clock.empty()) return refuse("checkpoint " + checkpoint.string() + ": " + clock);
    // dem.h5 of an external DEM is in the program's own format: neither dem_server nor
    // another program can continue it, nor can an external DEM continue dem_server's.
    if (settings.has_dem) {
      const std::string wrote = coupler.has_attribute("/", "dem_backend")
                                    ? coupler.attribute_string("/", "dem_backend")
                                    : std::string("cpu");
      if ((wrote == "external") != settings.dem_external())
        return refuse("checkpoint " + checkpoint.string() + " was taken with the DEM backend \"" +
                      wrote + "\"; this run's is \"" + settings.dem_backend +
                      "\" (dem.backend or --dem-backend), which cannot continue it: an external "
                      "program's checkpoint part is in its own format, which dem_server cannot "
                      "read, and dem_server's state is one an external program cannot take "
                      "over. Resume with --dem-backend " + wrote + ", or start afresh");
    }
    if (settings.has_dem && !settings.dem_external()) {
      const io::H5File dem(checkpoint / "dem.h5", io::H5File::Mode::read);
      if (dem.has_attribute("dem_tools", "setup_particles")) {
        const auto then = dem.attribute_int64("dem_tools", "setup_particles");
        if (then != static_cast<std::int64_t>(sections.dem_setup_particles)) {
          return refuse((checkpoint / "dem.h5").string() + ": the checkpoint's scene made " +
                        std::to_string(then) + " particles at set-up, " +
                        settings.scene_file.string() + " makes " +
                        std::to_string(sections.dem_setup_particles) +
                        " ([[dem.lattice]], [[dem.insert]] or run.seed changed); its state "
                        "cannot be continued with this scene: resume with the scene it was "
                        "taken with, or start afresh");
        }
      }
    }
    // The FEM backend that wrote fem.h5 (recorded by the coupler; older checkpoints: the full
    // FEM). Another backend continues it only where the state maps (docs/backends.md).
    std::string wrote = "fem";
    if (settings.has_fem && coupler.has_attribute("/", "fem_backend"))
      wrote = coupler.attribute_string("/", "fem_backend");
    if (settings.has_fem && wrote != settings.fem_backend) {
      const std::string why = fem::checkpoint_swap_refusal(wrote, settings.fem_backend);
      if (!why.empty())
        return refuse("checkpoint " + checkpoint.string() + " was taken with the FEM backend \"" +
                      wrote + "\"; this run's is \"" + settings.fem_backend +
                      "\" (fem.backend or --fem-backend), which cannot continue it: " + why +
                      ". Resume with --fem-backend " + wrote + ", or start afresh");
      std::fprintf(stderr,
                   "demfem run: note: checkpoint %s was taken with the FEM backend \"%s\"; the run "
                   "continues with \"%s\", which maps its state (the FEM's note below says how "
                   "closely)\n",
                   checkpoint.c_str(), wrote.c_str(), settings.fem_backend.c_str());
    }
    if (settings.has_fem && wrote != "external") {
      const io::H5File fem(checkpoint / "fem.h5", io::H5File::Mode::read);
      if (fem.has_attribute("fem", "mesh_nodes")) {
        const auto nodes = fem.attribute_int64("fem", "mesh_nodes");
        const auto elements = fem.attribute_int64("fem", "mesh_elements");
        if (nodes != static_cast<std::int64_t>(sections.fem_nodes) ||
            elements != static_cast<std::int64_t>(sections.fem_elements)) {
          return refuse((checkpoint / "fem.h5").string() + ": the checkpoint's FEM mesh has " +
                        std::to_string(nodes) + " nodes and " + std::to_string(elements) +
                        " elements, the mesh of " + settings.scene_file.string() + " has " +
                        std::to_string(sections.fem_nodes) + " and " +
                        std::to_string(sections.fem_elements) +
                        " ([fem.mesh] changed); its state cannot be continued on another mesh: "
                        "resume with the scene it was taken with, or start afresh");
        }
      }
    }
  } catch (const std::exception& e) {
    return refuse(std::string("checkpoint ") + checkpoint.string() +
                  " cannot be read: " + e.what());
  }
  // Resuming into another folder than the one the checkpoint's run wrote: its series
  // (coupling.csv, the FEM's and the DEM's files) are copied here first, and the run
  // continues them as it would in the original folder.
  // A folder moved or copied with its checkpoints (mv out/a out/b; an archive unpacked
  // elsewhere) holds the series of the checkpoint it holds: they are continued in place.
  if (!origin.empty() && !same_folder(origin, out_dir) && inside(checkpoint, out_dir) &&
      fs::exists(out_dir / "coupling.csv")) {
    std::fprintf(stderr,
                 "demfem run: note: checkpoint %s was taken by a run writing to %s; %s holds it "
                 "and that run's series (a moved or copied output folder): they are continued "
                 "here\n",
                 checkpoint.c_str(), origin.c_str(), out_dir.c_str());
    origin.clear();
  }
  if (!origin.empty() && !same_folder(origin, out_dir)) {
    if (!fs::exists(fs::path(origin) / "coupling.csv")) {
      return refuse("checkpoint " + checkpoint.string() + " was taken by a run writing to " +
                    origin +
                    ", whose series (coupling.csv) are not there any more; resume into "
                    "that folder with its output, or copy the output back there");
    }
    try {
      // Not while the run that wrote them is still going (a read-only archive cannot be
      // locked, and needs no lock: nothing writes there).
      io::FolderLock origin_lock;
      try {
        origin_lock = io::FolderLock(origin, "copying the series for a resume");
      } catch (const io::FolderBusy&) {
        throw;
      } catch (const std::exception&) {
      }
      const auto copied = copy_owned_outputs(origin, out_dir);
      record.copied_from = origin;
      std::fprintf(stderr,
                   "demfem run: resuming into %s: took over the series of %s (%zu files) to "
                   "continue them\n",
                   out_dir.c_str(), origin.c_str(), copied.size());
    } catch (const io::FolderBusy& e) {
      return refuse(std::string("the run that wrote the checkpoint is still going: ") + e.what());
    } catch (const std::exception& e) {
      return refuse(std::string("cannot take over the series of ") + origin + ": " + e.what());
    }
  }
  return std::nullopt;
}

}  // namespace demfem::coupling
