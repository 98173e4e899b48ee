// FEM time-step cost: assembly, factorisation of the Bossak effective matrix, and one
// dynamic step (RHS mat-vecs + two triangular solves) for hex8 box meshes of 10^3 to 10^5
// DOF, with CHOLMOD and with Eigen's SimplicialLDLT.
//
//   fem_step [--json FILE] [--max-ldlt-dof N] [--max-dof N]
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <string>

#include <CLI/CLI.hpp>

#include "bench_report.hpp"
#include "demfem/fem/assembly.hpp"
#include "demfem/fem/fem_solver.hpp"
#include "demfem/fem/mesher.hpp"

using namespace demfem::fem;
using Clock = std::chrono::steady_clock;

namespace {

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

FemProblem cube(int n) {
  FemProblem p;
  p.mesh = box_mesh_hex({0, 0, 0}, {1, 1, 1}, {n, n, n});
  p.materials.push_back(Material{"steel", 210e9, 0.3, 7850});
  p.sections.push_back(Section{0, 0});
  p.constraints.push_back(Constraint{p.mesh.node_sets.at("zmin"), {}});
  PressureLoad q;
  q.faces = p.mesh.surfaces.at("zmax");
  q.magnitude = 1e5;
  q.amplitude = [](double t) { return std::sin(100 * t); };
  p.pressures.push_back(q);
  return p;
}

}  // namespace

int main(int argc, char** argv) {
  long max_ldlt = 40000, max_dof = 110000;
  std::string json;
  CLI::App app{"FEM time-step cost (assembly, factorisation, one dynamic step) on hex8 boxes, "
               "CHOLMOD and SimplicialLDLT"};
  app.add_option("--max-ldlt-dof", max_ldlt, "largest mesh (free DOF) run with SimplicialLDLT")
      ->check(CLI::PositiveNumber);
  app.add_option("--max-dof", max_dof, "largest mesh (free DOF)")->check(CLI::PositiveNumber);
  app.add_option("--json", json, "write the results as JSON");
  CLI11_PARSE(app, argc, argv);
  demfem::bench::Report report("fem_step", {"backend", "elements", "dof", "assembly_s",
                                            "factorisation_s", "step_ms", "steps_timed"});
  report.set_info("machine", demfem::bench::machine_description());
  report.set_info("commit", demfem::bench::git_commit());
  report.set_info("mesh", std::string("unit cube of hex8 (incompatible modes), zmin clamped"));
  report.set_info("max_ldlt_dof", static_cast<long long>(max_ldlt));
  for (int n : {6, 10, 14, 21, 31}) {
    const long dof = 3L * (n + 1) * (n + 1) * n;  // free DOFs (zmin layer clamped)
    if (dof > max_dof) continue;
    for (SolverBackend b : {SolverBackend::cholmod, SolverBackend::simplicial_ldlt}) {
      if (b == SolverBackend::cholmod && !cholmod_available()) continue;
      if (b == SolverBackend::simplicial_ldlt && dof > max_ldlt) continue;
      const auto t_asm = Clock::now();
      FemSolver s(cube(n), b);
      const double assembly = seconds_since(t_asm);
      const double dt = 1e-5;
      // First step: initial acceleration (mass factorisation) + effective-matrix
      // factorisation + step. Factorisation alone is timed by a dt change below.
      s.advance(dt);
      const auto t_fac = Clock::now();
      s.advance(2 * dt);  // dt change: refactorises, then one step
      const double fac_and_step = seconds_since(t_fac);
      const int steps = dof < 20000 ? 200 : (dof < 50000 ? 50 : 20);
      const auto t_step = Clock::now();
      for (int i = 0; i < steps; ++i) s.advance(2 * dt);
      const double per_step = seconds_since(t_step) / steps;
      report.add_row({backend_name(b), static_cast<long long>(n) * n * n,
                      static_cast<long long>(s.free_dof_count()), assembly, fac_and_step - per_step,
                      1e3 * per_step, static_cast<long long>(steps)});
      std::cerr << "." << std::flush;
    }
  }
  std::cerr << "\n";
  report.print();
  report.write_json(json);
  return 0;
}
