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

namespace {

constexpr int kExitFailure = 1;
constexpr int kExitBadInput = 2;

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "fem_server: the demfem FEM engine (linear elasticity, static and Bossak-Newmark "
      "dynamics).\n"
      "With --segment it serves the coupler that started it; without, it runs the scene's "
      "[fem] section alone: one static solve (fem.analysis = \"static\"), or dynamic steps of "
      "fem.dt up to run.end_time, writing <output-dir>/fem.xdmf (+ HDF5 files) and "
      "fem_series.csv.\n"
      "Exit codes: 0 ok, 1 failure while running, 2 bad command line or scene."};
  std::string scene_file;
  std::string segment;
  std::string output_dir;
  bool quiet = false;
  app.add_option("--scene", scene_file, "Scene file (TOML) with [run] and [fem]")->required();
  app.add_option("--segment", segment,
                 "Shared-memory segment of the coupler to serve (e.g. /demfem-1a2b); omit to "
                 "run the FEM alone");
  app.add_option("--output-dir", output_dir, "Output folder (default: run.output_dir)");
  app.add_flag("--quiet", quiet, "No progress lines");
  bool resume = false;
  app.add_flag("--resume", resume,
               "With --segment: continue the output series in the output folder instead of "
               "replacing it (a restarted solver that the coupler then restores)");
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return kExitBadInput;
  }

  demfem::scene::RunSettings run;
  demfem::fem::FemScene fem;
  try {
    const auto doc = demfem::scene::Document::load(scene_file);
    run = demfem::scene::read_run_settings(doc);
    const auto root = doc.root();
    auto fem_table = root.table("fem");
    if (!fem_table) {
      std::cerr << scene_file << ": the scene has no [fem] section, nothing for fem_server\n";
      return kExitBadInput;
    }
    fem = demfem::fem::read_fem_scene(*fem_table);
  } catch (const demfem::scene::SceneError& e) {
    std::cerr << e.what() << "\n";
    return kExitBadInput;
  }
  const std::filesystem::path out_dir =
      output_dir.empty() ? run.output_dir : std::filesystem::path(output_dir);

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
