#include "demfem/dem/shapes/mesh_body.hpp"

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>
#include <utility>

namespace demfem::dem::shapes {

MeshBodyProperties closed_mesh_properties(const std::vector<double>& vertices,
                                          const std::vector<std::int32_t>& triangles,
                                          double density, const std::string& name) {
  auto bad = [&](const std::string& what) {
    throw std::invalid_argument("rigid body '" + name + "': " + what);
  };
  if (!(density > 0.0) || !std::isfinite(density)) bad("density must be a finite number > 0");
  const std::size_t nv = vertices.size() / 3, nt = triangles.size() / 3;
  if (nt < 4) bad("a closed mesh needs at least 4 triangles");
  // Closed and consistently oriented: every directed edge once, its reverse once.
  std::map<std::pair<std::int32_t, std::int32_t>, int> directed;
  for (std::size_t t = 0; t < nt; ++t)
    for (int e = 0; e < 3; ++e) {
      const std::int32_t a = triangles[3 * t + e], b = triangles[3 * t + (e + 1) % 3];
      if (++directed[{a, b}] > 1) bad("the mesh is not consistently oriented or not manifold");
    }
  for (const auto& [edge, count] : directed)
    if (!directed.count({edge.second, edge.first}))
      bad("the mesh is not closed (edge " + std::to_string(edge.first) + "-" +
          std::to_string(edge.second) + " has one triangle)");
  using Eigen::Matrix3d;
  using Eigen::Vector3d;
  auto vert = [&](std::int32_t i) {
    return Vector3d(vertices[3 * std::size_t(i)], vertices[3 * std::size_t(i) + 1],
                    vertices[3 * std::size_t(i) + 2]);
  };
  Vector3d o = Vector3d::Zero();  // reference point: the vertex mean (no lost digits)
  for (std::size_t i = 0; i < nv; ++i) o += vert(std::int32_t(i));
  o /= double(nv);
  double vol = 0.0;
  Vector3d first = Vector3d::Zero();
  Matrix3d second = Matrix3d::Zero();  // ∫ x xᵀ dV relative to o
  for (std::size_t t = 0; t < nt; ++t) {
    const Vector3d a = vert(triangles[3 * t]) - o, b = vert(triangles[3 * t + 1]) - o,
                   c = vert(triangles[3 * t + 2]) - o;
    const double v = a.dot(b.cross(c)) / 6.0;
    const Vector3d s = a + b + c;
    vol += v;
    first += v * s / 4.0;
    second +=
        v / 20.0 * (a * a.transpose() + b * b.transpose() + c * c.transpose() + s * s.transpose());
  }
  if (vol < 0) vol = -vol, first = -first, second = -second;  // inward normals (a box wall)
  if (!(vol > 0.0)) bad("the mesh encloses no volume");
  const Vector3d cen = first / vol;
  const Matrix3d cc = second - vol * cen * cen.transpose();
  const Matrix3d inertia = density * (cc.trace() * Matrix3d::Identity() - cc);
  Eigen::SelfAdjointEigenSolver<Matrix3d> es(inertia);
  Matrix3d axes = es.eigenvectors();
  if (axes.determinant() < 0) axes.col(2) = -axes.col(2);  // right-handed
  const Eigen::Quaterniond q(axes);
  MeshBodyProperties p;
  p.volume = vol;
  p.mass = density * vol;
  const Vector3d world = cen + o;
  p.centre = {world.x(), world.y(), world.z()};
  p.moments = {es.eigenvalues()(0), es.eigenvalues()(1), es.eigenvalues()(2)};
  const Eigen::Quaterniond qn = q.normalized();
  p.orientation = {qn.w(), qn.x(), qn.y(), qn.z()};
  return p;
}

}  // namespace demfem::dem::shapes
