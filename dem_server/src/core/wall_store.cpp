// The wall store (wall_store.hpp): the triangle store of all walls, their kinematics
// within a step, the triangles near each particle, and the loads the particles put on them.

#include "wall_store.hpp"

#include <omp.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <utility>
#include <vector>

#include "demfem/dem/physics/geometry.hpp"
#include "demfem/dem/physics/triangle_bins.hpp"
#include "demfem/dem/physics/wall_contact.hpp"

namespace demfem::dem::detail {

using phys::kMaxWallContacts;
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

void WallStore::build() {
  vertex_x.clear();
  vertex_v.clear();
  triangle_vertices.clear();
  triangle_wall.clear();
  triangle_material.clear();
  auto append = [&](Wall& w, std::int32_t widx) {
    w.first_vertex = static_cast<std::int64_t>(vertex_x.size() / 3);
    w.first_triangle = static_cast<std::int64_t>(triangle_vertices.size() / 3);
    vertex_x.insert(vertex_x.end(), w.mesh.vertices.begin(), w.mesh.vertices.end());
    for (std::size_t k = 0; k < w.mesh.triangles.size(); ++k)
      triangle_vertices.push_back(static_cast<std::int32_t>(w.first_vertex + w.mesh.triangles[k]));
    for (std::size_t k = 0; k < w.mesh.triangles.size() / 3; ++k) {
      triangle_wall.push_back(widx);
      triangle_material.push_back(w.mesh.material);
    }
  };
  for (std::size_t w = 0; w < rigid.size(); ++w) append(rigid[w], static_cast<std::int32_t>(w));
  if (has_flexible) {
    append(flexible, -1);
    if (flexible_x0.size() == flexible.mesh.vertices.size())
      std::copy(flexible_x0.begin(), flexible_x0.end(),
                vertex_x.begin() + 3 * flexible.first_vertex);
  }
  vertex_v.assign(vertex_x.size(), 0.0);
  vertex_x_at_build = vertex_x;
  // unique undirected edges
  const std::size_t ntri = triangle_vertices.size() / 3;
  std::vector<std::pair<std::pair<std::int32_t, std::int32_t>, std::int64_t>> edges;
  edges.reserve(3 * ntri);
  for (std::size_t k = 0; k < ntri; ++k)
    for (int e = 0; e < 3; ++e) {
      std::int32_t a = triangle_vertices[3 * k + e], b = triangle_vertices[3 * k + (e + 1) % 3];
      if (a > b) std::swap(a, b);
      edges.push_back({{a, b}, static_cast<std::int64_t>(3 * k + e)});
    }
  std::sort(edges.begin(), edges.end());
  triangle_edges.assign(3 * ntri, 0);
  std::int32_t id = -1;
  for (std::size_t k = 0; k < edges.size(); ++k) {
    if (k == 0 || edges[k].first != edges[k - 1].first) ++id;
    triangle_edges[edges[k].second] = id;
  }
  edge_count = static_cast<std::size_t>(id + 1);
  moving = has_flexible || !bodies.empty();
  motions.clear();
  force_limited = false;
  for (auto& w : rigid) {
    moving = moving || w.mesh.motion.kind != WallMotion::Kind::fixed;
    motions.push_back(rigid_motion(w.mesh.motion));
    force_limited = force_limited || w.mesh.motion.max_force > 0.0;
  }
  drift_time.resize(rigid.size(), 0.0);  // walls added later start at rest
  drift_rate.resize(rigid.size(), 1.0);
}

void WallStore::update(double tt, double tau) {
  for (std::size_t wi = 0; wi < rigid.size(); ++wi) {
    const Wall& w = rigid[wi];
    if (w.body >= 0) {
      bodies.place(w.body, vertex_x.data() + 3 * w.first_vertex,
                   vertex_v.data() + 3 * w.first_vertex);
      continue;
    }
    if (w.mesh.motion.kind == WallMotion::Kind::fixed) continue;
    const phys::RigidPose pose = motion_pose(wi, tt);
    const std::size_t nv = w.mesh.vertices.size() / 3;
    double* x = vertex_x.data() + 3 * w.first_vertex;
    double* v = vertex_v.data() + 3 * w.first_vertex;
    const double* x0 = w.mesh.vertices.data();
    for (std::size_t k = 0; k < nv; ++k) phys::rigid_vertex(pose, x0 + 3 * k, x + 3 * k, v + 3 * k);
  }
  if (has_flexible && flexible_x0.size() == flexible.mesh.vertices.size()) {
    const std::size_t nv = flexible.mesh.vertices.size() / 3;
    double* x = vertex_x.data() + 3 * flexible.first_vertex;
    double* v = vertex_v.data() + 3 * flexible.first_vertex;
    for (std::size_t k = 0; k < 3 * nv; ++k)
      phys::flexible_node(flexible_x0[k], flexible_v0[k], flexible_a0[k], tau, x[k], v[k]);
  }
}

phys::RigidPose WallStore::motion_pose(std::size_t wi, double tt) const {
  const phys::RigidMotion& m = motions[wi];
  return rigid[wi].mesh.motion.max_force > 0.0
             ? phys::rigid_pose(m, tt, drift_time[wi],
                                tt >= m.start_time && tt < m.end_time ? drift_rate[wi] : 0.0)
             : phys::rigid_pose(m, tt);
}

void WallStore::advance_drift(double t_end, double dt) {
  for (std::size_t wi = 0; wi < rigid.size(); ++wi) {
    const phys::RigidMotion& m = motions[wi];
    if (!(rigid[wi].mesh.motion.max_force > 0.0) || !(drift_rate[wi] > 0.0)) continue;
    const double lo = std::max(t_end - dt, m.start_time), hi = std::min(t_end, m.end_time);
    if (hi > lo) drift_time[wi] += drift_rate[wi] * (hi - lo);
  }
}

void WallStore::decide_drift() {
  for (std::size_t wi = 0; wi < rigid.size(); ++wi) {
    const WallMotion& m = rigid[wi].mesh.motion;
    if (!(m.max_force > 0.0)) continue;
    const double v = std::sqrt(m.velocity[0] * m.velocity[0] + m.velocity[1] * m.velocity[1] +
                               m.velocity[2] * m.velocity[2]);
    // the particles' force on the wall against its drift
    const auto& f = rigid[wi].force;
    const double resist = -(f[0] * m.velocity[0] + f[1] * m.velocity[1] + f[2] * m.velocity[2]) / v;
    // slower as the bed's resistance nears the limit: a step drift would ratchet on at full
    // speed whenever a bouncing bed let go, and end above the limit
    drift_rate[wi] = std::clamp(1.0 - resist / m.max_force, 0.0, 1.0);
  }
}

void WallStore::reset_drift() {
  std::fill(drift_time.begin(), drift_time.end(), 0.0);
  std::fill(drift_rate.begin(), drift_rate.end(), 1.0);
}

double WallStore::displacement() const {
  if (!moving) return 0.0;
  double m2 = 0.0;
  for (std::size_t k = 0; k < vertex_x.size(); k += 3) {
    const double dx = vertex_x[k] - vertex_x_at_build[k],
                 dy = vertex_x[k + 1] - vertex_x_at_build[k + 1],
                 dz = vertex_x[k + 2] - vertex_x_at_build[k + 2];
    m2 = std::max(m2, dx * dx + dy * dy + dz * dz);
  }
  return std::sqrt(m2);
}

void WallStore::bin_triangles(const phys::CellGrid& grid, const std::vector<std::int32_t>& cell,
                              const ListParticles& p, double rmax, double skin) {
  const auto np = static_cast<std::size_t>(p.n);
  const std::int64_t sn = p.n;
  const double* P[3] = {p.x, p.y, p.z};
  const double* R = p.radius;
  const std::int64_t* dim = grid.dim;
  const std::int64_t ncell = grid.cells();
  candidate_row.assign(np + 1, 0);
  candidate_triangle.clear();
  const std::size_t ntri = triangle_vertices.size() / 3;
  if (ntri > 0 && np > 0) {
    const double grow = rmax + skin;
    std::vector<std::int64_t> tcount(ncell + 1, 0);
    std::vector<std::array<std::int64_t, 6>> box(ntri);
    for (std::size_t k = 0; k < ntri; ++k) {
      if (!phys::triangle_cell_box(grid, vertex_x.data(), triangle_vertices.data() + 3 * k, grow,
                                   box[k].data()))
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
      return phys::near_triangle(Vec3{P[0][i], P[1][i], P[2][i]}, R[i], skin, vertex_x.data(),
                                 triangle_vertices.data() + 3 * k);
    };
#pragma omp parallel for num_threads(p.threads) schedule(static)
    for (std::int64_t i = 0; i < sn; ++i) {
      const std::int32_t c = cell[i];
      std::int64_t cnt = 0;
      for (std::int64_t k = tcount[c]; k < tcount[c + 1]; ++k)
        if (near(static_cast<std::size_t>(i), tbin[k])) ++cnt;
      candidate_row[i + 1] = cnt;
    }
    for (std::size_t i = 0; i < np; ++i) candidate_row[i + 1] += candidate_row[i];
    candidate_triangle.resize(static_cast<std::size_t>(candidate_row[np]));
#pragma omp parallel for num_threads(p.threads) schedule(static)
    for (std::int64_t i = 0; i < sn; ++i) {
      const std::int32_t c = cell[i];
      std::int64_t o = candidate_row[i];
      for (std::int64_t k = tcount[c]; k < tcount[c + 1]; ++k)
        if (near(static_cast<std::size_t>(i), tbin[k])) candidate_triangle[o++] = tbin[k];
    }
  }
}

void WallStore::reduce(const WallContactSlots& contacts, std::size_t n, bool last, ForceMode mode,
                       std::int64_t substeps) {
  for (auto& w : rigid) w.force = {0, 0, 0}, w.torque = {0, 0, 0};
  std::vector<double>& nodef = node_force_;  // member: no allocation per step
  if (has_flexible) nodef.assign(flexible.mesh.vertices.size(), 0.0);
  const WallContactSlots& wc = contacts;
  for (std::size_t i = 0; i < n; ++i)
    for (int c = 0; c < wc.count[i]; ++c) {
      const std::size_t slot = kMaxWallContacts * i + c;
      const std::int32_t tri = wc.triangle[slot];
      const std::int32_t w = triangle_wall[tri];
      // force ON the wall = - force on the particle
      const Vec3 f{-wc.force[3 * slot], -wc.force[3 * slot + 1], -wc.force[3 * slot + 2]};
      if (w >= 0) {
        const Vec3 x{wc.point[3 * slot], wc.point[3 * slot + 1], wc.point[3 * slot + 2]};
        const Vec3 q = phys::cross(x, f);
        auto& W = rigid[w];
        W.force[0] += f.x, W.force[1] += f.y, W.force[2] += f.z;
        W.torque[0] += q.x, W.torque[1] += q.y, W.torque[2] += q.z;
      } else {
        for (int e = 0; e < 3; ++e) {
          const std::int64_t node = triangle_vertices[3 * tri + e] - flexible.first_vertex;
          const Vec3 fb = phys::node_share(wc.weights[3 * slot + e], f);
          nodef[3 * node] += fb.x, nodef[3 * node + 1] += fb.y, nodef[3 * node + 2] += fb.z;
        }
      }
    }
  if (has_flexible) {
    if (mode == ForceMode::average) {
      const double inv = 1.0 / static_cast<double>(substeps);
      for (std::size_t k = 0; k < nodef.size(); ++k) flexible_force[k] += inv * nodef[k];
    } else if (last) {
      flexible_force = nodef;
    }
  }
}

}  // namespace demfem::dem::detail
