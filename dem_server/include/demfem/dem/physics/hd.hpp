#pragma once
// DEMFEM_HD marks the physics functions that both backends call: __host__ __device__ under
// nvcc, plain inline C++ otherwise. Vec3 is a minimal POD vector (no Eigen: these headers
// must compile under nvcc).

#include <cmath>

#if defined(__CUDACC__)
#define DEMFEM_HD __host__ __device__ __forceinline__
#elif defined(DEMFEM_PROFILE_NOINLINE)
// profiling builds only (-DDEMFEM_PROFILE_NOINLINE): each physics function shows in a profile
#define DEMFEM_HD inline __attribute__((noinline))
#elif defined(__GNUC__) || defined(__clang__)
// Forced inlining as on the device: the CPU pair loop is vectorised only when the whole
// contact law is inlined into it.
#define DEMFEM_HD inline __attribute__((always_inline))
#else
#define DEMFEM_HD inline
#endif

namespace demfem::dem::phys {

struct Vec3 {
  double x, y, z;
};

DEMFEM_HD Vec3 operator+(Vec3 a, Vec3 b) {
  return {a.x + b.x, a.y + b.y, a.z + b.z};
}
DEMFEM_HD Vec3 operator-(Vec3 a, Vec3 b) {
  return {a.x - b.x, a.y - b.y, a.z - b.z};
}
DEMFEM_HD Vec3 operator-(Vec3 a) {
  return {-a.x, -a.y, -a.z};
}
DEMFEM_HD Vec3 operator*(double s, Vec3 a) {
  return {s * a.x, s * a.y, s * a.z};
}
DEMFEM_HD double dot(Vec3 a, Vec3 b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}
DEMFEM_HD Vec3 cross(Vec3 a, Vec3 b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
DEMFEM_HD double norm2(Vec3 a) {
  return dot(a, a);
}

}  // namespace demfem::dem::phys
