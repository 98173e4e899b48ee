#pragma once
// Element results for output (per element, at its centroid) of a displacement field.

#include <vector>

#include <Eigen/Dense>

#include "demfem/fem/assembly.hpp"
#include "demfem/fem/fem_problem.hpp"

namespace demfem::fem {

/// @brief Element results for output (per element, at its centroid).
struct ElementResults {
  std::vector<double> strain;     ///< 6 per element: exx, eyy, ezz, gxy, gyz, gzx (engineering)
  std::vector<double> von_mises;  ///< Pa, one per element
  std::vector<double> max_principal_strain;  ///< one per element
};

/// @brief Centroid strain, von Mises stress and largest principal strain of every element for
/// the displacement `u` of all DOFs (fixed ones included, DofMap numbering). Shells: the more
/// stressed outer fibre.
ElementResults compute_element_results(const FemProblem& problem, const DofMap& dofs,
                                       const Eigen::VectorXd& u);

}  // namespace demfem::fem
