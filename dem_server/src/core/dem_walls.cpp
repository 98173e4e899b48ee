// DemSystem's wall API: rigid walls, walls moved by their contact forces and the flexible
// interface mesh added to the wall store (DemSystem::Impl::walls, wall_store.hpp), and their
// loads, poses and the flexible node forces read from it.

#include "dem_system_impl.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace demfem::dem {

using detail::bad;
using detail::kMaxWallContacts;
using phys::Vec3;

std::int32_t DemSystem::add_wall(WallMesh wall) {
  auto& I = *impl_;
  const std::string where = "add_wall('" + wall.name + "')";
  if (wall.vertices.size() % 3 != 0) bad(where + ": vertices size is not a multiple of 3");
  if (wall.triangles.size() % 3 != 0) bad(where + ": triangles size is not a multiple of 3");
  for (double x : wall.vertices)
    if (!std::isfinite(x)) bad(where + ": non-finite vertex coordinate");
  const auto nv = static_cast<std::int32_t>(wall.vertices.size() / 3);
  for (auto t : wall.triangles)
    if (t < 0 || t >= nv)
      bad(where + ": triangle vertex index " + std::to_string(t) + " outside [0, " +
          std::to_string(nv) + ")");
  if (wall.material < 0 || static_cast<std::size_t>(wall.material) >= I.material_count)
    bad(where + ": material " + std::to_string(wall.material) + " outside [0, " +
        std::to_string(I.material_count) + ")");
  const auto& m = wall.motion;
  if (!(m.end_time >= m.start_time)) bad(where + ": motion.end_time < motion.start_time");
  if (m.kind == WallMotion::Kind::rotation || m.kind == WallMotion::Kind::sinusoid) {
    const double a =
        std::sqrt(m.axis[0] * m.axis[0] + m.axis[1] * m.axis[1] + m.axis[2] * m.axis[2]);
    if (!(a > 0.0)) bad(where + ": motion.axis must be non-zero");
    if (m.kind == WallMotion::Kind::sinusoid)
      for (double& c : wall.motion.axis) c /= a;
  }
  if (m.max_force != 0.0) {
    if (!(m.max_force > 0.0) || !std::isfinite(m.max_force))
      bad(where + ": motion.max_force must be > 0 N (0: no limit)");
    if (m.kind != WallMotion::Kind::translation && m.kind != WallMotion::Kind::sinusoid)
      bad(where + ": motion.max_force limits a drift: a translation or a sinusoid's velocity");
    if (m.velocity[0] == 0.0 && m.velocity[1] == 0.0 && m.velocity[2] == 0.0)
      bad(where + ": motion.max_force needs a non-zero motion.velocity (the drift it limits)");
  }
  detail::WallStore::Wall w;
  if (wall.body.enabled) {
    w.body = I.walls.bodies.add(wall, I.s.gravity, where);
  }
  w.mesh = std::move(wall);
  I.walls.rigid.push_back(std::move(w));
  I.walls.build();
  I.list.must_build = true;
  I.walls.update(I.t, I.walls.flexible_tau);
  I.walls.vertex_x_at_build = I.walls.vertex_x;
  return static_cast<std::int32_t>(I.walls.rigid.size() - 1);
}

std::size_t DemSystem::wall_count() const {
  return impl_->walls.rigid.size();
}

#define check_wall(I, wall)                                                                   \
  if ((wall) < 0 || static_cast<std::size_t>(wall) >= (I).walls.rigid.size())                 \
  throw std::out_of_range("DemSystem: wall index " + std::to_string(wall) + " outside [0, " + \
                          std::to_string((I).walls.rigid.size()) + ")")

std::array<double, 3> DemSystem::wall_force(std::int32_t wall) const {
  check_wall(*impl_, wall);
  return impl_->walls.rigid[wall].force;
}
WallFaceLoad DemSystem::wall_face_load(std::int32_t wall,
                                       const std::array<double, 3>& direction) const {
  check_wall(*impl_, wall);
  const auto& I = *impl_;
  const auto& w = I.walls.rigid[wall];
  const double dl = std::sqrt(direction[0] * direction[0] + direction[1] * direction[1] +
                              direction[2] * direction[2]);
  if (!(dl > 0)) bad("wall_face_load: direction must not be zero");
  const Vec3 d{direction[0] / dl, direction[1] / dl, direction[2] / dl};
  auto vertex = [&I](std::int64_t v) {
    return Vec3{I.walls.vertex_x[3 * v], I.walls.vertex_x[3 * v + 1], I.walls.vertex_x[3 * v + 2]};
  };
  const auto nv = static_cast<std::int64_t>(w.mesh.vertices.size() / 3);
  const auto nt = static_cast<std::int64_t>(w.mesh.triangles.size() / 3);
  Vec3 c{0, 0, 0};
  for (std::int64_t v = 0; v < nv; ++v) c = c + vertex(w.first_vertex + v);
  c = (1.0 / static_cast<double>(nv)) * c;
  // The face: triangles normal to `direction` (either winding) on its side of the centroid.
  std::vector<std::uint8_t> on_face(static_cast<std::size_t>(nt), 0);
  WallFaceLoad load;
  for (std::int64_t k = 0; k < nt; ++k) {
    const std::int64_t t = w.first_triangle + k;
    const Vec3 a = vertex(I.walls.triangle_vertices[3 * t]),
               b = vertex(I.walls.triangle_vertices[3 * t + 1]),
               e = vertex(I.walls.triangle_vertices[3 * t + 2]);
    const Vec3 n = phys::cross(b - a, e - a);
    const double ln = std::sqrt(phys::dot(n, n));
    const Vec3 g = (1.0 / 3.0) * (a + b + e);
    const bool face =
        ln > 0 && std::abs(phys::dot(n, d)) > (1.0 - 1e-6) * ln && phys::dot(g - c, d) > 0;
    on_face[static_cast<std::size_t>(k)] = face;
    if (face) load.area += 0.5 * ln;
  }
  auto& f = load.force;
  const detail::WallContactSlots& wc = I.wall_contacts;
  for (std::size_t i = 0; i < I.n(); ++i)
    for (int k = 0; k < wc.count[i]; ++k) {
      const std::size_t slot = kMaxWallContacts * i + k;
      const std::int64_t t = wc.triangle[slot] - w.first_triangle;
      if (t < 0 || t >= nt || !on_face[static_cast<std::size_t>(t)]) continue;
      // force ON the wall; a contact at the face's edge that pulls it outwards (a particle
      // beside the wall, below the face's plane) is not a load on the face
      const Vec3 fw{-wc.force[3 * slot], -wc.force[3 * slot + 1], -wc.force[3 * slot + 2]};
      if (phys::dot(fw, d) > 0) continue;
      f[0] += fw.x, f[1] += fw.y, f[2] += fw.z;
    }
  return load;
}
std::array<double, 3> DemSystem::wall_torque(std::int32_t wall) const {
  check_wall(*impl_, wall);
  return impl_->walls.rigid[wall].torque;
}
std::vector<double> DemSystem::wall_vertices(std::int32_t wall) const {
  check_wall(*impl_, wall);
  const auto& I = *impl_;
  const auto& w = I.walls.rigid[wall];
  return {I.walls.vertex_x.begin() + 3 * w.first_vertex,
          I.walls.vertex_x.begin() + 3 * w.first_vertex + w.mesh.vertices.size()};
}

std::vector<double> DemSystem::wall_vertices_at_clock(std::int32_t wall) const {
  check_wall(*impl_, wall);
  const auto& I = *impl_;
  const auto& w = I.walls.rigid[wall];
  if (w.body >= 0 || w.mesh.motion.kind == WallMotion::Kind::fixed) return wall_vertices(wall);
  const phys::RigidPose pose = I.walls.motion_pose(static_cast<std::size_t>(wall), I.t);
  std::vector<double> x(w.mesh.vertices.size()), v(w.mesh.vertices.size());
  for (std::size_t k = 0; k < x.size(); k += 3)
    phys::rigid_vertex(pose, w.mesh.vertices.data() + k, x.data() + k, v.data() + k);
  return x;
}

RigidBodyState DemSystem::body_state(std::int32_t wall) const {
  check_wall(*impl_, wall);
  const auto& w = impl_->walls.rigid[wall];
  if (w.body < 0)
    throw std::invalid_argument("DemSystem: wall " + std::to_string(wall) + " (" + w.mesh.name +
                                ") is not a rigid body");
  return impl_->walls.bodies.state(w.body);
}

void DemSystem::set_flexible_mesh(const InterfaceMesh& mesh, std::int32_t material) {
  auto& I = *impl_;
  const auto nv = static_cast<std::int32_t>(mesh.node_count());
  if (mesh.reference_positions.size() % 3 != 0 || mesh.triangles.size() % 3 != 0)
    bad("set_flexible_mesh: array sizes are not multiples of 3");
  for (auto t : mesh.triangles)
    if (t < 0 || t >= nv)
      bad("set_flexible_mesh: node index " + std::to_string(t) + " outside [0, " +
          std::to_string(nv) + ")");
  if (material < 0 || static_cast<std::size_t>(material) >= I.material_count)
    bad("set_flexible_mesh: material " + std::to_string(material) + " outside [0, " +
        std::to_string(I.material_count) + ")");
  I.walls.flexible = {};
  I.walls.flexible.mesh.name = "flexible";
  I.walls.flexible.mesh.vertices = mesh.reference_positions;
  I.walls.flexible.mesh.triangles = mesh.triangles;
  I.walls.flexible.mesh.material = material;
  I.walls.flexible.flexible = true;
  I.walls.has_flexible = true;
  I.walls.flexible_x0 = mesh.reference_positions;
  I.walls.flexible_v0.assign(I.walls.flexible_x0.size(), 0.0);
  I.walls.flexible_a0.assign(I.walls.flexible_x0.size(), 0.0);
  I.walls.flexible_force.assign(I.walls.flexible_x0.size(), 0.0);
  I.walls.flexible_tau = 0.0;
  I.walls.build();
  I.list.must_build = true;
  I.walls.update(I.t, 0.0);
  I.walls.vertex_x_at_build = I.walls.vertex_x;
}

bool DemSystem::has_flexible_mesh() const {
  return impl_->walls.has_flexible;
}

void DemSystem::set_flexible_kinematics(std::span<const double> positions,
                                        std::span<const double> velocities,
                                        std::span<const double> accelerations) {
  auto& I = *impl_;
  if (!I.walls.has_flexible) bad("set_flexible_kinematics: no flexible mesh set");
  const std::size_t n3 = I.walls.flexible_x0.size();
  if (positions.size() != n3 || velocities.size() != n3 || accelerations.size() != n3)
    bad("set_flexible_kinematics: arrays must have 3 * node_count = " + std::to_string(n3) +
        " entries");
  for (std::size_t k = 0; k < n3; ++k)
    if (!std::isfinite(positions[k]) || !std::isfinite(velocities[k]) ||
        !std::isfinite(accelerations[k]))
      bad("set_flexible_kinematics: non-finite value at entry " + std::to_string(k));
  I.walls.flexible_x0.assign(positions.begin(), positions.end());
  I.walls.flexible_v0.assign(velocities.begin(), velocities.end());
  I.walls.flexible_a0.assign(accelerations.begin(), accelerations.end());
  I.walls.flexible_tau = 0.0;
  I.walls.update(I.t, 0.0);
}

void DemSystem::flexible_forces(std::span<double> forces) const {
  const auto& I = *impl_;
  if (!I.walls.has_flexible) bad("flexible_forces: no flexible mesh set");
  if (forces.size() != I.walls.flexible_force.size())
    bad("flexible_forces: output must have 3 * node_count = " +
        std::to_string(I.walls.flexible_force.size()) + " entries");
  std::copy(I.walls.flexible_force.begin(), I.walls.flexible_force.end(), forces.begin());
}

std::vector<double> DemSystem::flexible_positions() const {
  const auto& I = *impl_;
  if (!I.walls.has_flexible) return {};
  return {
      I.walls.vertex_x.begin() + 3 * I.walls.flexible.first_vertex,
      I.walls.vertex_x.begin() + 3 * I.walls.flexible.first_vertex + I.walls.flexible_x0.size()};
}

double DemSystem::flexible_max_overlap() const {
  return impl_->walls.flexible_max_overlap;
}

}  // namespace demfem::dem
