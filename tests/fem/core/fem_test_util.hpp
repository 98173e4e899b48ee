#pragma once
// Helpers for the fem_core tests: one-material problems on the structured meshes, node
// lookup by position, reduced dense matrices for eigenvalue checks.

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Dense>

#include "demfem/fem/assembly.hpp"
#include "demfem/fem/fem_problem.hpp"
#include "demfem/fem/fem_solver.hpp"
#include "demfem/fem/mesher.hpp"

namespace demfem::fem::test {

inline FemProblem make_problem(Mesh mesh, double e, double nu, double rho, double thickness = 0.0) {
  FemProblem p;
  p.mesh = std::move(mesh);
  p.materials.push_back(Material{"steel", e, nu, rho});
  p.sections.push_back(Section{0, thickness});
  return p;
}

inline void clamp(FemProblem& p, const std::string& set,
                  std::array<bool, 6> fixed = {true, true, true, true, true, true}) {
  p.constraints.push_back(Constraint{p.mesh.node_sets.at(set), fixed});
}

/// Index of the node nearest to x (the structured meshes put nodes exactly there).
inline std::size_t node_at(const Mesh& m, double x, double y, double z) {
  std::size_t best = 0;
  double bd = std::numeric_limits<double>::max();
  for (std::size_t i = 0; i < m.nodes.size(); ++i) {
    const double d = std::hypot(m.nodes[i][0] - x, m.nodes[i][1] - y, m.nodes[i][2] - z);
    if (d < bd) {
      bd = d;
      best = i;
    }
  }
  if (bd > 1e-9) throw std::runtime_error("no node at the requested position");
  return best;
}

struct BeamResult {
  double deflection;  ///< mid-span, on the neutral axis, m (positive down)
  double reaction_z;  ///< sum of the vertical reactions, N
};

/// The fixed-fixed steel beam of thesis table 4.1 (1000 x 100 x 100 mm, E = 210 GPa,
/// nu = 0.3, both end faces clamped, 5000 Pa on the top face), nx x ny x ny hex8 of the
/// given formulation.
inline BeamResult fixed_beam(int nx, int ny,
                             SolidFormulation f = SolidFormulation::incompatible_modes) {
  auto p = make_problem(box_mesh_hex({0, 0, 0}, {1.0, 0.1, 0.1}, {nx, ny, ny}), 210e9, 0.3, 7850);
  for (auto& e : p.mesh.elements) e.formulation = f;
  clamp(p, "xmin");
  clamp(p, "xmax");
  PressureLoad q;
  q.faces = p.mesh.surfaces.at("zmax");
  q.magnitude = 5000.0;
  p.pressures.push_back(q);
  const auto mid = node_at(p.mesh, 0.5, 0.05, 0.05);
  FemSolver s(std::move(p));
  s.solve_static();
  const auto r = s.reaction_forces();
  double rz = 0;
  for (std::size_t i = 2; i < r.size(); i += 3) rz += r[i];
  return {-s.displacements()[3 * mid + 2], rz};
}

struct Modes {
  Eigen::VectorXd omega2;  ///< ascending
  Eigen::MatrixXd shapes;  ///< columns, over the free DOFs
  DofMap dofs;
};

/// Dense generalized eigenproblem K phi = omega^2 M phi on the free DOFs (small models).
inline Modes modes(const FemProblem& p) {
  Modes r;
  r.dofs = make_dof_map(p);
  const Eigen::MatrixXd k = Eigen::MatrixXd(reduce_matrix(assemble_stiffness(p, r.dofs), r.dofs));
  const Eigen::MatrixXd m = Eigen::MatrixXd(reduce_matrix(assemble_mass(p, r.dofs), r.dofs));
  Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> es(k, m);
  r.omega2 = es.eigenvalues();
  r.shapes = es.eigenvectors();
  return r;
}

}  // namespace demfem::fem::test
