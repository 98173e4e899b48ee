// Element kernels (see elements.hpp). Voigt order xx, yy, zz, xy, yz, zx, engineering shear.
#include "elements.hpp"

#include <cmath>

namespace demfem::fem::detail {
namespace {

constexpr double kGauss = 0.57735026918962576451;  // 1/sqrt(3), 2-point Gauss, weight 1
constexpr double kHexNat[8][3] = {{-1, -1, -1}, {1, -1, -1}, {1, 1, -1}, {-1, 1, -1},
                                  {-1, -1, 1},  {1, -1, 1},  {1, 1, 1},  {-1, 1, 1}};
constexpr double kQuadNat[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};

using Mat3 = Eigen::Matrix3d;

void hex_shape(double r, double s, double t, Eigen::Matrix<double, 8, 1>& n,
               Eigen::Matrix<double, 3, 8>& dn) {
  for (int i = 0; i < 8; ++i) {
    const double a = 1 + r * kHexNat[i][0], b = 1 + s * kHexNat[i][1], c = 1 + t * kHexNat[i][2];
    n(i) = 0.125 * a * b * c;
    dn(0, i) = 0.125 * kHexNat[i][0] * b * c;
    dn(1, i) = 0.125 * a * kHexNat[i][1] * c;
    dn(2, i) = 0.125 * a * b * kHexNat[i][2];
  }
}

/// J(b, a) = d x_a / d xi_b.
Mat3 hex_jacobian(const std::array<Vec3, 8>& x, const Eigen::Matrix<double, 3, 8>& dn) {
  Mat3 j = Mat3::Zero();
  for (int i = 0; i < 8; ++i) j += dn.col(i) * x[i].transpose();
  return j;
}

/// Strain-displacement matrix from Cartesian shape derivatives g (3 x n), 3 DOF per node.
template <int N>
Eigen::Matrix<double, 6, 3 * N> strain_matrix(const Eigen::Matrix<double, 3, N>& g) {
  Eigen::Matrix<double, 6, 3 * N> b = Eigen::Matrix<double, 6, 3 * N>::Zero();
  for (int i = 0; i < N; ++i) {
    const double bx = g(0, i), by = g(1, i), bz = g(2, i);
    b(0, 3 * i) = bx;
    b(1, 3 * i + 1) = by;
    b(2, 3 * i + 2) = bz;
    b(3, 3 * i) = by;
    b(3, 3 * i + 1) = bx;
    b(4, 3 * i + 1) = bz;
    b(4, 3 * i + 2) = by;
    b(5, 3 * i) = bz;
    b(5, 3 * i + 2) = bx;
  }
  return b;
}

Mat3 tensor_from_voigt(const Voigt& v, double shear_factor) {
  Mat3 t;
  t << v(0), shear_factor * v(3), shear_factor * v(5), shear_factor * v(3), v(1),
      shear_factor * v(4), shear_factor * v(5), shear_factor * v(4), v(2);
  return t;
}

Voigt voigt_from_tensor(const Mat3& t, double shear_factor) {
  Voigt v;
  v << t(0, 0), t(1, 1), t(2, 2), shear_factor * t(0, 1), shear_factor * t(1, 2),
      shear_factor * t(2, 0);
  return v;
}

Mat3 skew(const Vec3& a) {
  Mat3 s;
  s << 0, -a(2), a(1), a(2), 0, -a(0), -a(1), a(0), 0;
  return s;
}

}  // namespace

Eigen::Matrix<double, 6, 6> elasticity_matrix(double e, double nu) {
  const double lambda = nu * e / ((1 + nu) * (1 - 2 * nu));
  const double mu = e / (2 * (1 + nu));
  Eigen::Matrix<double, 6, 6> d = Eigen::Matrix<double, 6, 6>::Zero();
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) d(i, j) = lambda;
    d(i, i) = lambda + 2 * mu;
    d(i + 3, i + 3) = mu;
  }
  return d;
}

// ---- hex8 ------------------------------------------------------------------------------

void hex8_stiffness(const std::array<Vec3, 8>& x, const Eigen::Matrix<double, 6, 6>& d,
                    Eigen::MatrixXd& k) {
  // Compatible part + 9 incompatible modes P_m = 1 - xi_m^2 (one per direction and
  // displacement component). Taylor's correction: the incompatible-mode gradients use the
  // centroid Jacobian J0 scaled by det J0 / det J, so that their volume integral vanishes
  // and constant strain states are represented exactly on distorted meshes (patch test).
  Eigen::Matrix<double, 8, 1> n;
  Eigen::Matrix<double, 3, 8> dn;
  hex_shape(0, 0, 0, n, dn);
  const Mat3 j0 = hex_jacobian(x, dn);
  const double det0 = j0.determinant();
  const Mat3 j0inv = j0.inverse();
  Eigen::Matrix<double, 24, 24> kcc = Eigen::Matrix<double, 24, 24>::Zero();
  Eigen::Matrix<double, 24, 9> kci = Eigen::Matrix<double, 24, 9>::Zero();
  Eigen::Matrix<double, 9, 9> kii = Eigen::Matrix<double, 9, 9>::Zero();
  for (int gi = 0; gi < 8; ++gi) {
    const double r = kGauss * kHexNat[gi][0], s = kGauss * kHexNat[gi][1],
                 t = kGauss * kHexNat[gi][2];
    hex_shape(r, s, t, n, dn);
    const Mat3 j = hex_jacobian(x, dn);
    const double det = j.determinant();
    const Eigen::Matrix<double, 3, 8> g = j.inverse() * dn;
    const auto bc = strain_matrix<8>(g);
    Mat3 dp = Mat3::Zero();
    dp(0, 0) = -2 * r;
    dp(1, 1) = -2 * s;
    dp(2, 2) = -2 * t;
    const Eigen::Matrix<double, 3, 3> gi3 = (det0 / det) * (j0inv * dp);
    const auto bi = strain_matrix<3>(gi3);
    const Eigen::Matrix<double, 6, 24> dbc = d * bc;
    kcc.noalias() += bc.transpose() * dbc * det;
    kci.noalias() += dbc.transpose() * bi * det;
    kii.noalias() += bi.transpose() * d * bi * det;
  }
  k = kcc - kci * kii.ldlt().solve(kci.transpose());
  k = 0.5 * (k + k.transpose());  // exact symmetry for the Cholesky factorisation
}

namespace {
/// Cartesian shape derivatives and det J at the 8 Gauss points, and their volume average
/// (1/V) sum g det J: the B-bar volumetric gradients.
struct HexGradients {
  std::array<Eigen::Matrix<double, 3, 8>, 8> g;
  std::array<double, 8> det;
  Eigen::Matrix<double, 3, 8> mean;
};
HexGradients hex_gradients(const std::array<Vec3, 8>& x) {
  HexGradients h;
  Eigen::Matrix<double, 8, 1> n;
  Eigen::Matrix<double, 3, 8> dn;
  h.mean.setZero();
  double volume = 0;
  for (int gi = 0; gi < 8; ++gi) {
    hex_shape(kGauss * kHexNat[gi][0], kGauss * kHexNat[gi][1], kGauss * kHexNat[gi][2], n, dn);
    const Mat3 j = hex_jacobian(x, dn);
    h.det[gi] = j.determinant();
    h.g[gi] = j.inverse() * dn;
    h.mean += h.det[gi] * h.g[gi];
    volume += h.det[gi];
  }
  h.mean /= volume;
  return h;
}

/// B-bar: the normal-strain rows get (mean - g) / 3 of every displacement component, which
/// replaces the volumetric strain by its element mean and leaves the deviator unchanged.
Eigen::Matrix<double, 6, 24> bbar_matrix(const Eigen::Matrix<double, 3, 8>& g,
                                         const Eigen::Matrix<double, 3, 8>& mean) {
  Eigen::Matrix<double, 6, 24> b = strain_matrix<8>(g);
  for (int i = 0; i < 8; ++i)
    for (int l = 0; l < 3; ++l) {
      const double c = (mean(l, i) - g(l, i)) / 3.0;
      for (int k = 0; k < 3; ++k) b(k, 3 * i + l) += c;
    }
  return b;
}
}  // namespace

void hex8_bbar_stiffness(const std::array<Vec3, 8>& x, const Eigen::Matrix<double, 6, 6>& d,
                         Eigen::MatrixXd& k) {
  const HexGradients h = hex_gradients(x);
  Eigen::Matrix<double, 24, 24> kk = Eigen::Matrix<double, 24, 24>::Zero();
  for (int gi = 0; gi < 8; ++gi) {
    const auto b = bbar_matrix(h.g[gi], h.mean);
    kk.noalias() += b.transpose() * d * b * h.det[gi];
  }
  k = 0.5 * (kk + kk.transpose());
}

Voigt hex8_bbar_centroid_strain(const std::array<Vec3, 8>& x, const double* ue) {
  const HexGradients h = hex_gradients(x);
  Eigen::Matrix<double, 8, 1> n;
  Eigen::Matrix<double, 3, 8> dn;
  hex_shape(0, 0, 0, n, dn);
  const Eigen::Matrix<double, 3, 8> g0 = hex_jacobian(x, dn).inverse() * dn;
  return bbar_matrix(g0, h.mean) * Eigen::Map<const Eigen::Matrix<double, 24, 1>>(ue);
}

std::array<double, 8> hex8_gauss_jacobians(const std::array<Vec3, 8>& x) {
  std::array<double, 8> out{};
  Eigen::Matrix<double, 8, 1> n;
  Eigen::Matrix<double, 3, 8> dn;
  for (int gi = 0; gi < 8; ++gi) {
    hex_shape(kGauss * kHexNat[gi][0], kGauss * kHexNat[gi][1], kGauss * kHexNat[gi][2], n, dn);
    out[gi] = hex_jacobian(x, dn).determinant();
  }
  return out;
}

void hex8_mass(const std::array<Vec3, 8>& x, double rho, bool lumped, Eigen::MatrixXd& m) {
  Eigen::Matrix<double, 8, 8> mn = Eigen::Matrix<double, 8, 8>::Zero();
  Eigen::Matrix<double, 8, 1> n;
  Eigen::Matrix<double, 3, 8> dn;
  for (int gi = 0; gi < 8; ++gi) {
    hex_shape(kGauss * kHexNat[gi][0], kGauss * kHexNat[gi][1], kGauss * kHexNat[gi][2], n, dn);
    mn.noalias() += rho * hex_jacobian(x, dn).determinant() * n * n.transpose();
  }
  m.setZero(24, 24);
  for (int a = 0; a < 8; ++a)
    for (int b = 0; b < 8; ++b) {
      const double v = lumped ? (a == b ? mn.row(a).sum() : 0.0) : mn(a, b);
      for (int c = 0; c < 3; ++c) m(3 * a + c, 3 * b + c) = v;
    }
}

Voigt hex8_centroid_strain(const std::array<Vec3, 8>& x, const double* ue) {
  Eigen::Matrix<double, 8, 1> n;
  Eigen::Matrix<double, 3, 8> dn;
  hex_shape(0, 0, 0, n, dn);
  const Eigen::Matrix<double, 3, 8> g = hex_jacobian(x, dn).inverse() * dn;
  return strain_matrix<8>(g) * Eigen::Map<const Eigen::Matrix<double, 24, 1>>(ue);
}

// ---- tet4 ------------------------------------------------------------------------------

namespace {
Eigen::Matrix<double, 3, 4> tet_gradients(const std::array<Vec3, 4>& x, double& volume) {
  Mat3 j;
  j << x[1] - x[0], x[2] - x[0], x[3] - x[0];  // columns
  volume = j.determinant() / 6.0;
  const Mat3 jinv = j.inverse();  // rows: gradients of the barycentric coords 1..3
  Eigen::Matrix<double, 3, 4> g;
  g.col(1) = jinv.row(0).transpose();
  g.col(2) = jinv.row(1).transpose();
  g.col(3) = jinv.row(2).transpose();
  g.col(0) = -(g.col(1) + g.col(2) + g.col(3));
  return g;
}
}  // namespace

double tet4_volume(const std::array<Vec3, 4>& x) {
  return (x[1] - x[0]).cross(x[2] - x[0]).dot(x[3] - x[0]) / 6.0;
}

void tet4_stiffness(const std::array<Vec3, 4>& x, const Eigen::Matrix<double, 6, 6>& d,
                    Eigen::MatrixXd& k) {
  double v = 0;
  const auto b = strain_matrix<4>(tet_gradients(x, v));
  k = b.transpose() * d * b * v;
  k = 0.5 * (k + k.transpose());
}

void tet4_mass(const std::array<Vec3, 4>& x, double rho, bool lumped, Eigen::MatrixXd& m) {
  const double mass = rho * tet4_volume(x);
  m.setZero(12, 12);
  for (int a = 0; a < 4; ++a)
    for (int b = 0; b < 4; ++b) {
      const double v = lumped ? (a == b ? mass / 4 : 0.0) : mass * (a == b ? 2.0 : 1.0) / 20.0;
      for (int c = 0; c < 3; ++c) m(3 * a + c, 3 * b + c) = v;
    }
}

Voigt tet4_strain(const std::array<Vec3, 4>& x, const double* ue) {
  double v = 0;
  return strain_matrix<4>(tet_gradients(x, v)) * Eigen::Map<const Eigen::Matrix<double, 12, 1>>(ue);
}

// ---- MITC4 shell -------------------------------------------------------------------------

namespace {

struct ShellPoint {
  Eigen::Matrix<double, 4, 1> n, dr, ds;
  Vec3 gr, gs, gz;                   ///< covariant base vectors
  Eigen::Matrix<double, 6, 24> cov;  ///< covariant strain rows (rr, ss, zz, rs, sz, zr)
};

void quad_shape(double r, double s, Eigen::Matrix<double, 4, 1>& n, Eigen::Matrix<double, 4, 1>& dr,
                Eigen::Matrix<double, 4, 1>& ds) {
  for (int i = 0; i < 4; ++i) {
    const double a = 1 + r * kQuadNat[i][0], b = 1 + s * kQuadNat[i][1];
    n(i) = 0.25 * a * b;
    dr(i) = 0.25 * kQuadNat[i][0] * b;
    ds(i) = 0.25 * a * kQuadNat[i][1];
  }
}

/// Geometry x = sum N_i (x_i + zeta a_i), displacement u = sum N_i (u_i + zeta theta_i x a_i)
/// with a_i = t/2 director_i (degenerated continuum); linear covariant strains
/// e_ij = (g_i . u_,j + g_j . u_,i) / 2 (shears as 2 e_ij).
ShellPoint shell_point(const ShellGeometry& g, double r, double s, double z) {
  ShellPoint p;
  quad_shape(r, s, p.n, p.dr, p.ds);
  std::array<Vec3, 4> a;
  for (int i = 0; i < 4; ++i) a[i] = 0.5 * g.thickness * g.director[i];
  p.gr.setZero();
  p.gs.setZero();
  p.gz.setZero();
  for (int i = 0; i < 4; ++i) {
    p.gr += p.dr(i) * (g.x[i] + z * a[i]);
    p.gs += p.ds(i) * (g.x[i] + z * a[i]);
    p.gz += p.n(i) * a[i];
  }
  Eigen::Matrix<double, 3, 24> ur = Eigen::Matrix<double, 3, 24>::Zero(), us = ur, uz = ur;
  for (int i = 0; i < 4; ++i) {
    const Mat3 sa = -skew(a[i]);  // theta x a = -a x theta
    ur.block<3, 3>(0, 6 * i).diagonal().setConstant(p.dr(i));
    us.block<3, 3>(0, 6 * i).diagonal().setConstant(p.ds(i));
    ur.block<3, 3>(0, 6 * i + 3) = z * p.dr(i) * sa;
    us.block<3, 3>(0, 6 * i + 3) = z * p.ds(i) * sa;
    uz.block<3, 3>(0, 6 * i + 3) = p.n(i) * sa;
  }
  p.cov.row(0) = p.gr.transpose() * ur;
  p.cov.row(1) = p.gs.transpose() * us;
  p.cov.row(2) = p.gz.transpose() * uz;
  p.cov.row(3) = p.gr.transpose() * us + p.gs.transpose() * ur;
  p.cov.row(4) = p.gs.transpose() * uz + p.gz.transpose() * us;
  p.cov.row(5) = p.gz.transpose() * ur + p.gr.transpose() * uz;
  return p;
}

/// Local orthonormal lamina frame (e1 along g_r, e3 normal to the lamina), columns.
Mat3 lamina_frame(const Vec3& gr, const Vec3& gs) {
  const Vec3 e3 = gr.cross(gs).normalized();
  const Vec3 e1 = gr.normalized();
  Mat3 f;
  f << e1, e3.cross(e1), e3;
  return f;
}

/// Cartesian strain rows (lamina frame) at (r, s, zeta), transverse shear by MITC4 tying:
/// e_rz from points A (0, 1), C (0, -1); e_sz from (1, 0), (-1, 0) (Dvorkin & Bathe 1984).
Eigen::Matrix<double, 6, 24> shell_strain_rows(const ShellGeometry& g, double r, double s, double z,
                                               Mat3& frame, double& detj) {
  ShellPoint p = shell_point(g, r, s, z);
  const ShellPoint pa = shell_point(g, 0, 1, z), pc = shell_point(g, 0, -1, z);
  const ShellPoint pb = shell_point(g, 1, 0, z), pd = shell_point(g, -1, 0, z);
  p.cov.row(5) = 0.5 * (1 + s) * pa.cov.row(5) + 0.5 * (1 - s) * pc.cov.row(5);
  p.cov.row(4) = 0.5 * (1 + r) * pb.cov.row(4) + 0.5 * (1 - r) * pd.cov.row(4);
  Mat3 j;
  j << p.gr, p.gs, p.gz;  // columns: covariant base vectors
  detj = j.determinant();
  const Mat3 contra = j.inverse();  // row i = contravariant g^i
  frame = lamina_frame(p.gr, p.gs);
  const Mat3 l = contra * frame;  // l(i, k) = g^i . e_k
  // eps_kl = e_ij l_ik l_jl; inputs and outputs use engineering shears.
  static const int pi[6] = {0, 1, 2, 0, 1, 2}, pj[6] = {0, 1, 2, 1, 2, 0};
  Eigen::Matrix<double, 6, 6> t;
  for (int o = 0; o < 6; ++o) {
    const int k = pi[o], ll = pj[o];
    const double fo = k == ll ? 1.0 : 2.0;
    for (int in = 0; in < 6; ++in) {
      const int i = pi[in], jj = pj[in];
      t(o, in) = i == jj ? fo * l(i, k) * l(i, ll)
                         : fo * 0.5 * (l(i, k) * l(jj, ll) + l(jj, k) * l(i, ll));
    }
  }
  return t * p.cov;
}

/// Plane-stress lamina law, sigma_33 = 0, transverse shear with the factor 5/6.
Eigen::Matrix<double, 6, 6> lamina_matrix(double e, double nu) {
  Eigen::Matrix<double, 6, 6> d = Eigen::Matrix<double, 6, 6>::Zero();
  const double c = e / (1 - nu * nu), gmod = e / (2 * (1 + nu));
  d(0, 0) = d(1, 1) = c;
  d(0, 1) = d(1, 0) = c * nu;
  d(3, 3) = gmod;
  d(4, 4) = d(5, 5) = 5.0 / 6.0 * gmod;
  return d;
}

}  // namespace

Vec3 quad_corner_normal(const std::array<Vec3, 4>& x, int a) {
  return (x[(a + 1) % 4] - x[a]).cross(x[(a + 3) % 4] - x[a]);
}

void mitc4_stiffness(const ShellGeometry& g, double e, double nu, Eigen::MatrixXd& k) {
  const auto d = lamina_matrix(e, nu);
  Eigen::Matrix<double, 24, 24> kk = Eigen::Matrix<double, 24, 24>::Zero();
  for (int gi = 0; gi < 4; ++gi)
    for (int gz = -1; gz <= 1; gz += 2) {
      Mat3 frame;
      double detj = 0;
      const auto b = shell_strain_rows(g, kGauss * kQuadNat[gi][0], kGauss * kQuadNat[gi][1],
                                       kGauss * gz, frame, detj);
      kk.noalias() += b.transpose() * d * b * detj;
    }
  // Drilling: the degenerated shell has no stiffness for the rotation about the director.
  // A penalty ties it to the element's in-plane rotation w = (du2/dx1 - du1/dx2) / 2 at the
  // centre (invariant under rigid rotations), with k = 1e-3 G t A: small against membrane
  // and bending stiffness, large enough to make K positive definite.
  const ShellPoint c = shell_point(g, 0, 0, 0);
  const Mat3 f = lamina_frame(c.gr, c.gs);
  Eigen::Matrix2d j2;
  j2 << c.gr.dot(f.col(0)), c.gr.dot(f.col(1)), c.gs.dot(f.col(0)), c.gs.dot(f.col(1));
  Eigen::Matrix<double, 2, 4> dnrs;
  dnrs << c.dr.transpose(), c.ds.transpose();
  const Eigen::Matrix<double, 2, 4> dnx = j2.inverse() * dnrs;
  Eigen::Matrix<double, 1, 24> w = Eigen::Matrix<double, 1, 24>::Zero();
  for (int i = 0; i < 4; ++i)
    w.segment<3>(6 * i) = 0.5 * (dnx(0, i) * f.col(1) - dnx(1, i) * f.col(0)).transpose();
  const double area = 4 * c.gr.cross(c.gs).norm();  // exact for parallelograms
  const double kd = 1e-3 * e / (2 * (1 + nu)) * g.thickness * area;
  for (int i = 0; i < 4; ++i) {
    Eigen::Matrix<double, 1, 24> row = -w;
    row.segment<3>(6 * i + 3) += g.director[i].transpose();
    kk.noalias() += kd * row.transpose() * row;
  }
  k = 0.5 * (kk + kk.transpose());
}

void mitc4_mass(const ShellGeometry& g, double rho, bool lumped, Eigen::MatrixXd& m) {
  Eigen::Matrix4d mn = Eigen::Matrix4d::Zero();
  for (int gi = 0; gi < 4; ++gi) {
    const ShellPoint p = shell_point(g, kGauss * kQuadNat[gi][0], kGauss * kQuadNat[gi][1], 0);
    mn.noalias() += p.gr.cross(p.gs).norm() * p.n * p.n.transpose();
  }
  const double t = g.thickness;
  m.setZero(24, 24);
  for (int a = 0; a < 4; ++a)
    for (int b = 0; b < 4; ++b) {
      const double v = lumped ? (a == b ? mn.row(a).sum() : 0.0) : mn(a, b);
      for (int c = 0; c < 3; ++c) {
        m(6 * a + c, 6 * b + c) = rho * t * v;
        m(6 * a + 3 + c, 6 * b + 3 + c) = rho * t * t * t / 12.0 * v;
      }
    }
}

void mitc4_strain_stress(const ShellGeometry& g, double e, double nu, double zeta, const double* ue,
                         Voigt& strain, Voigt& stress) {
  Mat3 frame;
  double detj = 0;
  const auto b = shell_strain_rows(g, 0, 0, zeta, frame, detj);
  Voigt el = b * Eigen::Map<const Eigen::Matrix<double, 24, 1>>(ue);
  const Voigt sl = lamina_matrix(e, nu) * el;
  el(2) = -nu / (1 - nu) * (el(0) + el(1));  // plane stress: sigma_33 = 0
  strain = voigt_from_tensor(frame * tensor_from_voigt(el, 0.5) * frame.transpose(), 2.0);
  stress = voigt_from_tensor(frame * tensor_from_voigt(sl, 1.0) * frame.transpose(), 1.0);
}

double von_mises(const Voigt& s) {
  const double a = s(0) - s(1), b = s(1) - s(2), c = s(2) - s(0);
  return std::sqrt(0.5 * (a * a + b * b + c * c) + 3 * (s(3) * s(3) + s(4) * s(4) + s(5) * s(5)));
}

double max_principal_strain(const Voigt& strain) {
  Eigen::SelfAdjointEigenSolver<Mat3> es(tensor_from_voigt(strain, 0.5), Eigen::EigenvaluesOnly);
  return es.eigenvalues()(2);
}

}  // namespace demfem::fem::detail
