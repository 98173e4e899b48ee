#include "demfem/coupling/beam_check.hpp"

#include <cmath>
#include <cstdio>

#include "demfem/fem/fem_scene.hpp"
#include "demfem/fem/fem_solver.hpp"
#include "demfem/fem/node_selector.hpp"

namespace demfem::coupling {

BeamCheckResult run_beam_check(const BeamCheck& check, const scene::Document& scene,
                               const RunSummary& coupled) {
  BeamCheckResult r;
  // Coupled: the FEM interface position at the end of the run.
  r.node = nearest_node(coupled.mesh, check.probe);
  const double* ref = &coupled.mesh.reference_positions[3 * r.node];
  r.probe_distance =
      std::hypot(ref[0] - check.probe[0], ref[1] - check.probe[1], ref[2] - check.probe[2]);
  r.coupled = coupled.positions[3 * r.node + 2] - ref[2];
  for (std::size_t k = 2; k < coupled.forces.size(); k += 3) r.coupled_load -= coupled.forces[k];

  // Pure FEM: the same [fem] structure with the load m g as a uniform pressure on the
  // surface, solved statically (no interface forces).
  fem::FemScene fs = fem::read_fem_scene(scene.root().required_table("fem"));
  fem::PressureLoad load;
  const scene::Table root = scene.root();
  try {
    load.faces = fem::select_faces(fs.problem.mesh, check.surface);
  } catch (const fem::SelectorError& e) {
    root.required_table("coupling").required_table("beam_check").fail("surface", e.what());
  }
  double area = 0.0;
  for (const auto& f : load.faces) area += fem::face_area(fs.problem.mesh, f);
  r.pressure_load = check.load_mass * check.gravity;
  load.magnitude = r.pressure_load / area;
  fs.problem.pressures.push_back(load);
  fem::FemSolver solver(fs.problem);
  solver.solve_static();
  const InterfaceMesh& mesh = solver.interface_mesh();
  const std::size_t n3 = 3 * mesh.node_count();
  std::vector<double> p(n3), v(n3), a(n3);
  solver.interface_kinematics(p, v, a);
  const std::size_t node = nearest_node(mesh, check.probe);
  r.fem_pressure = p[3 * node + 2] - mesh.reference_positions[3 * node + 2];

  // Clamped-clamped beam under a uniform line load w = m g / L (thesis eq. 4.1-4.3).
  const double w = r.pressure_load / check.length;
  const double inertia = check.width * std::pow(check.height, 3) / 12.0;
  r.analytical = -w * std::pow(check.length, 4) / (384.0 * check.youngs_modulus * inertia);
  return r;
}

std::string beam_check_table(const BeamCheckResult& r, const BeamCheck& check) {
  char text[1400];
  const double rel_fem = (r.coupled - r.fem_pressure) / r.fem_pressure;
  const double rel_ana = (r.coupled - r.analytical) / r.analytical;
  const double rel_fem_ana = (r.fem_pressure - r.analytical) / r.analytical;
  std::snprintf(text, sizeof(text),
                "beam check: load %.6g kg (m g = %.6g N; the interface forces sum to %.9g N);\n"
                "mid-span deflection at interface node %zu (%.3g m from the probe point):\n"
                "  %-30s %15s   %s\n"
                "  %-30s %15.9e   %+.3e %% vs pure FEM, %+.4f %% vs analytical\n"
                "  %-30s %15.9e   %+.4f %% vs analytical\n"
                "  %-30s %15.9e\n"
                // Why the FEM lies above the formula, where the reader sees the number.
                "  (the formula neglects shear deformation, not small at L/H = %.3g: a solid beam\n"
                "  deflects more: docs/verification.md, \"Fixed-fixed beam\")\n",
                check.load_mass, r.pressure_load, r.coupled_load, r.node, r.probe_distance, "",
                "deflection [m]", "relative difference", "coupled (DEM load)", r.coupled,
                100.0 * rel_fem, 100.0 * rel_ana, "pure FEM, load as pressure", r.fem_pressure,
                100.0 * rel_fem_ana, "analytical wL^4/(384 E I)", r.analytical,
                check.length / check.height);
  return text;
}

}  // namespace demfem::coupling
