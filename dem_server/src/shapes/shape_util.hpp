#pragma once
// Helpers private to the shape library: Eigen conversions and message formatting.

#include <Eigen/Dense>
#include <cstdio>
#include <string>

#include "demfem/dem/shapes/convex_polyhedron.hpp"

namespace demfem::dem::shapes::detail {

inline Eigen::Vector3d to_eigen(const Vec3& v) {
  return {v[0], v[1], v[2]};
}
inline Vec3 vec_from_eigen(const Eigen::Vector3d& v) {
  return {v[0], v[1], v[2]};
}
inline Eigen::Matrix3d to_eigen(const Mat3& m) {
  Eigen::Matrix3d e;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) e(i, j) = m[std::size_t(i)][std::size_t(j)];
  return e;
}
inline Mat3 mat_from_eigen(const Eigen::Matrix3d& e) {
  Mat3 m{};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) m[std::size_t(i)][std::size_t(j)] = e(i, j);
  return m;
}

/// "(x, y, z)" with 9 significant digits.
inline std::string format_point(const Vec3& p) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "(%.9g, %.9g, %.9g)", p[0], p[1], p[2]);
  return buf;
}
/// A number with 9 significant digits.
inline std::string format_number(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.9g", x);
  return buf;
}

}  // namespace demfem::dem::shapes::detail
