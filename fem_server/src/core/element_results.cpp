// Element results (centroid strain, von Mises stress, largest principal strain) of a
// displacement field; shared by every solver that writes FEM output.
#include <algorithm>

#include "demfem/fem/assembly.hpp"
#include "demfem/fem/fem_solver.hpp"
#include "elements.hpp"

namespace demfem::fem {

ElementResults compute_element_results(const FemProblem& p, const DofMap& dofs,
                                       const Eigen::VectorXd& uf) {
  std::vector<Eigen::Vector3d> directors;
  std::vector<double> thick;
  shell_nodal_directors(p, directors, thick);
  const std::size_t ne = p.mesh.elements.size();
  ElementResults r;
  r.strain.resize(6 * ne);
  r.von_mises.resize(ne);
  r.max_principal_strain.resize(ne);
  for (std::size_t e = 0; e < ne; ++e) {
    const Element& el = p.mesh.elements[e];
    const Material& mat = p.materials[static_cast<std::size_t>(
        p.sections[static_cast<std::size_t>(el.section)].material)];
    const int nn = nodes_per_element(el.type);
    const int per = el.type == ElementType::quad4 ? 6 : 3;
    double ue[24] = {};
    std::array<detail::Vec3, 8> x;
    for (int a = 0; a < nn; ++a) {
      const auto n = static_cast<std::size_t>(el.nodes[a]);
      const auto& pn = p.mesh.nodes[n];
      x[a] = detail::Vec3(pn[0], pn[1], pn[2]);
      for (int c = 0; c < per; ++c) ue[per * a + c] = uf(dofs.node_offset[n] + c);
    }
    detail::Voigt eps, sig;
    if (el.type == ElementType::hex8) {
      eps = el.formulation == SolidFormulation::selective_reduced
                ? detail::hex8_bbar_centroid_strain(x, ue)
                : detail::hex8_centroid_strain(x, ue);
      sig = detail::elasticity_matrix(mat.youngs_modulus, mat.poisson_ratio) * eps;
    } else if (el.type == ElementType::tet4) {
      eps = detail::tet4_strain({x[0], x[1], x[2], x[3]}, ue);
      sig = detail::elasticity_matrix(mat.youngs_modulus, mat.poisson_ratio) * eps;
    } else {
      // Shells: the more stressed of the two outer fibres (zeta = +-1) at the centre; the
      // mid-surface of a bent plate is nearly unstressed and says little.
      detail::ShellGeometry g;
      for (int a = 0; a < 4; ++a) {
        g.x[a] = x[a];
        g.director[a] = directors[static_cast<std::size_t>(el.nodes[a])];
      }
      g.thickness = p.sections[static_cast<std::size_t>(el.section)].thickness;
      detail::Voigt e2, s2;
      detail::mitc4_strain_stress(g, mat.youngs_modulus, mat.poisson_ratio, 1.0, ue, eps, sig);
      detail::mitc4_strain_stress(g, mat.youngs_modulus, mat.poisson_ratio, -1.0, ue, e2, s2);
      if (detail::von_mises(s2) > detail::von_mises(sig)) {
        eps = e2;
        sig = s2;
      }
    }
    for (int c = 0; c < 6; ++c) r.strain[6 * e + static_cast<std::size_t>(c)] = eps(c);
    r.von_mises[e] = detail::von_mises(sig);
    r.max_principal_strain[e] = detail::max_principal_strain(eps);
  }
  return r;
}

}  // namespace demfem::fem
