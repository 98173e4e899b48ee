#pragma once
// The walls of the CPU backend (DemSystem::Impl::walls): every wall triangle in one store
// (rigid walls first, in the order they were added, then the flexible interface mesh), the
// walls' kinematics within a step, the triangles near each particle (binned into the
// neighbour list's grid at each build) and the loads the particles put on the walls.
// DemSystem's wall API (dem_walls.cpp) adds walls and reads their loads; the step
// (dem_step.cpp) moves them and sums their loads; the CUDA bridge hands the store to the
// device. The kinematics are those of physics/wall_motion.hpp, shared with the device.

#include <array>
#include <cstdint>
#include <vector>

#include "demfem/dem/dem_system.hpp"
#include "demfem/dem/physics/grid_cell.hpp"
#include "demfem/dem/physics/wall_motion.hpp"
#include "neighbour_list.hpp"
#include "rigid_mesh_bodies.hpp"
#include "wall_contact_slots.hpp"

namespace demfem::dem::detail {

class WallStore {
 public:
  struct Wall {
    WallMesh mesh;  // as added (its vertices: the reference pose of a moving wall)
    std::int64_t first_vertex = 0, first_triangle = 0;  // offsets in the store
    std::array<double, 3> force{}, torque{};  // the particles' load on it, N, N m (about 0)
    bool flexible = false;
    int body = -1;  // index in `bodies` when the wall is moved by its contact forces
  };

  // ---- the walls
  std::vector<Wall> rigid;  // rigid walls (fixed, moved by a motion, or bodies), as added
  RigidMeshBodies bodies;   // walls moved by their contact forces (rigid_mesh_bodies.hpp)
  bool has_flexible = false;
  Wall flexible;  // the flexible interface mesh (has_flexible)
  // The flexible mesh's nodes at the start of the advance() (set_flexible_kinematics), 3 per
  // node: positions (m), velocities (m/s), accelerations (m/s^2); its nodes move from them
  // by phys::flexible_node over flexible_tau, the time since that start (s).
  std::vector<double> flexible_x0, flexible_v0, flexible_a0;
  double flexible_tau = 0.0;
  std::vector<double> flexible_force;  // 3 per node, N, as ForceMode asked
  double flexible_max_overlap = 0.0;   // m

  // ---- the triangle store (global vertex and triangle indices)
  std::vector<double> vertex_x, vertex_v;       // 3 per vertex: positions (m), velocities (m/s)
  std::vector<double> vertex_x_at_build;        // 3 per vertex: positions at the list's last build
  std::vector<std::int32_t> triangle_vertices;  // 3 per triangle
  std::vector<std::int32_t> triangle_edges;     // 3 per triangle: edge ids unique in the store
  std::vector<std::int32_t> triangle_wall;      // wall index in `rigid`, -1 = flexible mesh
  std::vector<std::int32_t> triangle_material;
  std::vector<phys::RigidMotion> motions;  // per rigid wall: its motion, for both backends
  std::size_t edge_count = 0;
  bool moving = false;  // some wall moves (a motion, a body, the flexible mesh)
  // Force-limited drift (WallMotion::max_force), per wall: the seconds its drift has
  // advanced, and the fraction of its velocity it advances at in the next step,
  // 1 - R / max_force in [0, 1] (R: the particles' push against it in the last one). Saved
  // with the state.
  std::vector<double> drift_time;
  std::vector<double> drift_rate;
  bool force_limited = false;  // some wall has a max_force

  // ---- the triangles near each particle (CSR, built with the neighbour list)
  std::vector<std::int64_t> candidate_row;       // n + 1
  std::vector<std::int32_t> candidate_triangle;  // triangle index of each entry

  std::size_t triangles() const { return triangle_vertices.size() / 3; }
  bool empty() const { return triangle_vertices.empty(); }

  // The store from the walls: vertices, triangles, unique undirected edge ids (so that a
  // contact at an edge or a vertex shared by neighbouring triangles is counted once), the
  // motions. The neighbour list must be rebuilt after it (the caller says so).
  void build();

  // Vertex positions and velocities of the walls at time t (tau: time into the advance()),
  // by the kinematics shared with the CUDA backend (physics/wall_motion.hpp).
  void update(double t, double tau);
  // The pose of rigid wall `wi`'s motion at time t, with its drift as it stands (a wall
  // with a motion, not a body); what update() places its vertices by.
  phys::RigidPose motion_pose(std::size_t wi, double t) const;

  // Force-limited walls: advance the drift over the step of `dt` that ends at t_end (before
  // update), and decide from this step's wall forces whether it goes on (after reduce).
  void advance_drift(double t_end, double dt);
  void decide_drift();
  void reset_drift();

  // The largest vertex displacement since the list's last build, m (0 unless walls move).
  double displacement() const;

  // The triangles near each particle (candidate_row, candidate_triangle): binned into the
  // cells of the list's grid (`cell`: each particle's) that their box grown by rmax + skin
  // touches, kept where phys::near_triangle says the particle may reach them.
  void bin_triangles(const phys::CellGrid& grid, const std::vector<std::int32_t>& cell,
                     const ListParticles& p, double rmax, double skin);

  // Per-wall force and torque (at the last substep of an advance()) and the flexible node
  // forces (as `mode` asks) from the wall contact slots of n particles, serial, in particle
  // and slot order.
  void reduce(const WallContactSlots& contacts, std::size_t n, bool last, ForceMode mode,
              std::int64_t substeps);

 private:
  std::vector<double> node_force_;  // per node, the current substep's (no allocation per step)
};

}  // namespace demfem::dem::detail
