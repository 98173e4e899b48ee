// The modal-reduced and rigid-body FEM backends against the full FEM (docs/backends.md).
//
// Part 1, accuracy: cases/beam_dynamic_ci.toml (51 kg of spheres dropped onto the clamped beam,
// just-in-time coupling, 50 steps of 0.1 ms) run in process with the full FEM and with the
// modal backend for several mode counts N: the largest difference of the interface
// displacement over all nodes and steps, relative to the largest interface displacement.
// Part 2, cost: one FEM step (interface forces in, interface kinematics out) of FemSolver,
// ModalSolver and RigidSolver (the beam on four corner springs) on beams of growing mesh,
// median of repeated steps, and the set-up times.
//
//   fem_backends [--json FILE] [--modes 5,10,20,40] [--max-cells 80]
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include <CLI/CLI.hpp>

#include "bench_report.hpp"
#include "demfem/fem/fem_solver.hpp"
#include "demfem/fem/mesher.hpp"
#include "demfem/fem/modal_solver.hpp"
#include "demfem/fem/rigid_solver.hpp"
#include "demfem_test/coupled_history.hpp"

using namespace demfem;
using Clock = std::chrono::steady_clock;

namespace {

double seconds(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

fem::FemProblem beam(int nx) {
  fem::FemProblem p;
  p.mesh = fem::box_mesh_hex({0, 0, 0}, {1.0, 0.1, 0.1}, {nx, nx / 10, nx / 10});
  p.materials.push_back({"steel", 210e9, 0.3, 7800});
  p.sections.push_back({0, 0.0});
  p.constraints.push_back({p.mesh.node_sets.at("xmin")});
  p.constraints.push_back({p.mesh.node_sets.at("xmax")});
  p.mesh.surfaces["top"] = p.mesh.surfaces.at("zmax");
  p.interface_surface = "top";
  p.bossak = {-0.3, 0.4225, 0.8};
  p.damping.stiffness_factor = 1e-4;
  return p;
}

/// The beam as a rigid body on four vertical corner springs (tests/system/test_fem_backends.cpp).
fem::RigidSettings corner_springs() {
  fem::RigidSettings r;
  r.fixed = {true, true, false, false, false, true};  // x, y, rz held
  for (const auto& p : {std::array<double, 3>{0, 0, 0}, {1, 0, 0}, {0, 0.1, 0}, {1, 0.1, 0}})
    r.springs.push_back({p, {0, 0, 1e8}, {}});
  return r;
}

/// Median wall time of one coupling step of `solver` (set the forces, advance, read the
/// interface kinematics), over `n` steps.
template <class Solver>
double step_time(Solver& s, int n) {
  const std::size_t n3 = 3 * s.interface_mesh().node_count();
  std::vector<double> f(n3), x(n3), v(n3), a(n3);
  std::vector<double> t;
  for (int i = 0; i < n; ++i) {
    for (std::size_t k = 2; k < n3; k += 3) f[k] = -10.0 * (1.0 + 0.01 * i);
    const auto t0 = Clock::now();
    s.set_interface_forces(f);
    s.advance(1e-4);
    s.interface_kinematics(x, v, a);
    t.push_back(seconds(t0, Clock::now()));
  }
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<int> modes = {5, 10, 20, 40};
  int max_cells = 80;
  std::string json;
  CLI::App app{"The modal-reduced and rigid-body FEM backends against the full FEM: accuracy "
               "on the coupled dynamic beam, cost of one step"};
  app.add_option("--modes", modes, "mode counts of the modal backend, e.g. 5,10,20,40")
      ->delimiter(',')
      ->check(CLI::PositiveNumber);
  app.add_option("--max-cells", max_cells, "longest beam of the cost part, cells")
      ->check(CLI::PositiveNumber);
  app.add_option("--json", json,
                 "write the cost as JSON to FILE and the accuracy to FILE.accuracy.json");
  CLI11_PARSE(app, argc, argv);
  const std::string scene = std::string(DEMFEM_SOURCE_DIR) + "/cases/beam_dynamic_ci.toml";
  const auto tmp =
      std::filesystem::temp_directory_path() / ("fem_backends_" + std::to_string(::getpid()));

  bench::Report acc("fem_backends: modal backend on the coupled dynamic beam (beam_dynamic_ci)",
                    {"backend", "modes", "max |du| (m)", "relative", "final rel.", "FEM s/step"});
  const auto full = test::coupled_history(scene, {}, tmp / "full");
  double umax = 0.0;
  for (const auto& u : full.u)
    for (double x : u) umax = std::max(umax, std::abs(x));
  acc.add_row({std::string("fem"), 0LL, 0.0, 0.0, 0.0,
               full.summary.wall_fem / static_cast<double>(full.summary.steps)});
  for (int n : modes) {
    for (bool correction : {true, false}) {
      const auto m = test::coupled_history(
          scene,
          {"fem.backend=\"modal\"", "fem.modal={ modes = " + std::to_string(n) +
                                        ", static_correction = " + (correction ? "true" : "false") +
                                        " }"},
          tmp / ("modal" + std::to_string(n)));
      double d = 0.0, dend = 0.0, uend = 0.0;
      for (std::size_t s = 0; s < std::min(m.u.size(), full.u.size()); ++s)
        for (std::size_t k = 0; k < m.u[s].size(); ++k)
          d = std::max(d, std::abs(m.u[s][k] - full.u[s][k]));
      for (std::size_t k = 0; k < m.u.back().size(); ++k) {
        dend = std::max(dend, std::abs(m.u.back()[k] - full.u.back()[k]));
        uend = std::max(uend, std::abs(full.u.back()[k]));
      }
      acc.add_row({std::string(correction ? "modal + static correction" : "modal, truncated"),
                   static_cast<long long>(n), d, d / umax, dend / uend,
                   m.summary.wall_fem / static_cast<double>(m.summary.steps)});
    }
  }
  acc.set_info("largest interface displacement of the full FEM (m)", umax);
  acc.set_info("steps", static_cast<long long>(full.summary.steps));
  acc.print();

  bench::Report cost(
      "fem_backends: one FEM coupling step, full FEM vs modal (20 modes) vs rigid body",
      {"cells", "free DOF", "interface nodes", "fem setup s", "fem step ms", "modal setup s",
       "modal step ms", "modal speed-up", "rigid setup s", "rigid step ms", "rigid speed-up"});
  for (int nx = 20; nx <= max_cells; nx *= 2) {
    const auto t0 = Clock::now();
    fem::FemSolver f(beam(nx));
    std::vector<double> z(3 * f.interface_mesh().node_count(), 0.0);
    f.set_interface_forces(z);
    f.advance(1e-4);  // assembly and factorisation of the effective matrix
    const double fem_setup = seconds(t0, Clock::now());
    const double fem_step = step_time(f, 21);
    const auto t1 = Clock::now();
    fem::ModalSettings ms;
    ms.modes = 20;
    fem::ModalSolver m(beam(nx), ms);
    const double modal_setup = seconds(t1, Clock::now());
    const double modal_step = step_time(m, 201);
    const auto t2 = Clock::now();
    fem::RigidSolver r(beam(nx), corner_springs());
    const double rigid_setup = seconds(t2, Clock::now());
    const double rigid_step = step_time(r, 201);
    cost.add_row(
        {std::to_string(nx) + "x" + std::to_string(nx / 10) + "x" + std::to_string(nx / 10),
         static_cast<long long>(f.free_dof_count()),
         static_cast<long long>(f.interface_mesh().node_count()), fem_setup, 1e3 * fem_step,
         modal_setup, 1e3 * modal_step, fem_step / modal_step, rigid_setup, 1e3 * rigid_step,
         fem_step / rigid_step});
  }
  cost.set_info("machine", bench::machine_description());
  cost.set_info("commit", bench::git_commit());
  cost.print();
  acc.write_json(json.empty() ? "" : json + ".accuracy.json");
  cost.write_json(json);
  std::filesystem::remove_all(tmp);
  return 0;
}
