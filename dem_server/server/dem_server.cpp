// dem_server: the DEM engine as a process.
//   dem_server --scene FILE --segment NAME   serve a coupler over shared memory
//   dem_server --scene FILE                  run the scene's [dem] alone to run.end_time
// Exit codes: 0 success; 1 a failure while running (engine, I/O); 2 a bad command line or
// scene (the message names file, line and key); with --segment, serve()'s codes.
#include <CLI/CLI.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <iostream>
#include <memory>
#include <string>

#include "demfem/dem/dem_backend.hpp"
#include "demfem/dem/omp_wait.hpp"
#include "demfem/dem/run/dem_run.hpp"
#include "demfem/io/folder_lock.hpp"
#include "demfem/protocol/protocol.hpp"
#include "demfem/scene/scene_reader.hpp"
#include "demfem/scene/solver_command_line.hpp"

using demfem::kExitBadInput;
using demfem::kExitFailed;

int main(int argc, char** argv) {
  demfem::dem::ensure_omp_wait_policy(argv);  // first: it may re-execute the program
  CLI::App app{
      "dem_server: the demfem DEM engine (spheres, Hertz-Mindlin contacts, STL walls).\n"
      "With --segment it serves the coupler that started it (the coupled surface arrives from "
      "the FEM; dem.interface_material is its wall material). Without, it runs the scene's "
      "[dem] section alone up to run.end_time, writing <output-dir>/particles.xdmf (+ one "
      "HDF5 file per output time) and sensor_<name>.csv per [[dem.sensors]], and printing "
      "progress. docs/scene_dem.md lists the [dem] keys.\n"
      "Exit codes: 0 ok, 1 failure while running, 2 bad command line or scene."};
  demfem::scene::SolverCommandLine cl;
  cl.add_to(app, "dem", "the DEM");
  if (const auto code = demfem::scene::parse_solver_command_line(app, argc, argv)) return *code;

  demfem::scene::RunSettings run;
  demfem::dem::DemScene dem;
  if (const auto code = demfem::scene::load_solver_scene(
          cl, "dem", "dem_server", run,
          [&](const auto& t) { dem = demfem::dem::read_dem_scene(t); }))
    return *code;
  const std::filesystem::path out_dir = cl.output_folder(run);
  const std::string& segment = cl.segment;
  const bool quiet = cl.quiet;
  std::ostream* log = quiet ? nullptr : (segment.empty() ? &std::cout : &std::cerr);

  try {
    const bool coupled = !segment.empty();
    // Alone, the run's length is this process's: refused upfront like the coupler's.
    if (!coupled) {
      demfem::scene::check_step_count(run, dem.settings.dt, dem.dt_where,
                                      demfem::scene::kMaxDemSteps, "DEM");
    }
    // Served: files are created by the first step, or continued by a restore.
    demfem::dem::DemRun dem_run(dem, out_dir, run.seed, run.output_interval, log, coupled);
    if (coupled) {
      demfem::dem::DemBackend backend(dem_run);
      demfem::protocol::ServeOptions options;
      options.segment = segment;
      options.remove_orphaned_segments = true;  // a killed coupler leaves nothing behind
      options.role = demfem::protocol::Role::dem;
      options.peer_timeout = std::chrono::milliseconds(
          static_cast<std::int64_t>(std::ceil(1000.0 * run.peer_timeout)));
      // Held from before serve(): its own handlers rule while it runs and hand back to
      // these, so that a stop signal after Shutdown finds no gap to kill the end state.
      const demfem::protocol::HeldStopSignals held;
      const int code = demfem::protocol::serve(backend, options);
      if (code == demfem::protocol::kExitOk) dem_run.finish();  // the end state
      return code;
    }
    // Alone, this process owns the output folder (served, the coupler holds its lock).
    const demfem::io::FolderLock lock(out_dir, "dem_server --scene " + cl.scene_file);
    const auto start = std::chrono::steady_clock::now();
    double last_print = -1.0;
    dem_run.run_to(run.end_time, [&](double t) {
      if (!log) return;
      const double wall =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      if (wall - last_print < 2.0 && t < run.end_time) return;
      last_print = wall;
      const double rate = t / std::max(wall, 1e-9);
      const double eta = rate > 0 ? (run.end_time - t) / rate : 0.0;
      char line[200];
      std::snprintf(line, sizeof line,
                    "dem: t = %.6g / %.6g s (%.1f %%), %zu particles, KE %.4g J, %.3g s "
                    "simulated per s, ETA %.0f s\n",
                    t, run.end_time, 100.0 * t / run.end_time, dem_run.system().particle_count(),
                    dem_run.system().kinetic_energy(), rate, eta);
      *log << line << std::flush;
    });
    if (log) *log << "dem: done, output in " << out_dir.string() << "\n";
    return 0;
  } catch (const demfem::scene::SceneError& e) {
    std::cerr << e.what() << "\n";
    return kExitBadInput;
  } catch (const demfem::io::FolderBusy& e) {
    std::cerr << "dem_server: " << e.what() << "; give this run another --output-dir\n";
    return kExitBadInput;
  } catch (const std::exception& e) {
    std::cerr << "dem_server: " << e.what() << "\n";
    return kExitFailed;
  }
}
