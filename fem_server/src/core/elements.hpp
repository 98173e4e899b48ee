#pragma once
// Element kernels of the linear-elastic FEM (internal to demfem_fem_core): stiffness, mass,
// centroid strain of hex8 with incompatible modes, tet4, and the MITC4 shell.

#include <array>

#include <Eigen/Dense>

namespace demfem::fem::detail {

using Vec3 = Eigen::Vector3d;
using Voigt = Eigen::Matrix<double, 6, 1>;  ///< xx, yy, zz, xy, yz, zx (engineering shears)

/// Isotropic 3-D elasticity matrix (thesis eq. 2.35-2.37) in the Voigt order above.
Eigen::Matrix<double, 6, 6> elasticity_matrix(double youngs, double poisson);

// ---- hex8, incompatible modes (Wilson-Taylor, QM6 with Taylor's correction) ------------
/// 24 x 24 stiffness after static condensation of the 9 internal (incompatible) modes.
void hex8_stiffness(const std::array<Vec3, 8>& x, const Eigen::Matrix<double, 6, 6>& d,
                    Eigen::MatrixXd& k);
/// 24 x 24 stiffness, full 2x2x2 integration with the mean-dilatation B-bar (selectively
/// reduced integration of the volumetric strain, Hughes 1980; Abaqus C3D8).
void hex8_bbar_stiffness(const std::array<Vec3, 8>& x, const Eigen::Matrix<double, 6, 6>& d,
                         Eigen::MatrixXd& k);
/// Strain at the centroid of the B-bar hex: deviatoric part there, volumetric the mean.
Voigt hex8_bbar_centroid_strain(const std::array<Vec3, 8>& x, const double* ue);
/// det J at the 2x2x2 Gauss points (element quality checks).
std::array<double, 8> hex8_gauss_jacobians(const std::array<Vec3, 8>& x);
/// 24 x 24 mass, consistent (2x2x2 Gauss) or row-sum lumped.
void hex8_mass(const std::array<Vec3, 8>& x, double density, bool lumped, Eigen::MatrixXd& m);
/// Strain at the centroid (the incompatible modes have zero gradient there).
Voigt hex8_centroid_strain(const std::array<Vec3, 8>& x, const double* ue);

// ---- tet4, constant strain -------------------------------------------------------------
void tet4_stiffness(const std::array<Vec3, 4>& x, const Eigen::Matrix<double, 6, 6>& d,
                    Eigen::MatrixXd& k);
void tet4_mass(const std::array<Vec3, 4>& x, double density, bool lumped, Eigen::MatrixXd& m);
Voigt tet4_strain(const std::array<Vec3, 4>& x, const double* ue);
double tet4_volume(const std::array<Vec3, 4>& x);

// ---- quad4 shell, MITC4 (Dvorkin-Bathe), 6 DOF per node (u, theta) in the global frame ----
struct ShellGeometry {
  std::array<Vec3, 4> x;         ///< mid-surface nodes
  std::array<Vec3, 4> director;  ///< unit nodal directors
  double thickness = 0.0;
};
/// 24 x 24 stiffness; includes the small drilling penalty (rotation about the director tied
/// to the in-plane rotation of the element, 1e-3 G t A).
void mitc4_stiffness(const ShellGeometry& g, double youngs, double poisson, Eigen::MatrixXd& k);
/// 24 x 24 mass: translational rho t N N, rotational rho t^3/12 N N (all three rotations).
void mitc4_mass(const ShellGeometry& g, double density, bool lumped, Eigen::MatrixXd& m);
/// Strain at the in-plane centre at thickness coordinate zeta in [-1, 1], global frame
/// (eps_33 of the lamina from the plane-stress condition); also the stress (global).
void mitc4_strain_stress(const ShellGeometry& g, double youngs, double poisson, double zeta,
                         const double* ue, Voigt& strain, Voigt& stress);
/// Element normal (unnormalised area vector direction) at local node a: (x_{a+1}-x_a) x
/// (x_{a-1}-x_a).
Vec3 quad_corner_normal(const std::array<Vec3, 4>& x, int a);

// ---- results helpers -------------------------------------------------------------------
double von_mises(const Voigt& stress);
double max_principal_strain(const Voigt& strain);

}  // namespace demfem::fem::detail
