// fem_server: the FEM engine as a process.
//   fem_server --scene FILE --segment NAME   serve a coupler over shared memory
//   fem_server --scene FILE                  run the scene's [fem] alone (static solve or
//                                            dynamic steps to run.end_time)
// Exit codes: 0 success; 1 a failure while running (solver, I/O); 2 a bad command line or
// scene (the message names file, line and key); with --segment, serve()'s codes.
#include <CLI/CLI.hpp>

#include <cstdio>
#include <exception>
#include <filesystem>
#include <iostream>
#include <memory>
#include <string>

#include "demfem/fem/fem_backend.hpp"
#include "demfem/fem/fem_output.hpp"
#include "demfem/fem/fem_scene.hpp"
#include "demfem/fem/fem_solver.hpp"
#include "demfem/protocol/protocol.hpp"
#include "demfem/scene/scene_reader.hpp"
#include "demfem/scene/solver_command_line.hpp"

using demfem::scene::kExitBadInput;
using demfem::scene::kExitFailure;

int main(int argc, char** argv) {
  CLI::App app{
      "fem_server: the demfem FEM engine (linear elasticity, static and Bossak-Newmark "
      "dynamics).\n"
      "With --segment it serves the coupler that started it; without, it runs the scene's "
      "[fem] section alone: one static solve (fem.analysis = \"static\"), or dynamic steps of "
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

  try {
    if (!segment.empty()) {
      demfem::fem::FemSolver solver(std::move(fem.problem));
      std::unique_ptr<demfem::fem::FemOutput> output;
      if (fem.output.enabled) {
        output = std::make_unique<demfem::fem::FemOutput>(
            out_dir, "fem", solver.problem().mesh, fem.output,
            resume ? demfem::fem::OutputMode::resume : demfem::fem::OutputMode::replace);
      }
      const double interval = fem.output.interval > 0.0 ? fem.output.interval : run.output_interval;
      if (output && !resume) output->write(solver);  // reference state
      demfem::fem::FemBackend backend(solver, output.get(), interval);
      demfem::protocol::ServeOptions options;
      options.segment = segment;
      options.remove_orphaned_segments = true;  // a killed coupler leaves nothing behind
      options.role = demfem::protocol::Role::fem;
      const int code = demfem::protocol::serve(backend, options);
      // The end state, unless the last step was just written by the backend.
      if (code == demfem::protocol::kExitOk && output && solver.step_count() > 0 &&
          (output->steps() == 0 || output->last_time() != solver.time())) {
        output->write(solver);
      }
      return code;
    }
    demfem::fem::run_fem_standalone(fem, run.end_time, run.output_interval, out_dir, "fem",
                                    quiet ? nullptr : &std::cout);
    return 0;
  } catch (const demfem::scene::SceneError& e) {
    std::cerr << e.what() << "\n";
    return kExitBadInput;
  } catch (const std::exception& e) {
    std::cerr << "fem_server: " << e.what() << "\n";
    return kExitFailure;
  }
}
