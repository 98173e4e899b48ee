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
