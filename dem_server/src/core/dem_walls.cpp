// DemSystem walls: the store of all wall triangles (rigid walls, walls moved by their
// contact forces, the flexible interface mesh), their kinematics within a step, and the
// loads the particles put on them.

#include "dem_system_impl.hpp"
#include "demfem/dem/physics/triangle_bins.hpp"

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

namespace {

// POD copy of a wall's motion for the shared kinematics (physics/wall_motion.hpp).
phys::RigidMotion rigid_motion(const WallMotion& m) {
  phys::RigidMotion r{};
  r.kind = static_cast<int>(m.kind);
  for (int d = 0; d < 3; ++d)
    r.velocity[d] = m.velocity[d], r.axis_point[d] = m.axis_point[d], r.axis[d] = m.axis[d];
  r.angular_velocity = m.angular_velocity, r.amplitude = m.amplitude;
  r.frequency = m.frequency, r.phase = m.phase;
  r.start_time = m.start_time, r.end_time = m.end_time;
  return r;
}

}  // namespace

void DemSystem::Impl::build_wall_store() {
  vpos.clear();
  vvel.clear();
  tri_v.clear();
  tri_wall.clear();
  tri_mat.clear();
  auto append = [&](Wall& w, std::int32_t widx) {
    w.vbase = static_cast<std::int64_t>(vpos.size() / 3);
    w.tbase = static_cast<std::int64_t>(tri_v.size() / 3);
    vpos.insert(vpos.end(), w.mesh.vertices.begin(), w.mesh.vertices.end());
    for (std::size_t k = 0; k < w.mesh.triangles.size(); ++k)
      tri_v.push_back(static_cast<std::int32_t>(w.vbase + w.mesh.triangles[k]));
    for (std::size_t k = 0; k < w.mesh.triangles.size() / 3; ++k) {
      tri_wall.push_back(widx);
      tri_mat.push_back(w.mesh.material);
    }
  };
  for (std::size_t w = 0; w < walls.size(); ++w) append(walls[w], static_cast<std::int32_t>(w));
  if (has_flex) {
    append(flex, -1);
    if (flex_x.size() == flex.mesh.vertices.size())
      std::copy(flex_x.begin(), flex_x.end(), vpos.begin() + 3 * flex.vbase);
  }
  vvel.assign(vpos.size(), 0.0);
  vbuild = vpos;
  // unique undirected edges
  const std::size_t ntri = tri_v.size() / 3;
  std::vector<std::pair<std::pair<std::int32_t, std::int32_t>, std::int64_t>> edges;
  edges.reserve(3 * ntri);
  for (std::size_t k = 0; k < ntri; ++k)
    for (int e = 0; e < 3; ++e) {
      std::int32_t a = tri_v[3 * k + e], b = tri_v[3 * k + (e + 1) % 3];
      if (a > b) std::swap(a, b);
      edges.push_back({{a, b}, static_cast<std::int64_t>(3 * k + e)});
    }
  std::sort(edges.begin(), edges.end());
  tri_e.assign(3 * ntri, 0);
  std::int32_t id = -1;
  for (std::size_t k = 0; k < edges.size(); ++k) {
    if (k == 0 || edges[k].first != edges[k - 1].first) ++id;
    tri_e[edges[k].second] = id;
  }
  nedges = static_cast<std::size_t>(id + 1);
  walls_moving = has_flex || !bodies.empty();
  wall_motions.clear();
  force_limited = false;
  for (auto& w : walls) {
    walls_moving = walls_moving || w.mesh.motion.kind != WallMotion::Kind::fixed;
    wall_motions.push_back(rigid_motion(w.mesh.motion));
    force_limited = force_limited || w.mesh.motion.max_force > 0.0;
  }
  drift_time.resize(walls.size(), 0.0);  // walls added later start at rest
  drift_rate.resize(walls.size(), 1.0);
  walls_dirty = false;
  list.must_build = true;
}

void DemSystem::Impl::update_walls(double tt, double tau) {
  for (std::size_t wi = 0; wi < walls.size(); ++wi) {
    const Wall& w = walls[wi];
    if (w.body >= 0) {
      bodies.place(w.body, vpos.data() + 3 * w.vbase, vvel.data() + 3 * w.vbase);
      continue;
    }
    if (w.mesh.motion.kind == WallMotion::Kind::fixed) continue;
    const phys::RigidMotion& m = wall_motions[wi];
    const phys::RigidPose pose =
        w.mesh.motion.max_force > 0.0
            ? phys::rigid_pose(m, tt, drift_time[wi],
                               tt >= m.start_time && tt < m.end_time ? drift_rate[wi] : 0.0)
            : phys::rigid_pose(m, tt);
    const std::size_t nv = w.mesh.vertices.size() / 3;
    double* x = vpos.data() + 3 * w.vbase;
    double* v = vvel.data() + 3 * w.vbase;
    const double* x0 = w.mesh.vertices.data();
    for (std::size_t k = 0; k < nv; ++k) phys::rigid_vertex(pose, x0 + 3 * k, x + 3 * k, v + 3 * k);
  }
  if (has_flex && flex_x.size() == flex.mesh.vertices.size()) {
    const std::size_t nv = flex.mesh.vertices.size() / 3;
    double* x = vpos.data() + 3 * flex.vbase;
    double* v = vvel.data() + 3 * flex.vbase;
    for (std::size_t k = 0; k < 3 * nv; ++k)
      phys::flexible_node(flex_x[k], flex_v[k], flex_a[k], tau, x[k], v[k]);
  }
}

void DemSystem::Impl::advance_drift(double t_end) {
  for (std::size_t wi = 0; wi < walls.size(); ++wi) {
    const phys::RigidMotion& m = wall_motions[wi];
    if (!(walls[wi].mesh.motion.max_force > 0.0) || !(drift_rate[wi] > 0.0)) continue;
    const double lo = std::max(t_end - s.dt, m.start_time), hi = std::min(t_end, m.end_time);
    if (hi > lo) drift_time[wi] += drift_rate[wi] * (hi - lo);
  }
}

void DemSystem::Impl::decide_drift() {
  for (std::size_t wi = 0; wi < walls.size(); ++wi) {
    const WallMotion& m = walls[wi].mesh.motion;
    if (!(m.max_force > 0.0)) continue;
    const double v = std::sqrt(m.velocity[0] * m.velocity[0] + m.velocity[1] * m.velocity[1] +
                               m.velocity[2] * m.velocity[2]);
    // the particles' force on the wall against its drift
    const auto& f = walls[wi].force;
    const double resist = -(f[0] * m.velocity[0] + f[1] * m.velocity[1] + f[2] * m.velocity[2]) / v;
    // slower as the bed's resistance nears the limit: a step drift would ratchet on at full
    // speed whenever a bouncing bed let go, and end above the limit
    drift_rate[wi] = std::clamp(1.0 - resist / m.max_force, 0.0, 1.0);
  }
}

void DemSystem::Impl::reset_drift() {
  std::fill(drift_time.begin(), drift_time.end(), 0.0);
  std::fill(drift_rate.begin(), drift_rate.end(), 1.0);
}

double DemSystem::Impl::wall_displacement() const {
  if (!walls_moving) return 0.0;
  double m2 = 0.0;
  for (std::size_t k = 0; k < vpos.size(); k += 3) {
    const double dx = vpos[k] - vbuild[k], dy = vpos[k + 1] - vbuild[k + 1],
                 dz = vpos[k + 2] - vbuild[k + 2];
    m2 = std::max(m2, dx * dx + dy * dy + dz * dz);
  }
  return std::sqrt(m2);
}

void DemSystem::Impl::bin_wall_triangles(const phys::CellGrid& grid,
                                         const std::vector<std::int32_t>& cell) {
  const std::size_t np = n();
  const std::int64_t sn = static_cast<std::int64_t>(np);
  const double* P[3] = {st.px.data(), st.py.data(), st.pz.data()};
  const double* R = st.radius.data();
  const std::int64_t* dim = grid.dim;
  const std::int64_t ncell = grid.cells();
  prow.assign(np + 1, 0);
  ptri.clear();
  const std::size_t ntri = tri_v.size() / 3;
  if (ntri > 0 && np > 0) {
    const double grow = rmax + list.skin;
    std::vector<std::int64_t> tcount(ncell + 1, 0);
    std::vector<std::array<std::int64_t, 6>> box(ntri);
    for (std::size_t k = 0; k < ntri; ++k) {
      if (!phys::triangle_cell_box(grid, vpos.data(), tri_v.data() + 3 * k, grow, box[k].data()))
        box[k][0] = -1;
      else
        for (std::int64_t z = box[k][2]; z <= box[k][5]; ++z)
          for (std::int64_t y = box[k][1]; y <= box[k][4]; ++y)
            for (std::int64_t x = box[k][0]; x <= box[k][3]; ++x)
              ++tcount[(z * dim[1] + y) * dim[0] + x + 1];
    }
    for (std::int64_t c = 0; c < ncell; ++c) tcount[c + 1] += tcount[c];
    std::vector<std::int32_t> tbin(static_cast<std::size_t>(tcount[ncell]));
    {
      std::vector<std::int64_t> fill(tcount.begin(), tcount.end() - 1);
      for (std::size_t k = 0; k < ntri; ++k) {
        if (box[k][0] < 0) continue;
        for (std::int64_t z = box[k][2]; z <= box[k][5]; ++z)
          for (std::int64_t y = box[k][1]; y <= box[k][4]; ++y)
            for (std::int64_t x = box[k][0]; x <= box[k][3]; ++x)
              tbin[fill[(z * dim[1] + y) * dim[0] + x]++] = static_cast<std::int32_t>(k);
      }
    }
    auto near = [&](std::size_t i, std::int32_t k) {
      return phys::near_triangle(Vec3{P[0][i], P[1][i], P[2][i]}, R[i], list.skin, vpos.data(),
                                 tri_v.data() + 3 * k);
    };
#pragma omp parallel for num_threads(nt()) schedule(static)
    for (std::int64_t i = 0; i < sn; ++i) {
      const std::int32_t c = cell[i];
      std::int64_t cnt = 0;
      for (std::int64_t k = tcount[c]; k < tcount[c + 1]; ++k)
        if (near(static_cast<std::size_t>(i), tbin[k])) ++cnt;
      prow[i + 1] = cnt;
    }
    for (std::size_t i = 0; i < np; ++i) prow[i + 1] += prow[i];
    ptri.resize(static_cast<std::size_t>(prow[np]));
#pragma omp parallel for num_threads(nt()) schedule(static)
    for (std::int64_t i = 0; i < sn; ++i) {
      const std::int32_t c = cell[i];
      std::int64_t o = prow[i];
      for (std::int64_t k = tcount[c]; k < tcount[c + 1]; ++k)
        if (near(static_cast<std::size_t>(i), tbin[k])) ptri[o++] = tbin[k];
    }
  }
}

void DemSystem::Impl::wall_reduce(bool last, ForceMode mode, std::int64_t substeps) {
  for (auto& w : walls) w.force = {0, 0, 0}, w.torque = {0, 0, 0};
  std::vector<double>& nodef = node_buf;  // member: no allocation per step
  if (has_flex) nodef.assign(flex.mesh.vertices.size(), 0.0);
  const std::size_t np = n();
  const detail::WallContactSlots& wc = wall_contacts;
  for (std::size_t i = 0; i < np; ++i)
    for (int c = 0; c < wc.count[i]; ++c) {
      const std::size_t slot = kMaxWallContacts * i + c;
      const std::int32_t tri = wc.triangle[slot];
      const std::int32_t w = tri_wall[tri];
      // force ON the wall = - force on the particle
      const Vec3 f{-wc.force[3 * slot], -wc.force[3 * slot + 1], -wc.force[3 * slot + 2]};
      if (w >= 0) {
        const Vec3 x{wc.point[3 * slot], wc.point[3 * slot + 1], wc.point[3 * slot + 2]};
        const Vec3 q = phys::cross(x, f);
        auto& W = walls[w];
        W.force[0] += f.x, W.force[1] += f.y, W.force[2] += f.z;
        W.torque[0] += q.x, W.torque[1] += q.y, W.torque[2] += q.z;
      } else {
        for (int e = 0; e < 3; ++e) {
          const std::int64_t node = tri_v[3 * tri + e] - flex.vbase;
          const Vec3 fb = phys::node_share(wc.weights[3 * slot + e], f);
          nodef[3 * node] += fb.x, nodef[3 * node + 1] += fb.y, nodef[3 * node + 2] += fb.z;
        }
      }
    }
  if (has_flex) {
    if (mode == ForceMode::average) {
      const double inv = 1.0 / static_cast<double>(substeps);
      for (std::size_t k = 0; k < nodef.size(); ++k) flex_force[k] += inv * nodef[k];
    } else if (last) {
      flex_force = nodef;
    }
  }
}

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
  if (wall.material < 0 || static_cast<std::size_t>(wall.material) >= I.nmat)
    bad(where + ": material " + std::to_string(wall.material) + " outside [0, " +
        std::to_string(I.nmat) + ")");
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
    if (I.gpu != nullptr || I.s.backend != DemBackendKind::cpu)
      bad(where +
          ": a force-limited wall (motion.max_force) runs on the CPU backend only (the CUDA "
          "backend moves walls on the device without their forces)");
  }
  Impl::Wall w;
  if (wall.body.enabled) {
    if (I.gpu != nullptr || I.s.backend != DemBackendKind::cpu)
      bad(where +
          ": rigid bodies moved by contact forces run on the CPU backend only (the CUDA "
          "backend has no kernel for them yet)");
    w.body = I.bodies.add(wall, I.s.gravity, where);
  }
  w.mesh = std::move(wall);
  I.walls.push_back(std::move(w));
  I.build_wall_store();
  I.update_walls(I.t, I.flex_tau);
  I.vbuild = I.vpos;
  return static_cast<std::int32_t>(I.walls.size() - 1);
}

std::size_t DemSystem::wall_count() const {
  return impl_->walls.size();
}

#define check_wall(I, wall)                                                                   \
  if ((wall) < 0 || static_cast<std::size_t>(wall) >= (I).walls.size())                       \
  throw std::out_of_range("DemSystem: wall index " + std::to_string(wall) + " outside [0, " + \
                          std::to_string((I).walls.size()) + ")")

std::array<double, 3> DemSystem::wall_force(std::int32_t wall) const {
  check_wall(*impl_, wall);
  return impl_->walls[wall].force;
}
WallFaceLoad DemSystem::wall_face_load(std::int32_t wall,
                                       const std::array<double, 3>& direction) const {
  check_wall(*impl_, wall);
  const auto& I = *impl_;
  const auto& w = I.walls[wall];
  const double dl = std::sqrt(direction[0] * direction[0] + direction[1] * direction[1] +
                              direction[2] * direction[2]);
  if (!(dl > 0)) bad("wall_face_load: direction must not be zero");
  const Vec3 d{direction[0] / dl, direction[1] / dl, direction[2] / dl};
  auto vertex = [&I](std::int64_t v) {
    return Vec3{I.vpos[3 * v], I.vpos[3 * v + 1], I.vpos[3 * v + 2]};
  };
  const auto nv = static_cast<std::int64_t>(w.mesh.vertices.size() / 3);
  const auto nt = static_cast<std::int64_t>(w.mesh.triangles.size() / 3);
  Vec3 c{0, 0, 0};
  for (std::int64_t v = 0; v < nv; ++v) c = c + vertex(w.vbase + v);
  c = (1.0 / static_cast<double>(nv)) * c;
  // The face: triangles normal to `direction` (either winding) on its side of the centroid.
  std::vector<std::uint8_t> on_face(static_cast<std::size_t>(nt), 0);
  WallFaceLoad load;
  for (std::int64_t k = 0; k < nt; ++k) {
    const std::int64_t t = w.tbase + k;
    const Vec3 a = vertex(I.tri_v[3 * t]), b = vertex(I.tri_v[3 * t + 1]),
               e = vertex(I.tri_v[3 * t + 2]);
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
      const std::int64_t t = wc.triangle[slot] - w.tbase;
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
  return impl_->walls[wall].torque;
}
std::vector<double> DemSystem::wall_vertices(std::int32_t wall) const {
  check_wall(*impl_, wall);
  const auto& I = *impl_;
  const auto& w = I.walls[wall];
  return {I.vpos.begin() + 3 * w.vbase, I.vpos.begin() + 3 * w.vbase + w.mesh.vertices.size()};
}

RigidBodyState DemSystem::body_state(std::int32_t wall) const {
  check_wall(*impl_, wall);
  const auto& w = impl_->walls[wall];
  if (w.body < 0)
    throw std::invalid_argument("DemSystem: wall " + std::to_string(wall) + " (" + w.mesh.name +
                                ") is not a rigid body");
  return impl_->bodies.state(w.body);
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
  if (material < 0 || static_cast<std::size_t>(material) >= I.nmat)
    bad("set_flexible_mesh: material " + std::to_string(material) + " outside [0, " +
        std::to_string(I.nmat) + ")");
  I.flex = {};
  I.flex.mesh.name = "flexible";
  I.flex.mesh.vertices = mesh.reference_positions;
  I.flex.mesh.triangles = mesh.triangles;
  I.flex.mesh.material = material;
  I.flex.flexible = true;
  I.has_flex = true;
  I.flex_x = mesh.reference_positions;
  I.flex_v.assign(I.flex_x.size(), 0.0);
  I.flex_a.assign(I.flex_x.size(), 0.0);
  I.flex_force.assign(I.flex_x.size(), 0.0);
  I.flex_tau = 0.0;
  I.build_wall_store();
  I.update_walls(I.t, 0.0);
  I.vbuild = I.vpos;
}

bool DemSystem::has_flexible_mesh() const {
  return impl_->has_flex;
}

void DemSystem::set_flexible_kinematics(std::span<const double> positions,
                                        std::span<const double> velocities,
                                        std::span<const double> accelerations) {
  auto& I = *impl_;
  if (!I.has_flex) bad("set_flexible_kinematics: no flexible mesh set");
  const std::size_t n3 = I.flex_x.size();
  if (positions.size() != n3 || velocities.size() != n3 || accelerations.size() != n3)
    bad("set_flexible_kinematics: arrays must have 3 * node_count = " + std::to_string(n3) +
        " entries");
  for (std::size_t k = 0; k < n3; ++k)
    if (!std::isfinite(positions[k]) || !std::isfinite(velocities[k]) ||
        !std::isfinite(accelerations[k]))
      bad("set_flexible_kinematics: non-finite value at entry " + std::to_string(k));
  I.flex_x.assign(positions.begin(), positions.end());
  I.flex_v.assign(velocities.begin(), velocities.end());
  I.flex_a.assign(accelerations.begin(), accelerations.end());
  I.flex_tau = 0.0;
  I.update_walls(I.t, 0.0);
}

void DemSystem::flexible_forces(std::span<double> forces) const {
  const auto& I = *impl_;
  if (!I.has_flex) bad("flexible_forces: no flexible mesh set");
  if (forces.size() != I.flex_force.size())
    bad("flexible_forces: output must have 3 * node_count = " +
        std::to_string(I.flex_force.size()) + " entries");
  std::copy(I.flex_force.begin(), I.flex_force.end(), forces.begin());
}

std::vector<double> DemSystem::flexible_positions() const {
  const auto& I = *impl_;
  if (!I.has_flex) return {};
  return {I.vpos.begin() + 3 * I.flex.vbase, I.vpos.begin() + 3 * I.flex.vbase + I.flex_x.size()};
}

double DemSystem::flexible_max_overlap() const {
  return impl_->flex_max_ov;
}

}  // namespace demfem::dem
