#include "demfem/dem/shapes/mass_properties.hpp"

#include <Eigen/Eigenvalues>
#include <cmath>
#include <numbers>

#include "shape_util.hpp"

namespace demfem::dem::shapes {

namespace {

using detail::to_eigen;
using Eigen::Matrix3d;
using Eigen::Vector3d;
constexpr double kPi = std::numbers::pi;

/// Running sums of volume, first moment and second moment (integral of x x^T), relative to
/// a reference point near the body (so that shifting to the centroid loses no digits).
struct Moments {
  double v = 0.0;
  Vector3d s = Vector3d::Zero();
  Matrix3d c = Matrix3d::Zero();
};

Matrix3d sym(const Vector3d& a, const Vector3d& b) {
  return a * b.transpose() + b * a.transpose();
}

/// Exterior angle between two unit normals, accurate for small and large angles.
double angle_between(const Vector3d& n1, const Vector3d& n2) {
  return std::atan2(n1.cross(n2).norm(), n1.dot(n2));
}

Vector3d vertex(const ConvexPolyhedron& k, std::int32_t i, const Vector3d& o) {
  return to_eigen(k.vertices()[std::size_t(i)]) - o;
}

Vector3d reference_point(const ConvexPolyhedron& k) {
  Vector3d o = Vector3d::Zero();
  for (const Vec3& v : k.vertices()) o += to_eigen(v);
  return o / double(k.vertices().size());
}

/// The core: tetrahedra (o, a, b, c) with o the reference point (inside, as the mean of the
/// vertices of a convex body). For a tetrahedron with one vertex at the origin,
/// int x = V (a + b + c) / 4 and int x x^T = V / 20 (a a^T + b b^T + c c^T + s s^T), s = a + b + c.
void add_core(const ConvexPolyhedron& k, const Vector3d& o, Moments& m) {
  for (const Triangle& t : k.triangles()) {
    const Vector3d a = vertex(k, t[0], o), b = vertex(k, t[1], o), c = vertex(k, t[2], o);
    const double vol = a.dot(b.cross(c)) / 6.0;
    const Vector3d s = a + b + c;
    m.v += vol;
    m.s += vol / 4.0 * s;
    m.c += vol / 20.0 *
           (a * a.transpose() + b * b.transpose() + c * c.transpose() + s * s.transpose());
  }
}

/// Face slabs: T x [0, r] along the unit normal n. With the triangle's area A, first moment
/// m1 = A (a + b + c) / 3 and second moment M2 = A / 12 (a a^T + b b^T + c c^T + s s^T):
/// V = A r, S = r m1 + r^2/2 A n, C = r M2 + r^2/2 (m1 n^T + n m1^T) + r^3/3 A n n^T.
void add_slabs(const ConvexPolyhedron& k, const Vector3d& o, double r, Moments& m) {
  for (std::size_t f = 0; f < k.triangles().size(); ++f) {
    const Triangle& t = k.triangles()[f];
    const Vector3d a = vertex(k, t[0], o), b = vertex(k, t[1], o), c = vertex(k, t[2], o);
    const Vector3d n = to_eigen(k.normals()[f]);
    const double area = 0.5 * (b - a).cross(c - a).norm();
    const Vector3d s = a + b + c;
    const Vector3d m1 = area / 3.0 * s;
    const Matrix3d m2 =
        area / 12.0 *
        (a * a.transpose() + b * b.transpose() + c * c.transpose() + s * s.transpose());
    m.v += area * r;
    m.s += r * m1 + 0.5 * r * r * area * n;
    m.c += r * m2 + 0.5 * r * r * sym(m1, n) + r * r * r / 3.0 * area * n * n.transpose();
  }
}

/// Edge wedges: x = a + s e + rho (cos phi u + sin phi w), s in [0, L], rho in [0, r], phi in
/// [0, theta], dV = rho drho dphi ds; u = n_left, w = the unit vector towards n_right
/// perpendicular to u.
void add_wedges(const ConvexPolyhedron& k, const Vector3d& o, double r, Moments& m) {
  for (const Edge& e : k.edges()) {
    const Vector3d n1 = to_eigen(k.normals()[std::size_t(e.left)]);
    const Vector3d n2 = to_eigen(k.normals()[std::size_t(e.right)]);
    const Vector3d axis = n1.cross(n2);
    const double sin_t = axis.norm();
    if (sin_t == 0.0) continue;  // coplanar triangles (a merged facet): no wedge
    const double theta = std::atan2(sin_t, n1.dot(n2));
    const Vector3d u = n1;
    const Vector3d w = (axis / sin_t).cross(n1);
    const Vector3d a = vertex(k, e.a, o);
    const Vector3d d = vertex(k, e.b, o) - a;
    const double len = d.norm();
    const Vector3d ev = d / len;
    const double ring = 0.5 * theta * r * r;                                // cross-section area
    const Vector3d d1 = std::sin(theta) * u + (1.0 - std::cos(theta)) * w;  // int d dphi
    const double s2 = std::sin(2.0 * theta);
    const double sn = std::sin(theta);
    const Matrix3d d2 = (0.5 * theta + 0.25 * s2) * u * u.transpose() +
                        (0.5 * theta - 0.25 * s2) * w * w.transpose() +
                        0.5 * sn * sn * sym(u, w);       // int d d^T dphi
    const Vector3d y1 = len * a + 0.5 * len * len * ev;  // int (a + s e) ds
    const Matrix3d yy = len * a * a.transpose() + 0.5 * len * len * sym(a, ev) +
                        len * len * len / 3.0 * ev * ev.transpose();
    const double r3 = r * r * r / 3.0, r4 = r * r * r * r / 4.0;
    m.v += ring * len;
    m.s += ring * y1 + len * r3 * d1;
    m.c += ring * yy + r3 * sym(y1, d1) + len * r4 * d2;
  }
}

/// Unit-sphere moments of a spherical polygon P: omega = area, p1 = int_P x dA,
/// p2 = int_P x x^T dA.
struct SphericalMoments {
  double omega = 0.0;
  Vector3d p1 = Vector3d::Zero();
  Matrix3d p2 = Matrix3d::Zero();
};

/// The normal cone at vertex v: the spherical polygon of the face normals of its fan, in the
/// fan's (counter-clockwise seen from outside) order, so the polygon lies to the left of its
/// arcs. On the unit sphere x_i and x_i x_j - delta_ij / 3 are spherical harmonics of degree
/// 1 and 2 (Laplace-Beltrami eigenvalues -2 and -6); Green's identity turns their integrals
/// over P into integrals along the great-circle arcs, whose outward co-normal is -m (m the
/// unit normal of the arc's plane, p x q / |p x q| for the arc p -> q of angle alpha):
///   int_P x dA = 1/2 sum alpha m,
///   int_P x x^T dA = omega/3 I + 1/6 sum (m c^T + c m^T), c = int_arc x ds
///                  = sin(alpha) p + (1 - cos(alpha)) (m x p).
/// omega is the angular defect 2 pi - sum of face angles at v (Gauss-Bonnet for the normal
/// cone of a convex vertex).
SphericalMoments normal_cone(const ConvexPolyhedron& k, std::size_t v) {
  SphericalMoments sm;
  if (k.is_point()) {
    sm.omega = 4.0 * kPi;
    sm.p2 = 4.0 * kPi / 3.0 * Matrix3d::Identity();
    return sm;
  }
  const auto fan = k.vertex_triangles(v);
  const auto nb = k.neighbours(v);
  const Vector3d x = to_eigen(k.vertices()[v]);
  double angle_sum = 0.0;
  for (std::size_t i = 0; i < fan.size(); ++i) {
    const Vector3d p1 = to_eigen(k.vertices()[std::size_t(nb[i])]) - x;
    const Vector3d p2 = to_eigen(k.vertices()[std::size_t(nb[(i + 1) % nb.size()])]) - x;
    angle_sum += angle_between(p1, p2);
  }
  sm.omega = 2.0 * kPi - angle_sum;
  Matrix3d arcs = Matrix3d::Zero();
  for (std::size_t i = 0; i < fan.size(); ++i) {
    const Vector3d p = to_eigen(k.normals()[std::size_t(fan[i])]);
    const Vector3d q = to_eigen(k.normals()[std::size_t(fan[(i + 1) % fan.size()])]);
    const Vector3d pq = p.cross(q);
    const double s = pq.norm();
    if (s == 0.0) continue;  // coplanar neighbours: a zero-length arc
    const double alpha = std::atan2(s, p.dot(q));
    const Vector3d mv = pq / s;
    const Vector3d c = std::sin(alpha) * p + (1.0 - std::cos(alpha)) * mv.cross(p);
    sm.p1 += 0.5 * alpha * mv;
    arcs += sym(mv, c);
  }
  sm.p2 = sm.omega / 3.0 * Matrix3d::Identity() + arcs / 6.0;
  return sm;
}

/// Vertex sectors: x = v + rho d, d in the normal cone, rho in [0, r], dV = rho^2 drho dA(d):
/// V = omega r^3 / 3, S = V v + r^4/4 p1, C = V v v^T + r^4/4 (v p1^T + p1 v^T) + r^5/5 p2.
void add_sectors(const ConvexPolyhedron& k, const Vector3d& o, double r, Moments& m) {
  const double r3 = r * r * r;
  for (std::size_t v = 0; v < k.vertices().size(); ++v) {
    const SphericalMoments sm = normal_cone(k, v);
    const Vector3d x = to_eigen(k.vertices()[v]) - o;
    const double vol = sm.omega * r3 / 3.0;
    m.v += vol;
    m.s += vol * x + 0.25 * r3 * r * sm.p1;
    m.c += vol * x * x.transpose() + 0.25 * r3 * r * sym(x, sm.p1) + 0.2 * r3 * r * r * sm.p2;
  }
}

MassProperties finish(const Moments& m, const Vector3d& o) {
  MassProperties mp;
  mp.volume = m.v;
  if (m.v == 0.0) {
    mp.centroid = detail::vec_from_eigen(o);
    return mp;
  }
  const Vector3d c = m.s / m.v;
  const Matrix3d central = m.c - m.v * c * c.transpose();
  const Matrix3d inertia = central.trace() * Matrix3d::Identity() - central;
  mp.centroid = detail::vec_from_eigen(o + c);
  // Symmetric by construction; averaging removes the round-off asymmetry.
  mp.inertia = detail::mat_from_eigen(0.5 * (inertia + inertia.transpose()));
  return mp;
}

}  // namespace

double SteinerCoefficients::dilated_volume(double r) const {
  return volume + r * (area + r * (edge_term + r * 4.0 * kPi / 3.0));
}

MassProperties core_mass_properties(const ConvexPolyhedron& core) {
  const Vector3d o = reference_point(core);
  Moments m;
  add_core(core, o, m);
  return finish(m, o);
}

MassProperties dilated_mass_properties(const ConvexPolyhedron& core, double r) {
  if (!(r >= 0) || !std::isfinite(r)) {
    throw ShapeError("dilated_mass_properties: dilation radius " + detail::format_number(r) +
                     " must be finite and >= 0");
  }
  const Vector3d o = reference_point(core);
  Moments m;
  add_core(core, o, m);
  if (r > 0) {
    add_slabs(core, o, r, m);
    add_wedges(core, o, r, m);
    add_sectors(core, o, r, m);
  }
  return finish(m, o);
}

SteinerCoefficients steiner_coefficients(const ConvexPolyhedron& core) {
  SteinerCoefficients s;
  s.volume = core_mass_properties(core).volume;
  for (const Triangle& t : core.triangles()) {
    const Vector3d a = to_eigen(core.vertices()[std::size_t(t[0])]);
    const Vector3d b = to_eigen(core.vertices()[std::size_t(t[1])]);
    const Vector3d c = to_eigen(core.vertices()[std::size_t(t[2])]);
    s.area += 0.5 * (b - a).cross(c - a).norm();
  }
  for (const Edge& e : core.edges()) {
    const double len =
        (to_eigen(core.vertices()[std::size_t(e.b)]) - to_eigen(core.vertices()[std::size_t(e.a)]))
            .norm();
    s.edge_term += 0.5 * len * e.angle;
  }
  return s;
}

std::vector<double> vertex_solid_angles(const ConvexPolyhedron& core) {
  std::vector<double> omega(core.vertices().size());
  for (std::size_t v = 0; v < omega.size(); ++v) omega[v] = normal_cone(core, v).omega;
  return omega;
}

PrincipalFrame principal_frame(const Mat3& inertia) {
  const Eigen::SelfAdjointEigenSolver<Matrix3d> eig(to_eigen(inertia));
  Matrix3d axes = eig.eigenvectors();
  for (int k = 0; k < 2; ++k) {
    Eigen::Index i = 0;
    axes.col(k).cwiseAbs().maxCoeff(&i);
    if (axes(i, k) < 0) axes.col(k) *= -1.0;
  }
  axes.col(2) = axes.col(0).cross(axes.col(1));
  PrincipalFrame f;
  f.moments = detail::vec_from_eigen(eig.eigenvalues());
  f.axes = detail::mat_from_eigen(axes);
  return f;
}

}  // namespace demfem::dem::shapes
