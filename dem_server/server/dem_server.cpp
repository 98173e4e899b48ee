// dem_server: the DEM engine as a process.
//   dem_server --scene FILE --segment NAME   serve a coupler over shared memory
//   dem_server --scene FILE                  run the scene's [dem] alone to run.end_time
// Exit codes: 0 success; 1 a failure while running (engine, I/O); 2 a bad command line or
// scene (the message names file, line and key); with --segment, serve()'s codes.
#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <iostream>
#include <memory>
#include <string>

#include "demfem/dem/dem_backend.hpp"
#include "demfem/dem/dem_scene.hpp"
#include "demfem/protocol/protocol.hpp"
#include "demfem/scene/scene_reader.hpp"

namespace {

constexpr int kExitFailure = 1;
constexpr int kExitBadInput = 2;

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "dem_server: the demfem DEM engine (spheres, Hertz-Mindlin contacts, STL walls).\n"
      "With --segment it serves the coupler that started it (the coupled surface arrives from "
      "the FEM; dem.interface_material is its wall material). Without, it runs the scene's "
      "[dem] section alone up to run.end_time, writing <output-dir>/particles.xdmf (+ one "
      "HDF5 file per output time) and sensor_<name>.csv per [[dem.sensors]], and printing "
      "progress. docs/scene_dem.md lists the [dem] keys.\n"
      "Exit codes: 0 ok, 1 failure while running, 2 bad command line or scene."};
  std::string scene_file;
  std::string segment;
  std::string output_dir;
  bool quiet = false;
  app.add_option("--scene", scene_file, "Scene file (TOML) with [run] and [dem]")->required();
  app.add_option("--segment", segment,
                 "Shared-memory segment of the coupler to serve (e.g. /demfem-1a2b); omit to "
                 "run the DEM alone");
  app.add_option("--output-dir", output_dir, "Output folder (default: run.output_dir)");
  app.add_flag("--quiet", quiet, "No progress lines");
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return kExitBadInput;
  }

  demfem::scene::RunSettings run;
  demfem::dem::DemScene dem;
  try {
    const auto doc = demfem::scene::Document::load(scene_file);
    run = demfem::scene::read_run_settings(doc);
    const auto root = doc.root();
    auto dem_table = root.table("dem");
    if (!dem_table) {
      std::cerr << scene_file << ": the scene has no [dem] section, nothing for dem_server\n";
      return kExitBadInput;
    }
    dem = demfem::dem::read_dem_scene(*dem_table);
  } catch (const demfem::scene::SceneError& e) {
    std::cerr << e.what() << "\n";
    return kExitBadInput;
  }
  const std::filesystem::path out_dir =
      output_dir.empty() ? run.output_dir : std::filesystem::path(output_dir);
  std::ostream* log = quiet ? nullptr : (segment.empty() ? &std::cout : &std::cerr);

  try {
    const bool coupled = !segment.empty();
    // Served: files are created by the first step, or continued by a restore.
    demfem::dem::DemRun dem_run(dem, out_dir, run.seed, run.output_interval, log, coupled);
    if (coupled) {
      demfem::dem::DemBackend backend(dem_run);
      demfem::protocol::ServeOptions options;
      options.segment = segment;
      options.remove_orphaned_segments = true;  // a killed coupler leaves nothing behind
      options.role = demfem::protocol::Role::dem;
      const int code = demfem::protocol::serve(backend, options);
      if (code == demfem::protocol::kExitOk) dem_run.finish();  // the end state
      return code;
    }
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
  } catch (const std::exception& e) {
    std::cerr << "dem_server: " << e.what() << "\n";
    return kExitFailure;
  }
}
