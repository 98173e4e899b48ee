// fem_static_check: does the dynamic run's mean deflection follow from its mean load?
//
//   fem_static_check --scene FILE --output-dir DIR
//
// For a linear structure M u'' + C u' + K u = F(t), the time mean over a window of length T
// gives K <u> = <F> - (M [u'] + C [u]) / T, with [.] the change over the window: for a window
// long against the structure's periods the mean displacement is the static answer to the
// mean load. DIR/fem_mean.h5 ([fem.monitor] mean_window) holds the run's time-mean interface
// forces and displacement field; this program solves the scene's [fem] statically under
// those forces (no other loads may vary in time) and compares, at every probe of
// [fem.monitor] and over the whole field. It prints a table and writes DIR/static_check.csv
// (probe, node, mean_uz, static_uz, difference, relative). Exit status: 0 done, 1 failure,
// 2 bad command line or scene.

#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <sstream>

#include "demfem/fem/fem_scene.hpp"
#include "demfem/fem/fem_solver.hpp"
#include "demfem/io/atomic_file.hpp"
#include "demfem/io/h5_file.hpp"
#include "demfem/scene/scene_reader.hpp"

namespace fs = std::filesystem;

int main(int argc, char** argv) {
  CLI::App app{
      "fem_static_check: the static FEM solution under a run's time-mean interface "
      "forces, compared with the run's time-mean displacement (fem_mean.h5)."};
  std::string scene_file, out_dir;
  app.add_option("--scene", scene_file, "the scene of the run (its [fem] section)")->required();
  app.add_option("--output-dir", out_dir, "the run's output folder (default: run.output_dir)");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  demfem::fem::FemScene fem;
  fs::path dir;
  try {
    const auto doc = demfem::scene::Document::load(scene_file);
    const auto run = demfem::scene::read_run_settings(doc);
    fem = demfem::fem::read_fem_scene(doc.root().required_table("fem"));
    dir = out_dir.empty() ? run.output_dir : fs::path(out_dir);
  } catch (const demfem::scene::SceneError& e) {
    std::cerr << "fem_static_check: " << e.what() << "\n";
    return 2;
  }
  try {
    const fs::path mean_file = dir / "fem_mean.h5";
    if (!fs::exists(mean_file)) {
      std::cerr << "fem_static_check: " << mean_file.string()
                << " does not exist: the run needs [fem.monitor] mean_window, and must have "
                   "run past its end\n";
      return 1;
    }
    demfem::io::H5File h5(mean_file, demfem::io::H5File::Mode::read);
    const auto force = h5.read_doubles("interface_force");
    const auto mean_u = h5.read_doubles("displacement");
    const double start = h5.attribute_double("/", "start"), end = h5.attribute_double("/", "end");
    const double duration = h5.attribute_double("/", "duration");
    demfem::fem::FemSolver solver(std::move(fem.problem));
    if (force.size() != 3 * solver.interface_mesh().node_count())
      throw std::runtime_error(mean_file.string() + ": forces for " +
                               std::to_string(force.size() / 3) +
                               " interface nodes, the scene has " +
                               std::to_string(solver.interface_mesh().node_count()));
    solver.set_interface_forces(force);
    solver.solve_static();
    const auto u = solver.displacements();
    if (u.size() != mean_u.size())
      throw std::runtime_error(mean_file.string() + ": displacement of another mesh");
    double fz = 0.0;
    for (std::size_t i = 2; i < force.size(); i += 3) fz += force[i];
    // Whole field: the z components, relative L2 difference.
    double d2 = 0, n2 = 0;
    for (std::size_t i = 2; i < u.size(); i += 3) {
      d2 += (u[i] - mean_u[i]) * (u[i] - mean_u[i]);
      n2 += mean_u[i] * mean_u[i];
    }
    std::ostringstream csv;
    csv.precision(17);
    csv << "probe,node,mean_uz,static_uz,difference,relative\n";
    std::printf(
        "static check: window %.6g-%.6g s (%.6g s averaged), mean interface force %.6g N "
        "along z\n",
        start, end, duration, fz);
    std::printf("  %-12s %8s %16s %16s %12s\n", "probe", "node", "mean uz (m)", "static uz (m)",
                "relative");
    for (const auto& p : fem.monitor.probes) {
      const double a = mean_u[3 * std::size_t(p.node) + 2], b = u[3 * std::size_t(p.node) + 2];
      const double rel = a != 0.0 ? (b - a) / std::abs(a) : 0.0;
      std::printf("  %-12s %8d %16.9g %16.9g %+11.3f%%\n", p.name.c_str(), p.node, a, b, 100 * rel);
      csv << p.name << "," << p.node << "," << a << "," << b << "," << b - a << "," << rel << "\n";
    }
    const double field = n2 > 0 ? std::sqrt(d2 / n2) : 0.0;
    std::printf("  whole field: relative L2 difference of uz %.3f%%\n", 100 * field);
    csv << "field_l2,-1,0,0,0," << field << "\n";
    demfem::io::write_file_atomic(dir / "static_check.csv", csv.str());
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "fem_static_check: " << e.what() << "\n";
    return 1;
  }
}
