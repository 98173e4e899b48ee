// liggghts_dem: LIGGGHTS as demfem's DEM (dem.backend = "external"), on one or more MPI ranks.
//
// The user's own LIGGGHTS input deck makes the particles, walls and contact models; demfem's
// interface mesh reaches it as an STL file, ${demfem_mesh}, which the deck loads as a
// `fix mesh/surface` and lists among the meshes of a `fix wall/gran ... store_force_contact_stress
// yes`. Each coupling step runs cmd.substeps LIGGGHTS steps and returns the particles' forces on
// the interface nodes (each contact's force with the barycentric weights of its contact point,
// as dem_server distributes them), gathered from every rank onto rank 0, which speaks the
// protocol. A step with the structure's kinematics first moves LIGGGHTS's mesh to the node
// positions of the step's start, with the node velocities (docs/liggghts.md).
//
// In the scene:
//   [dem]
//   backend = "external"
//   command = ["mpirun", "-np", "2", "<build>/bin/liggghts_dem"]   # or the program alone
//   dt = 2e-6
//   [dem.external]
//   deck = "beam_fixed_ci.liggghts"   # relative to the scene's folder
//   mesh_fix = "demfem_surface"       # the deck's fix mesh/surface on ${demfem_mesh}
//
// Run: ./demfem run examples/liggghts_dem/beam_fixed_ci.toml (one-way static) or
//      ./demfem run examples/liggghts_dem/beam_spheres_ci.toml (two-way, just in time).
// demfem starts it with --scene FILE --segment NAME [--set K=V]... --output-dir DIR [--resume].
#include <mpi.h>

#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <string>

#include "demfem/interface/exit_status.hpp"
#include "demfem/protocol/protocol.hpp"
#include "demfem/scene/solver_command_line.hpp"
#include "liggghts_backend.hpp"
#include "liggghts_domain.hpp"

namespace {

struct AdapterSettings {
  std::filesystem::path deck;
  std::string mesh_fix;
  double dem_timestep = 0.0;  ///< dem.dt, s
  std::int64_t steps_per_coupling_step = 1;  ///< n_D = fem.dt / dem.dt
};

/// Reads [dem.external]; refuses what dem_server would do instead of LIGGGHTS.
std::optional<int> read_settings(const demfem::scene::SolverCommandLine& cl,
                                 demfem::scene::RunSettings& run, AdapterSettings& settings) {
  const auto early = demfem::scene::load_solver_scene(
      cl, "dem", "liggghts_dem", run, [&](const demfem::scene::Table& dem) {
        if (dem.has("shapes"))
          throw demfem::scene::SceneError(
              dem.where("shapes") +
              ": dilated polyhedra are dem_server's (dem.backend = \"cpu\" or \"cuda\"); "
              "liggghts_dem couples LIGGGHTS's spheres only");
        settings.dem_timestep = dem.number("dt", demfem::scene::Range::positive());
        const auto external = dem.required_table("external");
        settings.deck = external.path("deck");
        settings.mesh_fix = external.string("mesh_fix");
        external.finish();
        if (!std::filesystem::is_regular_file(settings.deck))
          throw demfem::scene::SceneError(external.where("deck") + ": the LIGGGHTS deck " +
                                          settings.deck.string() + " does not exist");
      });
  if (early) return early;
  // The coupling step, to check a restored LIGGGHTS step counter (the launcher has checked
  // that fem.dt is a whole multiple of dem.dt).
  std::vector<demfem::scene::Override> overrides;
  for (const auto& o : cl.overrides) overrides.push_back(demfem::scene::Override::parse(o));
  try {
    const auto doc = demfem::scene::Document::load(cl.scene_file, overrides);
    const auto fem = doc.root().table("fem");
    if (fem && fem->has("dt"))
      settings.steps_per_coupling_step = std::llround(fem->number("dt") / settings.dem_timestep);
  } catch (const demfem::scene::SceneError& e) {
    std::cerr << e.what() << "\n";
    return demfem::kExitBadInput;
  }
  return std::nullopt;
}

/// LIGGGHTS ends the process on an error in its input or in a run (Error::all: its ERROR
/// line, MPI_Finalize, exit(1); 3.8 offers no way to catch it), so the coupler sees a dead
/// DEM. Rank 0 then says, on its way out, which coupling step LIGGGHTS stopped in and with
/// which of its messages (the last ERROR line of its log), beside the launcher's "dem solver
/// died". Errors on one rank (Error::one) abort every rank through MPI_Abort instead, which
/// runs no exit handler; LIGGGHTS's "ERROR on proc N" line and mpirun's report remain.
struct ExitNote {
  const demfem::liggghts::LiggghtsBackend* backend = nullptr;  ///< set while serve() runs
  std::filesystem::path log;
};
ExitNote exit_note;

void note_liggghts_exit() {
  if (!exit_note.backend) return;  // not inside serve(): an ordinary end
  std::string message = "no ERROR line in " + exit_note.log.string();
  std::ifstream in(exit_note.log);
  for (std::string line; std::getline(in, line);)
    if (line.rfind("ERROR", 0) == 0) message = line;
  const std::int64_t step = exit_note.backend->step_in_progress();
  char where[96] = "outside a coupling step (a handshake, checkpoint or restore)";
  if (step >= 0)
    std::snprintf(where, sizeof where, "in coupling step %lld (t = %.9g s)",
                  static_cast<long long>(step), exit_note.backend->time_in_progress());
  std::fprintf(stderr, "liggghts_dem: LIGGGHTS ended the DEM %s: %s (LIGGGHTS's log: %s)\n", where,
               message.c_str(), exit_note.log.c_str());
  std::fflush(stderr);
}

}  // namespace

int main(int argc, char** argv) {
  // LIGGGHTS writes its messages to stdout, which is a pipe under demfem run: line by line,
  // so that an error that ends in MPI_Abort (which flushes nothing) still shows its ERROR
  // line.
  std::setvbuf(stdout, nullptr, _IOLBF, 0);
  MPI_Init(&argc, &argv);
  int rank = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);

  CLI::App app{"liggghts_dem: LIGGGHTS as demfem's DEM over the SDK's DEM side"};
  demfem::scene::SolverCommandLine cl;
  cl.add_to(app, "dem", "LIGGGHTS");
  bool resume = false;
  app.add_flag("--resume", resume, "Continue from the checkpoint demfem restores");
  demfem::scene::RunSettings run;
  AdapterSettings settings;
  std::optional<int> early;
  // Every rank parses and reads the scene (the same files: the same verdict); only rank 0
  // prints the reason.
  {
    std::streambuf* quiet = rank == 0 ? nullptr : std::cerr.rdbuf(nullptr);
    early = demfem::scene::parse_solver_command_line(app, argc, argv);
    if (!early) early = read_settings(cl, run, settings);
    if (!early && cl.segment.empty()) {
      std::cerr << "liggghts_dem: --segment is required: it runs only under demfem run\n";
      early = demfem::kExitBadInput;
    }
    if (quiet) std::cerr.rdbuf(quiet);
  }
  if (early) {
    MPI_Finalize();
    return *early;
  }

  int code = 0;
  bool restored = false;
  {
    demfem::liggghts::LiggghtsDomain domain(MPI_COMM_WORLD, settings.deck, settings.mesh_fix,
                                            settings.dem_timestep, cl.output_folder(run), run.seed);
    if (rank == 0) {
      demfem::liggghts::LiggghtsBackend backend(MPI_COMM_WORLD, domain,
                                                settings.steps_per_coupling_step, resume);
      exit_note = {&backend, cl.output_folder(run) / "liggghts.log"};
      std::atexit(note_liggghts_exit);
      code = demfem::protocol::serve(backend, {.segment = cl.segment,
                                               .role = demfem::protocol::Role::dem,
                                               .remove_orphaned_segments = true});
      exit_note.backend = nullptr;
      backend.release_other_ranks();
      backend.write_times(cl.output_folder(run) / "liggghts_dem_times.json");
    } else {
      demfem::liggghts::serve_other_rank(MPI_COMM_WORLD, domain);
    }
    restored = domain.restored();
  }
  if (restored) {
    // After a read_restart LIGGGHTS 3.8 leaves the heap damaged: MPI_Finalize and the static
    // destructors then abort. The work is done and written: end here. (Under mpirun, whose
    // ranks must finalize, that makes mpirun's own status 1: docs/liggghts.md.)
    MPI_Barrier(MPI_COMM_WORLD);
    std::fflush(nullptr);
    std::_Exit(code);
  }
  MPI_Finalize();
  return code;
}
