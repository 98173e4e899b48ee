// fem_server: the FEM engine as a process.
//   fem_server --scene FILE --segment NAME   serve a coupler over shared memory
//   fem_server --scene FILE                  run the scene's [fem] alone (static solve or
//                                            dynamic steps to run.end_time)
// Exit codes: 0 success; 1 a failure while running (I/O); 2 a bad command line, scene or
// model (the message names file, line and key, or the nodes of a mechanism); with --segment,
// serve()'s codes.
#include <CLI/CLI.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <iostream>
#include <memory>
#include <string>
#include <type_traits>

#include "demfem/fem/fem_backend.hpp"
#include "demfem/fem/fem_output.hpp"
#include "demfem/fem/fem_scene.hpp"
#include "demfem/fem/fem_solver.hpp"
#include "demfem/io/folder_lock.hpp"
#include "demfem/protocol/protocol.hpp"
#include "demfem/scene/scene_reader.hpp"
#include "demfem/scene/solver_command_line.hpp"

using demfem::kExitBadInput;
using demfem::kExitFailed;

int main(int argc, char** argv) {
  CLI::App app{
      "fem_server: the demfem FEM engine (linear elasticity, static and Bossak-Newmark "
      "dynamics, natural frequencies); serves the backends fem.backend = \"fem\" (full FEM), "
      "\"modal\" (first N modes + static correction) and \"rigid\" (one rigid body on "
      "springs).\n"
      "With --segment it serves the coupler that started it; without, it runs the scene's "
      "[fem] section alone: one static solve (fem.analysis = \"static\"), the modes "
      "(\"modal\": fem_modes.csv, fem_modes.xdmf), or dynamic steps of "
      "fem.dt up to run.end_time, writing <output-dir>/fem.xdmf (+ HDF5 files) and "
      "fem_series.csv.\n"
      "Exit codes: 0 ok, 1 failure while running, 2 bad command line or scene."};
  demfem::scene::SolverCommandLine cl;
  cl.add_to(app, "fem", "the FEM");
  bool resume = false;
  app.add_flag("--resume", resume,
               "With --segment: continue the output series in the output folder instead of "
               "replacing it (a restarted solver that the coupler then restores)");
  if (const auto code = demfem::scene::parse_solver_command_line(app, argc, argv)) return *code;

  demfem::scene::RunSettings run;
  demfem::fem::FemScene fem;
  if (const auto code = demfem::scene::load_solver_scene(
          cl, "fem", "fem_server", run,
          [&](const auto& t) { fem = demfem::fem::read_fem_scene(t); }))
    return *code;
  const std::filesystem::path out_dir = cl.output_folder(run);
  const std::string& segment = cl.segment;
  const bool quiet = cl.quiet;
  // Notes (orphan nodes left out, .inp element formulations, keywords accepted with a
  // caveat) go to stderr even with --quiet: they can change how results must be read.
  for (const auto& note : fem.notes) std::cerr << "fem: note: " << note << "\n";

  try {
    if (!segment.empty()) {
      // The scene's backend (fem.backend; demfem run --fem-backend sets it for every process).
      auto serve_with = [&](auto& solver) {
        std::unique_ptr<demfem::fem::FemOutput> output;
        if (fem.output.enabled) {
          output = std::make_unique<demfem::fem::FemOutput>(
              out_dir, "fem", solver.problem().mesh, fem.output,
              resume ? demfem::fem::OutputMode::resume : demfem::fem::OutputMode::replace);
        }
        const double interval =
            fem.output.interval > 0.0 ? fem.output.interval : run.output_interval;
        demfem::fem::StructureBackend backend(solver, output.get(), interval);
        std::unique_ptr<demfem::fem::FemMonitor> monitor;
        if constexpr (std::is_same_v<std::decay_t<decltype(solver)>, demfem::fem::FemSolver>) {
          if (fem.monitor.enabled) {  // the full FEM only (read_fem_scene refuses it otherwise)
            monitor = std::make_unique<demfem::fem::FemMonitor>(out_dir, fem.monitor, resume);
            backend.set_monitor(monitor.get());
          }
        }
        if (!resume) backend.write_initial_output();  // reference state
        demfem::protocol::ServeOptions options;
        options.segment = segment;
        options.remove_orphaned_segments = true;  // a killed coupler leaves nothing behind
        options.role = demfem::protocol::Role::fem;
        options.peer_timeout = std::chrono::milliseconds(
            static_cast<std::int64_t>(std::ceil(1000.0 * run.peer_timeout)));
        // Held from before serve(): its own handlers rule while it runs and hand back to
        // these, so that a stop signal after Shutdown finds no gap to kill the end state.
        const demfem::protocol::HeldStopSignals held;
        const int code = demfem::protocol::serve(backend, options);
        if (code == demfem::protocol::kExitOk) backend.write_final_output();  // the end state
        return code;
      };
      switch (fem.backend) {
        case demfem::fem::FemBackendKind::modal: {
          demfem::fem::ModalSolver solver(std::move(fem.problem), fem.modal);
          return serve_with(solver);
        }
        case demfem::fem::FemBackendKind::rigid: {
          demfem::fem::RigidSolver solver(std::move(fem.problem), fem.rigid);
          return serve_with(solver);
        }
        case demfem::fem::FemBackendKind::external:
          std::cerr << "fem_server: fem.backend = \"external\": the coupler starts fem.command, "
                       "not fem_server\n";
          return kExitBadInput;
        case demfem::fem::FemBackendKind::fem:
          break;
      }
      demfem::fem::FemSolver solver(std::move(fem.problem));
      // Before it attaches: a model that cannot be solved (a mechanism, a structure the
      // clamps do not hold) ends the run now, with status 2, instead of after the DEM's work
      // (the coupler reports "ended with status 2 before it attached"). The factorisation is
      // the one the first step needs, so this costs nothing extra.
      solver.prepare(fem.analysis == demfem::fem::Analysis::static_analysis);
      return serve_with(solver);
    }
    // Alone, the run's length is this process's: refused upfront like the coupler's.
    if (fem.analysis == demfem::fem::Analysis::dynamic && fem.dt > 0.0) {
      demfem::scene::check_step_count(run, fem.dt, fem.dt_location, demfem::scene::kMaxFemSteps,
                                      "FEM");
    }
    // Alone, this process owns the output folder (served, the coupler holds its lock).
    const demfem::io::FolderLock lock(out_dir, "fem_server --scene " + cl.scene_file);
    demfem::fem::run_fem_standalone(fem, run.end_time, run.output_interval, out_dir, "fem",
                                    quiet ? nullptr : &std::cout);
    return 0;
  } catch (const demfem::scene::SceneError& e) {
    std::cerr << e.what() << "\n";
    return kExitBadInput;
  } catch (const demfem::io::FolderBusy& e) {
    std::cerr << "fem_server: " << e.what() << "; give this run another --output-dir\n";
    return kExitBadInput;
  } catch (const demfem::fem::FemModelError& e) {
    // A defect of the model found by the solver (mechanism, massless dynamics): bad input.
    std::cerr << "fem_server: " << e.what() << "\n";
    return kExitBadInput;
  } catch (const std::invalid_argument& e) {
    // A model the solver cannot take (modes asked for beyond the DOFs, an external backend).
    std::cerr << "fem_server: " << e.what() << "\n";
    return kExitBadInput;
  } catch (const std::exception& e) {
    std::cerr << "fem_server: " << e.what() << "\n";
    return kExitFailed;
  }
}
