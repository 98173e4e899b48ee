#pragma once
// Internal interface between DemSystem (g++) and the CUDA backend (cuda/dem_cuda.cu, nvcc).
// Plain pointers only, so that the .cu translation unit needs nothing but the physics
// headers. Without CUDA (DEMFEM_HAVE_CUDA undefined) the functions are provided by
// cuda_stub.cpp and report that no device exists.

#include <atomic>
#include <cstddef>
#include <cstdint>

#include "demfem/dem/physics/contact.hpp"
#include "demfem/dem/physics/periodic_image.hpp"
#include "demfem/dem/physics/shape_table.hpp"
#include "demfem/dem/physics/wall_contact.hpp"
#include "demfem/dem/physics/wall_motion.hpp"

namespace demfem::dem {

struct CudaBackend;

/// GpuHostView::vwall of a vertex the host places before each step (a wall moved by its
/// contact forces or a force-limited wall: cuda_upload_wall_vertices); -1: the flexible mesh,
/// >= 0: the rigid wall whose motion the device evaluates.
constexpr std::int32_t kVertexPlacedByHost = -2;

/// Host arrays of the particle state and the neighbour list (views into DemSystem::Impl).
struct GpuHostView {
  std::size_t n = 0;
  double *px, *py, *pz, *vx, *vy, *vz, *wx, *wy, *wz, *qw, *qx, *qy, *qz;
  double *fx, *fy, *fz, *tx, *ty, *tz;
  const double *radius, *mass, *inertia;
  const std::int32_t* material;
  // neighbour list (CSR rows i < j and their transpose), springs, build positions
  std::size_t npairs = 0;
  const std::int64_t *row, *trow, *tpair;
  const std::int32_t* nbr;
  double* shear;            // 3 per pair (may be null when frictionless)
  double* rhist = nullptr;  // 3 per pair: rolling-torque history (null unless rolling)
  const double *bx, *by, *bz;
  // walls (triangle store, candidate lists, per-particle contact slots)
  std::size_t nverts = 0, ntris = 0, nptri = 0;
  double *vpos = nullptr, *vvel = nullptr;  // in; out when walls_moving
  const std::int32_t *tri_v = nullptr, *tri_e = nullptr, *tri_mat = nullptr, *tri_wall = nullptr;
  const std::int64_t* prow = nullptr;
  const std::int32_t* ptri = nullptr;
  std::int64_t* wkey = nullptr;
  double *wshear = nullptr, *wf = nullptr, *wp = nullptr, *wb = nullptr;
  std::int32_t* wtri = nullptr;
  std::uint8_t* wcount = nullptr;
  // moving walls and the flexible mesh: vertex positions and velocities are computed on
  // the device every step (physics/wall_motion.hpp)
  bool walls_moving = false;
  const double* vbuild = nullptr;       ///< 3 per vertex: positions at the last build
  const double* vref = nullptr;         ///< 3 per vertex: reference (rigid) / start (flexible)
  const std::int32_t* vwall = nullptr;  ///< per vertex: wall index, -1 = flexible mesh,
                                        ///< kVertexPlacedByHost
  const phys::RigidMotion* motion = nullptr;  ///< per rigid wall
  std::size_t nwalls = 0;
  std::size_t flex_vbase = 0, flex_nodes = 0;         ///< first vertex and node count of the mesh
  const double *flex_v = nullptr, *flex_a = nullptr;  ///< 3 per node, start of the advance()
  double* flex_force = nullptr;                       ///< 3 per node: out, as ForceMode asked
  bool flex_average = false;  ///< ForceMode::average (else the last substep)
  double flex_inv_substeps = 1.0;
  double* wroll = nullptr;  // 3 per slot: rolling-torque history (null unless rolling)
  // parameters
  const phys::PairConstants* pc;
  std::size_t nmat = 0;
  double dt = 0.0;
  double gravity[3] = {0, 0, 0};
  bool friction = false, rolling = false;
  bool orientation = true;  ///< integrate the orientation quaternion
  // dilated polyhedra (poly: some particle is one): the shape table, per particle the shape
  // (-1: sphere), scale and principal moments, per pair the torque on j and the narrow
  // phase's caches
  bool poly = false;
  std::size_t nshapes = 0, nshape_verts = 0, nshape_faces = 0, nshape_fverts = 0, nshape_edges = 0;
  const std::int32_t *vbase = nullptr, *snv = nullptr, *fbase = nullptr, *snf = nullptr,
                     *floop = nullptr, *flen = nullptr, *fvert = nullptr, *ebase = nullptr,
                     *sne = nullptr, *edge = nullptr;
  const double *vert = nullptr, *fnormal = nullptr, *dilation = nullptr, *bound = nullptr;
  const std::int32_t* shape_id = nullptr;
  const double *scale = nullptr, *ix = nullptr, *iy = nullptr, *iz = nullptr;
  double* ptj = nullptr;          // 3 per pair (out)
  double* paxis = nullptr;        // 3 per pair (in/out)
  std::int32_t* pfeat = nullptr;  // 6 per pair (in/out)
  // periodic boundaries (physics/periodic_image.hpp): the periods and per particle 3 image
  // counters (in/out; the device wraps the positions after each drift)
  bool periodic = false;
  phys::PeriodicBox pbox;
  std::int32_t* image = nullptr;
  // frozen particles (DemSystem::freeze; nfrozen 0: none): the mask (n), the held particles
  // and their poses (7 each: x, y, z, qw, qx, qy, qz)
  std::size_t nfrozen = 0;
  const std::uint8_t* frozen = nullptr;
  const std::int64_t* frozen_idx = nullptr;
  const double* frozen_hold = nullptr;
};

/// Host arrays a list built on the device is copied into (sized from cuda_list_sizes()).
struct GpuListDownload {
  std::int64_t* row = nullptr;                         ///< n + 1
  std::int32_t* nbr = nullptr;                         ///< pairs
  double *bx = nullptr, *by = nullptr, *bz = nullptr;  ///< build positions, n
  std::int64_t* prow = nullptr;                        ///< n + 1 (null: no walls)
  std::int32_t* ptri = nullptr;                        ///< wall candidates
  double* vbuild = nullptr;  ///< 3 per wall vertex (null unless walls move)
};

bool cuda_device_present();
CudaBackend* cuda_backend_create();
void cuda_backend_destroy(CudaBackend* b);
/// Copies the particle state and parameters to the device.
void cuda_upload_state(CudaBackend* b, const GpuHostView& v);
/// At the start of every advance(), after an upload or on the resident state: the moving
/// walls' motions and reference vertices and the flexible mesh's node kinematics of this
/// advance(), the ForceMode fold, the maxima of the advance() set to zero (enqueued, no wait).
void cuda_begin_advance(CudaBackend* b, const GpuHostView& v);
/// Whether the device holds the host's particle state and list (n particles, npairs pairs):
/// set by the host after an advance() downloaded its results, cleared by an upload of the
/// state and by the host before it runs steps (a step that throws leaves the host behind).
bool cuda_resident(CudaBackend* b, std::size_t n, std::size_t npairs);
void cuda_set_resident(CudaBackend* b, bool resident);
/// Copies the neighbour list, springs and build positions to the device.
void cuda_upload_lists(CudaBackend* b, const GpuHostView& v);
/// Copies the particle state and the springs (tangential and rolling) back to the host;
/// with moving walls also the wall vertex positions and velocities and the flexible node
/// forces.
void cuda_download_state(CudaBackend* b, const GpuHostView& v);
/// Runs up to `steps` steps on the device (a CUDA graph of one step, replayed) and stops
/// early when the neighbour list must be rebuilt (the CPU rule: a particle moved more than
/// skin / 2, or the largest particle displacement plus the largest wall vertex displacement
/// since the last build exceeds the skin): returns the number of steps done. The check runs
/// on the device; the host waits once, at the end, and reads one summary (flags, steps done,
/// overlap maxima). At most twice the steps between the last two builds are run before that
/// wait (steps after a build request are no-ops on the device). t and tau are the time and
/// the time into the advance() at the start (the device advances its copy by dt per step, as
/// the host does). Returns early when `cancel` (may be null) is found set (looked at every
/// 256 steps enqueued).
std::int64_t cuda_run_steps(CudaBackend* b, std::int64_t steps, double skin, double t, double tau,
                            const std::atomic<bool>* cancel = nullptr);
/// Whether the last cuda_run_steps stopped because a list build is due (the drift of the next
/// step done, its forces held back: cuda_build_lists, then cuda_finish_step); false when it
/// ran all the steps of its batch (fewer than asked: the batch cap) or saw the cancel flag.
bool cuda_build_pending(CudaBackend* b);
/// Builds the neighbour list and the wall candidates on the device from the device's
/// positions (cuda/device_list.hpp: the CPU's one-level list, pair for pair), carrying the
/// pair histories over: no particle state crosses to the host. Returns the pair count.
std::size_t cuda_build_lists(CudaBackend* b, double skin, double rmax);
/// Pairs and wall candidates of the device's list.
void cuda_list_sizes(CudaBackend* b, std::size_t* npairs, std::size_t* nptri);
/// Copies the device's list (rows, partners, build positions, wall candidates and the wall
/// vertices at the build) to the host.
void cuda_download_lists(CudaBackend* b, const GpuListDownload& v);
/// Completes a step whose drift was done but whose forces were held back for a rebuild, and
/// reads the summary (one wait).
void cuda_finish_step(CudaBackend* b);
/// The maxima below are those of the summary read at the last wait (no transfer).
/// Copies the wall vertex positions and velocities (vpos, vvel) to the device, enqueued
/// before the next step: the vertices marked kVertexPlacedByHost keep them in that step.
void cuda_upload_wall_vertices(CudaBackend* b, const GpuHostView& v);
/// Copies the wall contact slots of the last step (forces, points, weights, triangles,
/// counts) to the host (one wait), for WallStore::reduce.
void cuda_download_wall_contacts(CudaBackend* b, const GpuHostView& v);
/// Largest overlap of the last step, m.
double cuda_max_overlap(CudaBackend* b);
/// Largest overlap with the flexible mesh since the last upload_state, m.
double cuda_flex_max_overlap(CudaBackend* b);
/// Largest overlap (particles and walls) since the last upload_state, m.
double cuda_advance_max_overlap(CudaBackend* b);
/// Largest phys::relative_overlap (particles and walls) since the last upload_state.
double cuda_advance_max_relative_overlap(CudaBackend* b);

}  // namespace demfem::dem
