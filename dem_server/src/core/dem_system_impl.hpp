// DemSystem::Impl, the DEM engine behind DemSystem (dem_system.hpp): state, contact
// detection, walls and the CPU (OpenMP) backend. Private to src/core. It holds its parts as
// classes of their own: the neighbour list (neighbour_list.hpp), the per-pair slots
// (pair_slots.hpp), the wall store (wall_store.hpp) and the wall contact slots
// (wall_contact_slots.hpp). Its member functions live by concern in dem_system.cpp (setup,
// particles), dem_step.cpp (the list update, force pass and integration), dem_walls.cpp
// (DemSystem's wall API), dem_gpu_bridge.cpp (the CUDA backend's host side),
// dem_periodic.cpp (periodic boundaries: the wrap, tiling) and dem_state_io.cpp (save /
// restore). The physics (contact law, integrator, triangle geometry, the step integrator)
// comes from include/demfem/dem/physics/*.hpp, shared with the CUDA backend.
//
// Step structure (velocity Verlet, see physics/integrator.hpp):
//   1. per particle: half kick with the last force, drift, max displacement since the last
//      list update
//   2. walls: vertex positions/velocities at the new time (moving walls, flexible mesh)
//   3. pair list: refiltered from the grid build's candidates when the two largest
//      displacements since the last update may have closed the list skin, built from the
//      grid when the candidates may no longer hold every pair that can touch (two levels,
//      see neighbour_list.hpp and step())
//   4. per particle i (parallel): forces of the pairs (i, j > i) of its CSR row, written to
//      per-pair slots
//   5. per particle (parallel): own-row slots + transposed pair slots (fixed order) + walls +
//      gravity, second half kick
//   6. walls (serial, fixed order, at the last substep of an advance() or for averaged
//      flexible node forces): per-wall force/torque and flexible node forces
// No floating-point atomics: every sum has a fixed order independent of the thread count, so
// the result is bitwise identical for any number of threads.

#pragma once

#include <algorithm>
#include <array>
#include <atomic>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "dem_cuda_backend.hpp"
#include "demfem/dem/dem_system.hpp"
#include "demfem/dem/physics/contact.hpp"
#include "demfem/dem/physics/grid_cell.hpp"
#include "demfem/dem/physics/pair.hpp"
#include "demfem/dem/physics/periodic_image.hpp"
#include "demfem/dem/physics/wall_contact.hpp"
#include "demfem/dem/physics/wall_motion.hpp"
#include "neighbour_list.hpp"
#include "pair_slots.hpp"
#include "polyhedra.hpp"
#include "rigid_mesh_bodies.hpp"
#include "separation_proofs.hpp"
#include "shape_table.hpp"
#include "thread_balance.hpp"
#include "wall_contact_slots.hpp"
#include "wall_store.hpp"

namespace demfem::dem {

namespace detail {

[[noreturn]] inline void bad(const std::string& what) {
  throw std::invalid_argument("DemSystem: " + what);
}

inline constexpr int kMaxWallContacts = phys::kMaxWallContacts;

}  // namespace detail

struct DemSystem::Impl {
  DemSettings s;
  int threads = 1;
  std::size_t material_count = 0;
  // contact constants per pair of materials, material_count x material_count (row: i's)
  std::vector<phys::PairConstants> pair_table;
  bool friction = false;     // some pair has friction or rolling resistance
  bool orientation = false;  // integrate the orientation (settings or a non-spherical particle)
  bool rolling = false;
  std::int64_t uniform_mat = -1;  // the material of every particle, -1 = mixed
  // Dilated polyhedra (polyhedra.cpp): the shape table, and whether some particle is one. A
  // system of spheres alone never runs their code (its bits and speed are those of before).
  detail::ShapeTable shapes;
  bool poly = false;
  std::size_t poly_count = 0;  // particles that are polyhedra (the threads' work estimate)
  // The separation proofs of the polyhedra's pair pass (separation_proofs.hpp).
  detail::SeparationProofs proofs;
  // Frozen particles (DemSystem::freeze): the mask (empty: none), and derived from it the
  // frozen particles' indices and the pose each is held at (7 per particle: x, y, z, qw, qx,
  // qy, qz), which hold_frozen() puts back after each kick and drift.
  std::vector<std::uint8_t> frozen;
  std::vector<std::int64_t> frozen_idx;
  std::vector<double> frozen_hold;
  void refresh_frozen();
  void hold_frozen();

  // Periodic boundaries (dem_periodic.cpp, physics/periodic_image.hpp): the periods, and per
  // particle 3 image counters (empty when not periodic). A system without periodic
  // directions runs none of their code (its bits and speed are those of before).
  bool periodic = false;
  phys::PeriodicBox pbox;
  std::vector<std::int32_t> image;
  // After the drift: every particle that is not frozen and has left [lo, lo + L) in a
  // periodic direction comes back in at the other side (its list position bx with it, so
  // that its displacement since the list update is not a period). Every step, so that the
  // positions, and hence the bits, do not depend on when the list is rebuilt. Returns
  // whether some particle wrapped: its candidate wall triangles, binned where it was, are
  // then stale (walls are not wrapped), and the step rebuilds the list.
  bool wrap_positions();
  // Throws std::invalid_argument when a period is below the least one (least_period()).
  void check_periods() const;
  double least_period() const { return 2.0 * (2.0 * rmax + list.skin); }

  ParticleState st;
  std::vector<double> tx, ty, tz;  // torque of the last step
  double t = 0.0;
  std::int64_t steps = 0;
  const std::atomic<bool>* cancel = nullptr;  // set_cancel_flag(): polled by advance()
  void check_cancel(std::int64_t done, std::int64_t of) const {
    if (cancel != nullptr && cancel->load(std::memory_order_relaxed)) {
      throw Cancelled("DEM advance cancelled after " + std::to_string(done) + " of " +
                      std::to_string(of) + " steps (a stop was requested)");
    }
  }
  double rmax = 0.0;  // the largest bounding radius, m

  // The neighbour list (neighbour_list.hpp) and the per-pair slots of its pairs.
  detail::NeighbourList list;
  detail::PairSlots slots;  // per pair of the list: springs, forces, caches
  // The particles as the list reads them.
  detail::ListParticles list_particles() const {
    return {
        st.px.data(), st.py.data(), st.pz.data(), st.radius.data(), static_cast<std::int64_t>(n()),
        pbox,         periodic,     nt()};
  }
  // The list's skin is fixed (settings.list_skin) or one level (the device's list).
  bool fixed_inner_skin() const { return gpu != nullptr || s.list_skin > 0.0; }
  // The largest overlap of the last step (m), over the steps of the last advance() (m), and
  // over them against each contact's own radii (phys::relative_overlap).
  double max_overlap = 0.0;
  double advance_max_overlap = 0.0;
  double advance_max_relative_overlap = 0.0;

  // The walls (wall_store.hpp): every wall triangle in one store, their motion, the
  // triangles near each particle, the loads on them.
  detail::WallStore walls;
  detail::WallContactSlots wall_contacts;  // per particle (wall_contact_slots.hpp)

  CudaBackend* gpu = nullptr;
  DemSystem::Timings timing;

  // Particle ranges of the threads in forces_and_kick() (thread_balance.hpp).
  detail::ThreadBalance balance;

  ~Impl() { cuda_backend_destroy(gpu); }

  // ---------------------------------------------------------------------------------------
  void setup_pairs();

  std::size_t n() const { return st.px.size(); }
  // Threads for the particle loops: small systems run on one thread, where the fork/join
  // of a parallel region costs more than the work (results do not depend on it). The work
  // is counted in sphere-steps: a polyhedron step costs about kPolyWork of them (measured by
  // bench/poly_throughput: 20-26 for rocks of 30 triangles), so beds from about 80 rocks on
  // run threaded.
  static constexpr std::size_t kPolyWork = 24;
  int nt() const { return n() + (kPolyWork - 1) * poly_count >= 2048 ? threads : 1; }

  // ---------------------------------------------------------------------------------------
  // The list's grid build (NeighbourList::build), the wall triangles binned into its grid,
  // then the refilter.
  void rebuild();
  // The list proper refiltered from the candidates (NeighbourList::refilter), then indexed.
  void refilter();
  // The indices derived from the pair list (NeighbourList::index), the per-pair force slots
  // sized to it, the uniform material. refilter() and the CUDA backend's adoption of a list
  // built on the device call it.
  void index_list();

  // ---------------------------------------------------------------------------------------
  // Forces and the second half kick, in one parallel region. Each thread owns a contiguous
  // range of particles (rows of the pair list) and walks it in blocks: the pair forces of the
  // block's rows into the per-pair slots (vectorised kernel), then, while those slots are
  // still in cache, the gather of the block's particles: own-row slots in row order, minus
  // the transposed slots (pairs j < i, i ascending), walls, gravity, kick. A particle whose
  // pairs reach back into an earlier thread's range (the first layer of each range) waits
  // for a barrier, so that no thread reads a slot or a velocity that another thread has not
  // written yet or has already kicked; after the barrier the threads share the waiting
  // particles out evenly. Every sum has a fixed order and every pair is independent, so the
  // result is bitwise identical for any thread count, range bounds and block size.
  // Poly: some particle is a polyhedron (polyhedra.cpp): the pairs go through the narrow
  // phase, each pair slot holds the torques on both bodies (pt on i, ptj on j), polyhedra have
  // their own wall contacts and angular kick, and torques are always summed (a normal force
  // off the centre of mass turns a polyhedron).
  template <bool Friction, bool Poly = false>
  void forces_and_kick();

  // The particles as the contact laws read them (physics/pair.hpp).
  phys::ParticleView particle_view() const;
  detail::PolyParticles poly_particles(const phys::ParticleView& view) const;

  // The arrays that the step integrator (physics/step_integrator.hpp) moves; the principal
  // moments and shapes only in a system with polyhedra (spheres alone: none is a rigid body).
  phys::MotionArrays motion_arrays();

  // Kick + drift of a system with polyhedra (polyhedra.cpp): per particle, spheres and rigid
  // bodies alike.
  double poly_kick_drift();

  phys::WallView wall_view();

  // Half kick + drift; returns the largest displacement since the last list update. The
  // orientation is advanced in a second loop: with only small rotations in this step (the
  // usual case) it runs in SIMD lanes without sin/cos; the per-particle arithmetic is the
  // same either way.
  template <bool Friction>
  double kick_drift();

  template <bool Friction>
  void step(bool last, ForceMode mode, std::int64_t substeps);
  // After a step's wall loads are summed (WallStore::reduce): force-limited walls decide
  // their drift of the next step, rigid mesh bodies take their loads and the second half
  // kick. Both backends.
  void walls_follow_loads();

  // Wall kinematics for the device (filled by gpu_wall_kinematics() when walls move): the
  // reference vertices (rigid walls) and the node positions at the start of the advance()
  // (flexible mesh) in store order, the wall of each vertex (-1: flexible,
  // kVertexPlacedByHost: a body or a force-limited wall, placed by the host every step).
  std::vector<double> gpu_vertex_ref;
  std::vector<std::int32_t> gpu_vertex_wall;

  void gpu_wall_kinematics();

  GpuHostView gpu_view();

  // CUDA backend: the same step on the device; the neighbour list is built on the device
  // when the device reports that it must be (the CPU rule, moving walls included), from the
  // device's positions (cuda/device_list.hpp); the host builds the first list of an advance()
  // only when its own is stale (particles added or removed, a restore). Moving walls
  // and the flexible mesh are placed on the device every step by the CPU's formulas
  // (physics/wall_motion.hpp); the device sums the flexible node forces as `mode` asks.
  // Walls moved by their loads (rigid mesh bodies, force-limited walls) need the loads of
  // each step before the next: then the device runs one step per wait and the host moves
  // those walls between the steps by the CPU step's code (gpu_place_walls_by_loads before a step,
  // gpu_walls_follow_loads after it).
  void advance_gpu(std::int64_t substeps, ForceMode mode);
  bool walls_move_by_loads() const { return !walls.bodies.empty() || walls.force_limited; }
  void gpu_place_walls_by_loads();
  void gpu_walls_follow_loads();
  // After an advance in which the device rebuilt the list: the device's list taken over
  // (rows, partners, build positions, wall candidates), its indices derived (index_list()).
  void adopt_device_list();

  void refresh_particle_derived();
};

}  // namespace demfem::dem
