// CUDA backend of DemSystem: the same physics headers as the CPU backend
// (physics/contact.hpp, physics/step_integrator.hpp) over device structure-of-arrays state.
// Walls use the shared sphere-triangle contact set (physics/wall_contact.hpp) inside the
// gather kernel. One step is three kernels (kick+drift, pair forces per CSR row,
// gather+kick), captured once into a CUDA graph and replayed without host synchronisation. The
// state, the list and the graph stay on the device from one advance() to the next; the host
// waits for the device once per run of steps and then reads one summary (the stop flags, the
// steps done, the overlap maxima) in one transfer, and once more per list build. Sums are
// in a fixed order (per-pair slots gathered per particle), so the particle state is
// deterministic; the atomics are integer ones (flags, step counter, bit patterns of maxima).
// Moving walls and the flexible mesh add a kernel after the drift that places every wall vertex
// at the new time (physics/wall_motion.hpp, the CPU's update_walls) and measures its displacement
// since the build, and one after the gather that folds the substep's flexible node forces into
// the output as ForceMode asks. The node forces are summed with floating-point atomicAdd, so they
// agree with the CPU to round-off only (they are an output and do not feed back into the step).

#include <cuda_runtime.h>

#include <array>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <string>

#include "core/dem_cuda_backend.hpp"
#include "demfem/dem/physics/contact.hpp"
#include "demfem/dem/physics/pair.hpp"
#include "demfem/dem/physics/poly_contact.hpp"
#include "demfem/dem/physics/step_integrator.hpp"
#include "device_list.hpp"

namespace demfem::dem {

namespace {

void check(cudaError_t e, const char* what) {
  if (e != cudaSuccess)
    throw std::runtime_error(std::string("DemSystem (cuda): ") + what + ": " +
                             cudaGetErrorString(e));
}

template <class T>
void ensure(T*& p, std::size_t& cap, std::size_t n) {
  if (n <= cap && p) return;
  if (p) cudaFree(p);
  check(cudaMalloc(&p, (n > 0 ? n : 1) * sizeof(T)), "cudaMalloc");
  cap = n;
}

// As ensure(), keeping the first `keep` values (a pair history that a list build reads).
template <class T>
void ensure_keep(T*& p, std::size_t& cap, std::size_t n, std::size_t keep) {
  if (n <= cap && p) return;
  T* q = nullptr;
  check(cudaMalloc(&q, (n > 0 ? n : 1) * sizeof(T)), "cudaMalloc");
  if (p && keep > 0)
    check(cudaMemcpy(q, p, keep * sizeof(T), cudaMemcpyDeviceToDevice), "cudaMemcpy");
  if (p) cudaFree(p);
  p = q;
  cap = n;
}

// What the host reads after a run of steps, in one transfer into pinned memory. The
// maxima are the bit patterns of non-negative doubles (ordered as integers).
struct DeviceSummary {
  unsigned long long steps_done;   // steps completed since the run began
  unsigned long long max_ov;       // largest overlap of the last step
  unsigned long long flex_max_ov;  // largest overlap with the flexible mesh this advance()
  unsigned long long adv_max_ov;   // largest overlap this advance()
  unsigned long long adv_max_rel;  // largest phys::relative_overlap this advance()
  int stop[2];                     // a list build stopped the run / was asked for
};

struct Dev {
  double *px, *py, *pz, *vx, *vy, *vz, *wx, *wy, *wz, *qw, *qx, *qy, *qz;
  double *fx, *fy, *fz, *tx, *ty, *tz, *radius, *mass, *inertia;
  double *acc, *acct, *bx, *by, *bz;
  std::int32_t* material;
  std::int64_t *row, *trow, *tpair;
  std::int32_t* nbr;
  double *shear, *pf, *pt, *pr;
  double *rhist, *wroll;  // rolling-torque histories per pair / wall slot (when rolling)
  phys::PairConstants* pc;
  // walls
  bool walls;
  double *vpos, *vvel;
  std::int32_t *tri_v, *tri_e, *tri_mat, *tri_wall;
  std::int64_t* prow;
  std::int32_t* ptri;
  std::int64_t* wkey;
  double *wshear, *wf, *wp, *wb;
  std::int32_t* wtri;
  std::uint8_t* wcount;
  // moving walls and the flexible mesh
  double *vbuild, *vref;          // 3 per vertex: positions at the build / reference positions
  std::int32_t* vwall;            // wall per vertex, -1 = flexible mesh
  phys::RigidMotion* motion;      // per rigid wall
  bool walls_moving;              // motion (and the clock) are valid
  double *flex_v, *flex_a;        // 3 per node, start of the advance()
  double *flex_force, *node_buf;  // 3 per node: output (ForceMode), forces of this substep
  std::int64_t flex_vbase;
  std::size_t flex_nodes;
  double* clock;                        // t and tau after the last drift
  unsigned long long *pdisp2, *wdisp2;  // bits of the largest squared displacement this step
  unsigned long long* flex_max_ov;      // bits of the largest overlap with the flexible mesh
  unsigned long long* adv_max_ov;       // bits of the largest overlap since upload_state
  unsigned long long* adv_max_rel;      // and of the largest phys::relative_overlap
  int* stop;
  unsigned long long* steps_done;
  unsigned long long* max_ov;
  // dilated polyhedra (poly): the shape table, per particle shape / scale / principal moments,
  // per pair the torque on j and the narrow phase's caches
  bool poly;
  std::int32_t *vbase, *snv, *fbase, *snf, *floop, *flen, *fvert, *ebase, *sne, *edge;
  double *vert, *fnormal, *dilation, *bound;
  std::int32_t* shape_id;
  double *scale, *ix, *iy, *iz, *ptj, *paxis;
  std::int32_t* pfeat;
  // periodic boundaries: the periods and 3 image counters per particle
  bool periodic;
  phys::PeriodicBox pbox;
  std::int32_t* image;
  // frozen particles (DemSystem::freeze; frozen null: none): the mask, the held particles and
  // their poses (7 each: x, y, z, qw, qx, qy, qz)
  const std::uint8_t* frozen;
  std::int64_t* frozen_idx;
  double* frozen_hold;
};

// The physics view of a system with polyhedra (device pointers).
__device__ phys::PolyView poly_view(const Dev& d) {
  phys::PolyView v;
  v.p = phys::ParticleView{d.px, d.py, d.pz, d.vx, d.vy, d.vz, d.wx, d.wy, d.wz, d.radius, d.mass};
  v.qw = d.qw, v.qx = d.qx, v.qy = d.qy, v.qz = d.qz;
  v.ix = d.ix, v.iy = d.iy, v.iz = d.iz, v.inertia = d.inertia, v.scale = d.scale;
  v.shape_id = d.shape_id;
  v.table = phys::ShapeTableView{d.vbase, d.snv,   d.vert,  d.fbase, d.snf,  d.fnormal,  d.floop,
                                 d.flen,  d.fvert, d.ebase, d.sne,   d.edge, d.dilation, d.bound};
  return v;
}

// The arrays the step integrator moves (device pointers; rigid bodies only with polyhedra).
__device__ phys::MotionArrays motion_arrays(const Dev& d) {
  return phys::MotionArrays{d.px, d.py, d.pz, d.vx, d.vy, d.vz, d.wx, d.wy, d.wz,
                            d.qw, d.qx, d.qy, d.qz, d.fx, d.fy, d.fz, d.tx, d.ty, d.tz,
                            d.mass, d.inertia,
                            d.poly ? d.ix : nullptr, d.poly ? d.iy : nullptr,
                            d.poly ? d.iz : nullptr, d.poly ? d.shape_id : nullptr};
}

// Folds v (>= 0) into *dst, the bit pattern of a non-negative double (whose integer order is
// the order of the values): a shuffle reduction over the warp, then one atomic per warp. Every
// lane of the warp must call it (no thread of the block may have returned before).
__device__ void warp_max_to(double v, unsigned long long* dst) {
  for (int o = 16; o > 0; o >>= 1) v = fmax(v, __shfl_down_sync(0xffffffffu, v, o));
  if ((threadIdx.x & 31u) == 0 && v > 0.0)
    atomicMax(dst, static_cast<unsigned long long>(__double_as_longlong(v)));
}

__device__ double bits_to_double(unsigned long long b) {
  return __longlong_as_double(static_cast<long long>(b));
}

// track: also record the largest squared displacement since the build (moving walls).
__global__ void k_kick_drift(Dev d, std::size_t n, double dt, double half_skin2, bool friction,
                             bool orientation, bool track) {
  if (*d.stop) return;  // the same for all threads: stop[0] is written by k_latch only
  const std::size_t i = blockIdx.x * static_cast<std::size_t>(blockDim.x) + threadIdx.x;
  if (i == 0) *d.max_ov = 0ull;  // max overlap of this step (read after the pair kernel)
  double d2 = 0.0;
  if (i < n) {
    const phys::MotionArrays m = motion_arrays(d);
    const bool held = d.frozen != nullptr && d.frozen[i] != 0;
    // a frozen body among polyhedra is not moved; a frozen sphere is put back by k_hold (as
    // on the CPU: the displacement then counts its step)
    if (!(held && d.poly))
      phys::kick_drift(m, static_cast<std::int64_t>(i), dt, friction || d.poly, orientation);
    d2 = phys::displacement2(m, static_cast<std::int64_t>(i), d.bx, d.by, d.bz);
    if (d2 > half_skin2) atomicExch(d.stop + 1, 1);
    if (d.periodic && !held) {  // back into the periods (wrap_positions() on the CPU)
      double* x[3] = {d.px + i, d.py + i, d.pz + i};
      double* b[3] = {d.bx + i, d.by + i, d.bz + i};
      bool wrapped = false;
      for (int a = 0; a < 3; ++a) {
        const int k = phys::wrap_coordinate(d.pbox, a, *x[a], b[a]);
        d.image[3 * i + a] += k;
        wrapped = wrapped || k != 0;
      }
      // the wall candidates were binned where it was (walls do not wrap): a new list
      if (wrapped && d.walls) atomicExch(d.stop + 1, 1);
    }
  }
  if (track) warp_max_to(d2, d.pdisp2);
}

// Frozen particles back at rest in their held poses (hold_frozen() on the CPU), after the
// drift and after the force pass.
__global__ void k_hold(Dev d, std::size_t nheld, bool force) {
  if (*d.stop && !force) return;
  const std::size_t k = blockIdx.x * static_cast<std::size_t>(blockDim.x) + threadIdx.x;
  if (k < nheld) phys::hold_pose(motion_arrays(d), d.frozen_idx[k], d.frozen_hold + 7 * k);
}

// Wall vertices at the new time t + dt (tau + dt into the advance()), as update_walls() on the
// CPU: rigid walls from their reference vertices and motion, the flexible mesh from the node
// kinematics of the advance(); and the largest squared displacement since the build.
__global__ void k_walls(Dev d, std::size_t nverts, double dt) {
  if (*d.stop) return;
  const std::size_t k = blockIdx.x * static_cast<std::size_t>(blockDim.x) + threadIdx.x;
  double d2 = 0.0;
  if (k < nverts) {
    double* x = d.vpos + 3 * k;
    double* v = d.vvel + 3 * k;
    const std::int32_t w = d.vwall[k];
    if (w >= 0) {  // a fixed wall (kind 0) keeps its vertices
      phys::rigid_vertex(phys::rigid_pose(d.motion[w], d.clock[0] + dt), d.vref + 3 * k, x, v);
    } else if (w != kVertexPlacedByHost) {  // placed: uploaded before the step
      const double tau = d.clock[1] + dt;
      const std::int64_t node = static_cast<std::int64_t>(k) - d.flex_vbase;
      for (int c = 0; c < 3; ++c)
        phys::flexible_node(d.vref[3 * k + c], d.flex_v[3 * node + c], d.flex_a[3 * node + c], tau,
                            x[c], v[c]);
    }
    const double dx = x[0] - d.vbuild[3 * k], dy = x[1] - d.vbuild[3 * k + 1],
                 dz = x[2] - d.vbuild[3 * k + 2];
    d2 = dx * dx + dy * dy + dz * dz;
  }
  warp_max_to(d2, d.wdisp2);
}

// After the drift (and the walls) of a step that was not skipped: advances the clock and
// promotes a rebuild request to a stop of the following kernels (2: drift of this step done,
// forces pending). Particle rule: a particle moved more than skin / 2 (stop[1]); with moving
// walls also the CPU rule 2 disp > skin or disp + wall disp > skin on the same maxima.
__global__ void k_latch(Dev d, double dt, double skin, bool moving) {
  if (d.stop[0]) return;
  d.clock[0] += dt;
  d.clock[1] += dt;
  bool rebuild = d.stop[1] != 0;
  if (moving) {
    const double disp = sqrt(bits_to_double(*d.pdisp2));
    const double wdisp = sqrt(bits_to_double(*d.wdisp2));
    *d.pdisp2 = 0ull;
    *d.wdisp2 = 0ull;
    const phys::ListRule one_level{skin, skin, 0.0};  // the list is the build's
    rebuild = rebuild || one_level.build_by_pairs(2.0 * disp) ||
              one_level.build_by_walls(disp, wdisp);
  }
  if (rebuild) d.stop[0] = 2;
}

// Flexible node forces of this substep into the output: the average over the substeps or the
// last substep (ForceMode), as wall_reduce() on the CPU; clears the substep buffer.
__global__ void k_flex_fold(Dev d, std::size_t n3, bool average, double inv, bool force) {
  if (*d.stop && !force) return;
  const std::size_t k = blockIdx.x * static_cast<std::size_t>(blockDim.x) + threadIdx.x;
  if (k >= n3) return;
  const double f = d.node_buf[k];
  d.node_buf[k] = 0.0;
  d.flex_force[k] = average ? d.flex_force[k] + inv * f : f;
}

template <bool Friction>
__global__ void k_pairs(Dev d, std::size_t n, std::size_t nmat, double dt, bool rolling,
                        bool force) {
  if (*d.stop && !force) return;
  const std::size_t i = blockIdx.x * static_cast<std::size_t>(blockDim.x) + threadIdx.x;
  if (i >= n) return;
  double ax = 0, ay = 0, az = 0, qx = 0, qy = 0, qz = 0, mo = 0, mr = 0;
  const double ri = d.radius[i];
  const std::size_t mrow = static_cast<std::size_t>(d.material[i]) * nmat;
  const phys::ParticleView view{d.px, d.py, d.pz, d.vx,     d.vy,  d.vz,
                                d.wx, d.wy, d.wz, d.radius, d.mass};
  if (d.poly) {  // a system with polyhedra: the mixed pair law, torques on both bodies
    const phys::PolyView pv = poly_view(d);
    const phys::PeriodicBox* box = d.periodic ? &d.pbox : nullptr;
    const bool held = d.frozen != nullptr && d.frozen[i] != 0;
    for (std::int64_t p = d.row[i]; p < d.row[i + 1]; ++p) {
      const std::int32_t j = d.nbr[p];
      if (held && d.frozen[j] != 0) {
        // both held: their mutual force moves nothing and cancels in the frozen particles'
        // total, so it is not computed and the caches are kept (as the CPU's pair_range)
        for (int c = 0; c < 3; ++c) d.pf[3 * p + c] = d.pt[3 * p + c] = d.ptj[3 * p + c] = 0.0;
        continue;
      }
      phys::Vec3 sh{0, 0, 0}, rh{0, 0, 0};
      if (Friction) sh = phys::Vec3{d.shear[3 * p], d.shear[3 * p + 1], d.shear[3 * p + 2]};
      if (Friction && rolling)
        rh = phys::Vec3{d.rhist[3 * p], d.rhist[3 * p + 1], d.rhist[3 * p + 2]};
      phys::Vec3 axis{d.paxis[3 * p], d.paxis[3 * p + 1], d.paxis[3 * p + 2]};
      phys::Vec3 fij, ti, tj;
      const double delta = phys::mixed_pair<Friction>(
          pv, static_cast<int>(i), j, d.pc[mrow + d.material[j]], dt, Friction && rolling, sh, rh,
          axis, d.pfeat + 6 * p, fij, ti, tj, nullptr, box);
      mo = fmax(mo, delta);
      if (delta > 0.0)
        mr = fmax(mr, phys::relative_overlap(delta, phys::particle_contact_radius(pv, i),
                                             phys::particle_contact_radius(pv, j)));
      d.pf[3 * p] = fij.x, d.pf[3 * p + 1] = fij.y, d.pf[3 * p + 2] = fij.z;
      d.pt[3 * p] = ti.x, d.pt[3 * p + 1] = ti.y, d.pt[3 * p + 2] = ti.z;
      d.ptj[3 * p] = tj.x, d.ptj[3 * p + 1] = tj.y, d.ptj[3 * p + 2] = tj.z;
      d.paxis[3 * p] = axis.x, d.paxis[3 * p + 1] = axis.y, d.paxis[3 * p + 2] = axis.z;
      if (Friction) d.shear[3 * p] = sh.x, d.shear[3 * p + 1] = sh.y, d.shear[3 * p + 2] = sh.z;
      if (Friction && rolling)
        d.rhist[3 * p] = rh.x, d.rhist[3 * p + 1] = rh.y, d.rhist[3 * p + 2] = rh.z;
      ax += fij.x, ay += fij.y, az += fij.z;
      qx += ti.x, qy += ti.y, qz += ti.z;
    }
    d.acc[3 * i] = ax, d.acc[3 * i + 1] = ay, d.acc[3 * i + 2] = az;
    d.acct[3 * i] = qx, d.acct[3 * i + 1] = qy, d.acct[3 * i + 2] = qz;
    if (mo > 0.0) {
      atomicMax(d.max_ov, static_cast<unsigned long long>(__double_as_longlong(mo)));
      atomicMax(d.adv_max_ov, static_cast<unsigned long long>(__double_as_longlong(mo)));
      atomicMax(d.adv_max_rel, static_cast<unsigned long long>(__double_as_longlong(mr)));
    }
    return;
  }
  const phys::PeriodicBox* box = d.periodic ? &d.pbox : nullptr;
  for (std::int64_t p = d.row[i]; p < d.row[i + 1]; ++p) {
    const std::int32_t j = d.nbr[p];
    double* f = d.pf + 3 * p;
    phys::Vec3 sh{0, 0, 0}, rh{0, 0, 0};
    if (Friction) sh = phys::Vec3{d.shear[3 * p], d.shear[3 * p + 1], d.shear[3 * p + 2]};
    if (Friction && rolling)
      rh = phys::Vec3{d.rhist[3 * p], d.rhist[3 * p + 1], d.rhist[3 * p + 2]};
    phys::ContactResult r{};
    double delta = 0.0;
    if (!phys::sphere_sphere<Friction>(view, static_cast<int>(i), j, d.pc[mrow + d.material[j]], dt,
                                       sh, rh, r, delta, box)) {
      f[0] = f[1] = f[2] = 0.0;
      if (Friction) {
        double* shp = d.shear + 3 * p;
        shp[0] = shp[1] = shp[2] = 0.0;
        double* tq = d.pt + 3 * p;
        tq[0] = tq[1] = tq[2] = 0.0;
        double* rq = d.pr + 3 * p;
        if (rolling) rq[0] = rq[1] = rq[2] = 0.0;
        double* rhp = d.rhist + 3 * p;
        if (rolling) rhp[0] = rhp[1] = rhp[2] = 0.0;
      }
      continue;
    }
    mo = fmax(mo, delta);
    mr = fmax(mr, phys::relative_overlap(delta, ri, d.radius[j]));
    f[0] = r.force.x, f[1] = r.force.y, f[2] = r.force.z;
    ax += r.force.x, ay += r.force.y, az += r.force.z;
    if (Friction) {
      double* shp = d.shear + 3 * p;
      shp[0] = sh.x, shp[1] = sh.y, shp[2] = sh.z;
      double* tq = d.pt + 3 * p;
      tq[0] = r.torque.x, tq[1] = r.torque.y, tq[2] = r.torque.z;
      qx += ri * r.torque.x, qy += ri * r.torque.y, qz += ri * r.torque.z;
      if (rolling) {
        double* rq = d.pr + 3 * p;
        rq[0] = r.roll.x, rq[1] = r.roll.y, rq[2] = r.roll.z;
        qx += r.roll.x, qy += r.roll.y, qz += r.roll.z;
        double* rhp = d.rhist + 3 * p;
        rhp[0] = rh.x, rhp[1] = rh.y, rhp[2] = rh.z;
      }
    }
  }
  d.acc[3 * i] = ax, d.acc[3 * i + 1] = ay, d.acc[3 * i + 2] = az;
  if (Friction) d.acct[3 * i] = qx, d.acct[3 * i + 1] = qy, d.acct[3 * i + 2] = qz;
  if (mo > 0.0) {
    atomicMax(d.max_ov, static_cast<unsigned long long>(__double_as_longlong(mo)));
    atomicMax(d.adv_max_ov, static_cast<unsigned long long>(__double_as_longlong(mo)));
    atomicMax(d.adv_max_rel, static_cast<unsigned long long>(__double_as_longlong(mr)));
  }
}

template <bool Friction>
__global__ void k_gather_kick(Dev d, std::size_t n, std::size_t nmat, double dt, double gx,
                              double gy, double gz, bool rolling, bool force) {
  if (*d.stop && !force) return;
  const std::size_t i = blockIdx.x * static_cast<std::size_t>(blockDim.x) + threadIdx.x;
  if (i == 0) atomicAdd(d.steps_done, 1ull);
  if (i >= n) return;
  double fx = d.acc[3 * i], fy = d.acc[3 * i + 1], fz = d.acc[3 * i + 2];
  double qx = 0, qy = 0, qz = 0;
  if (Friction || d.poly) qx = d.acct[3 * i], qy = d.acct[3 * i + 1], qz = d.acct[3 * i + 2];
  const double ri = d.radius[i];
  for (std::int64_t k = d.trow[i]; k < d.trow[i + 1]; ++k) {
    const std::int64_t p = d.tpair[k];
    fx -= d.pf[3 * p], fy -= d.pf[3 * p + 1], fz -= d.pf[3 * p + 2];
    if (d.poly) {
      qx += d.ptj[3 * p], qy += d.ptj[3 * p + 1], qz += d.ptj[3 * p + 2];
    } else if (Friction) {
      qx += ri * d.pt[3 * p], qy += ri * d.pt[3 * p + 1], qz += ri * d.pt[3 * p + 2];
      if (rolling) qx -= d.pr[3 * p], qy -= d.pr[3 * p + 1], qz -= d.pr[3 * p + 2];
    }
  }
  if (d.walls) {
    const phys::ParticleView view{d.px, d.py, d.pz, d.vx,     d.vy,  d.vz,
                                  d.wx, d.wy, d.wz, d.radius, d.mass};
    phys::WallView wv{d.vpos, d.vvel,   d.tri_v, d.tri_e, d.tri_mat, d.tri_wall, d.prow,  d.ptri,
                      d.wkey, d.wshear, d.wf,    d.wp,    d.wb,      d.wtri,     d.wcount};
    wv.wroll = rolling ? d.wroll : nullptr;
    if (d.walls_moving) wv.motion = d.motion, wv.time = d.clock[0];  // clock: this step's time
    phys::Vec3 f{fx, fy, fz}, q{qx, qy, qz};
    double mo = 0.0, fmo = 0.0, rc = ri;  // rc: the particle's contact radius
    if (d.poly && d.shape_id[i] >= 0) {
      rc = phys::particle_contact_radius(poly_view(d), static_cast<int>(i));
      phys::poly_wall_contacts<Friction>(
          phys::poly_wall_particle(poly_view(d), static_cast<int>(i)), wv,
          static_cast<std::int64_t>(i), d.pc + static_cast<std::size_t>(d.material[i]) * nmat, dt,
          f, q, mo, fmo);
    } else {
      phys::wall_contacts<Friction>(view, wv, static_cast<std::int64_t>(i),
                                    d.pc + static_cast<std::size_t>(d.material[i]) * nmat, dt, f, q,
                                    mo, fmo);
    }
    fx = f.x, fy = f.y, fz = f.z;
    qx = q.x, qy = q.y, qz = q.z;
    if (mo > 0.0) {
      const double mr = phys::relative_overlap(mo, rc, rc);
      atomicMax(d.max_ov, static_cast<unsigned long long>(__double_as_longlong(mo)));
      atomicMax(d.adv_max_ov, static_cast<unsigned long long>(__double_as_longlong(mo)));
      atomicMax(d.adv_max_rel, static_cast<unsigned long long>(__double_as_longlong(mr)));
    }
    if (d.flex_nodes > 0) {
      if (fmo > 0.0)
        atomicMax(d.flex_max_ov, static_cast<unsigned long long>(__double_as_longlong(fmo)));
      // this particle's contacts with the flexible mesh, split onto the nodes of the touched
      // triangle with the barycentric weights of the contact point (as wall_reduce())
      for (int c = 0; c < d.wcount[i]; ++c) {
        const std::int64_t slot = phys::kMaxWallContacts * static_cast<std::int64_t>(i) + c;
        const std::int32_t tri = d.wtri[slot];
        if (d.tri_wall[tri] >= 0) continue;  // a rigid wall: reduced on the host
        const phys::Vec3 fw{-d.wf[3 * slot], -d.wf[3 * slot + 1], -d.wf[3 * slot + 2]};
        for (int e = 0; e < 3; ++e) {
          const std::int64_t node = d.tri_v[3 * tri + e] - d.flex_vbase;
          const phys::Vec3 fb = phys::node_share(d.wb[3 * slot + e], fw);
          atomicAdd(d.node_buf + 3 * node, fb.x);
          atomicAdd(d.node_buf + 3 * node + 1, fb.y);
          atomicAdd(d.node_buf + 3 * node + 2, fb.z);
        }
      }
    }
  }
  phys::finish_kick(motion_arrays(d), static_cast<std::int64_t>(i), phys::Vec3{fx, fy, fz},
                    phys::Vec3{qx, qy, qz}, gx, gy, gz, dt, Friction || d.poly);
}

}  // namespace

struct CudaBackend {
  Dev d{};
  std::size_t cap[96] = {};
  std::size_t n = 0, npairs = 0, nmat = 0;
  double dt = 0, g[3] = {0, 0, 0};
  bool friction = false, rolling = false, orientation = true;
  cudaStream_t stream = nullptr;
  cudaGraphExec_t graph = nullptr;
  double graph_skin = -1.0;
  bool walls_moving = false;  // walls move or a flexible mesh is set (this advance())
  std::size_t nverts = 0, flex_nodes = 0;
  bool flex_average = false;
  double flex_inv = 1.0;
  DeviceSummary* summary_dev = nullptr;   // the stop flags, counters and maxima of Dev
  DeviceSummary* summary_host = nullptr;  // pinned: its copy after the last wait
  cudaEvent_t chunk_done = nullptr;       // recorded after each chunk's summary copy
  Dev graph_dev{};                        // the Dev the graph was captured with
  bool graph_flex_average = false;        // and its ForceMode fold
  double graph_flex_inv = 0.0;
  bool resident = false;                  // the device holds the host's state and list
  std::int64_t steps_since_build = 0;     // steps run since the last list build
  std::int64_t steps_between_builds = std::int64_t{1} << 40;  // between the last two builds
  std::size_t ntris = 0, nptri = 0;
  std::size_t nfrozen = 0;                 // frozen particles (Dev::frozen_idx)
  std::uint8_t* frozen_mask = nullptr;     // Dev::frozen when some are
  DeviceNeighbourList list;  // the list builder (device_list.hpp)
};

bool cuda_device_present() {
  int count = 0;
  if (cudaGetDeviceCount(&count) != cudaSuccess) {
    cudaGetLastError();
    return false;
  }
  return count > 0;
}

CudaBackend* cuda_backend_create() {
  auto* b = new CudaBackend();
  check(cudaStreamCreate(&b->stream), "cudaStreamCreate");
  check(cudaEventCreateWithFlags(&b->chunk_done, cudaEventDisableTiming), "cudaEventCreate");
  check(cudaMalloc(&b->summary_dev, sizeof(DeviceSummary)), "cudaMalloc");
  check(cudaMallocHost(&b->summary_host, sizeof(DeviceSummary)), "cudaMallocHost");
  check(cudaMemset(b->summary_dev, 0, sizeof(DeviceSummary)), "cudaMemset");
  std::memset(b->summary_host, 0, sizeof(DeviceSummary));
  DeviceSummary* s = b->summary_dev;
  b->d.stop = s->stop, b->d.steps_done = &s->steps_done, b->d.max_ov = &s->max_ov;
  b->d.flex_max_ov = &s->flex_max_ov, b->d.adv_max_ov = &s->adv_max_ov;
  b->d.adv_max_rel = &s->adv_max_rel;
  check(cudaMalloc(&b->d.clock, 2 * sizeof(double)), "cudaMalloc");
  check(cudaMalloc(&b->d.pdisp2, sizeof(unsigned long long)), "cudaMalloc");
  check(cudaMalloc(&b->d.wdisp2, sizeof(unsigned long long)), "cudaMalloc");
  check(cudaMemset(b->d.clock, 0, 2 * sizeof(double)), "cudaMemset");
  check(cudaMemset(b->d.pdisp2, 0, sizeof(unsigned long long)), "cudaMemset");
  check(cudaMemset(b->d.wdisp2, 0, sizeof(unsigned long long)), "cudaMemset");
  return b;
}

void cuda_backend_destroy(CudaBackend* b) {
  if (!b) return;
  if (b->graph) cudaGraphExecDestroy(b->graph);
  double** dp[] = {
      &b->d.px, &b->d.py, &b->d.pz, &b->d.vx,     &b->d.vy,   &b->d.vz,      &b->d.wx,  &b->d.wy,
      &b->d.wz, &b->d.qw, &b->d.qx, &b->d.qy,     &b->d.qz,   &b->d.fx,      &b->d.fy,  &b->d.fz,
      &b->d.tx, &b->d.ty, &b->d.tz, &b->d.radius, &b->d.mass, &b->d.inertia, &b->d.acc, &b->d.acct,
      &b->d.bx, &b->d.by, &b->d.bz, &b->d.shear,  &b->d.pf,   &b->d.pt,      &b->d.pr};
  for (auto* p : dp) cudaFree(*p);
  cudaFree(b->d.material), cudaFree(b->d.row), cudaFree(b->d.trow), cudaFree(b->d.tpair);
  cudaFree(b->d.nbr), cudaFree(b->d.pc), cudaFree(b->summary_dev), cudaFreeHost(b->summary_host);
  cudaFree(b->d.vpos), cudaFree(b->d.vvel), cudaFree(b->d.tri_v), cudaFree(b->d.tri_e);
  cudaFree(b->d.tri_mat), cudaFree(b->d.tri_wall), cudaFree(b->d.prow), cudaFree(b->d.ptri);
  cudaFree(b->d.wkey), cudaFree(b->d.wshear), cudaFree(b->d.wf), cudaFree(b->d.wp);
  cudaFree(b->d.wb), cudaFree(b->d.wtri), cudaFree(b->d.wcount);
  cudaFree(b->d.vbuild), cudaFree(b->d.vref), cudaFree(b->d.vwall), cudaFree(b->d.motion);
  cudaFree(b->d.flex_v), cudaFree(b->d.flex_a), cudaFree(b->d.flex_force);
  cudaFree(b->d.node_buf), cudaFree(b->d.clock), cudaFree(b->d.pdisp2), cudaFree(b->d.wdisp2);
  cudaFree(b->d.rhist), cudaFree(b->d.wroll), cudaFree(b->d.image);
  cudaFree(b->frozen_mask), cudaFree(b->d.frozen_idx), cudaFree(b->d.frozen_hold);
  for (void* p : {static_cast<void*>(b->d.vbase),    static_cast<void*>(b->d.snv),
                  static_cast<void*>(b->d.fbase),    static_cast<void*>(b->d.snf),
                  static_cast<void*>(b->d.floop),    static_cast<void*>(b->d.flen),
                  static_cast<void*>(b->d.fvert),    static_cast<void*>(b->d.ebase),
                  static_cast<void*>(b->d.sne),      static_cast<void*>(b->d.edge),
                  static_cast<void*>(b->d.vert),     static_cast<void*>(b->d.fnormal),
                  static_cast<void*>(b->d.dilation), static_cast<void*>(b->d.bound),
                  static_cast<void*>(b->d.shape_id), static_cast<void*>(b->d.scale),
                  static_cast<void*>(b->d.ix),       static_cast<void*>(b->d.iy),
                  static_cast<void*>(b->d.iz),       static_cast<void*>(b->d.ptj),
                  static_cast<void*>(b->d.paxis),    static_cast<void*>(b->d.pfeat)})
    cudaFree(p);
  if (b->chunk_done) cudaEventDestroy(b->chunk_done);
  if (b->stream) cudaStreamDestroy(b->stream);
  delete b;
}

namespace {
template <class T>
void up(T*& dst, std::size_t& cap, const T* src, std::size_t n) {
  ensure(dst, cap, n);
  if (n) check(cudaMemcpy(dst, src, n * sizeof(T), cudaMemcpyHostToDevice), "upload");
}
// Per advance(): enqueued on the stream (a pageable source is staged before the call returns).
template <class T>
void up_async(T*& dst, std::size_t& cap, const T* src, std::size_t n, cudaStream_t stream) {
  ensure(dst, cap, n);
  if (n)
    check(cudaMemcpyAsync(dst, src, n * sizeof(T), cudaMemcpyHostToDevice, stream), "upload");
}
template <class T>
void down(T* dst, const T* src, std::size_t n) {
  if (n) check(cudaMemcpy(dst, src, n * sizeof(T), cudaMemcpyDeviceToHost), "download");
}
}  // namespace

void cuda_upload_state(CudaBackend* b, const GpuHostView& v) {
  const std::size_t n = v.n;
  b->n = n, b->nmat = v.nmat, b->dt = v.dt, b->friction = v.friction, b->rolling = v.rolling;
  b->orientation = v.orientation;
  // the graph holds the particle count (its launch sizes) and these parameters: capture again
  if (b->graph) cudaGraphExecDestroy(b->graph), b->graph = nullptr;
  for (int k = 0; k < 3; ++k) b->g[k] = v.gravity[k];
  std::size_t* c = b->cap;
  Dev& d = b->d;
  up(d.px, c[0], v.px, n), up(d.py, c[1], v.py, n), up(d.pz, c[2], v.pz, n);
  up(d.vx, c[3], v.vx, n), up(d.vy, c[4], v.vy, n), up(d.vz, c[5], v.vz, n);
  up(d.wx, c[6], v.wx, n), up(d.wy, c[7], v.wy, n), up(d.wz, c[8], v.wz, n);
  up(d.qw, c[9], v.qw, n), up(d.qx, c[10], v.qx, n), up(d.qy, c[11], v.qy, n);
  up(d.qz, c[12], v.qz, n), up(d.fx, c[13], v.fx, n), up(d.fy, c[14], v.fy, n);
  up(d.fz, c[15], v.fz, n), up(d.tx, c[16], v.tx, n), up(d.ty, c[17], v.ty, n);
  up(d.tz, c[18], v.tz, n);
  up(d.radius, c[19], v.radius, n), up(d.mass, c[20], v.mass, n);
  up(d.inertia, c[21], v.inertia, n), up(d.material, c[22], v.material, n);
  ensure(d.acc, c[23], 3 * n), ensure(d.acct, c[24], 3 * n);
  up(d.pc, c[25], v.pc, v.nmat * v.nmat);
  d.poly = v.poly;
  if (v.poly) {
    up(d.vbase, c[63], v.vbase, v.nshapes), up(d.snv, c[64], v.snv, v.nshapes);
    up(d.fbase, c[65], v.fbase, v.nshapes), up(d.snf, c[66], v.snf, v.nshapes);
    up(d.floop, c[67], v.floop, v.nshape_faces), up(d.flen, c[68], v.flen, v.nshape_faces);
    up(d.fvert, c[69], v.fvert, v.nshape_fverts), up(d.ebase, c[70], v.ebase, v.nshapes);
    up(d.sne, c[71], v.sne, v.nshapes), up(d.edge, c[72], v.edge, 2 * v.nshape_edges);
    up(d.vert, c[73], v.vert, 3 * v.nshape_verts);
    up(d.fnormal, c[74], v.fnormal, 3 * v.nshape_faces);
    up(d.dilation, c[75], v.dilation, v.nshapes), up(d.bound, c[76], v.bound, v.nshapes);
    up(d.shape_id, c[77], v.shape_id, n), up(d.scale, c[78], v.scale, n);
    up(d.ix, c[79], v.ix, n), up(d.iy, c[80], v.iy, n), up(d.iz, c[81], v.iz, n);
  }
  b->nfrozen = v.nfrozen;
  if (v.nfrozen > 0) {
    up(b->frozen_mask, c[86], v.frozen, n), up(d.frozen_idx, c[87], v.frozen_idx, v.nfrozen);
    up(d.frozen_hold, c[88], v.frozen_hold, 7 * v.nfrozen);
  }
  d.frozen = v.nfrozen > 0 ? b->frozen_mask : nullptr;
  d.periodic = v.periodic;
  d.pbox = v.pbox;
  if (v.periodic) up(d.image, c[85], v.image, 3 * n);
  d.walls = v.ntris > 0;
  b->ntris = v.ntris;
  if (d.walls) {
    const std::size_t ns = static_cast<std::size_t>(phys::kMaxWallContacts) * n;
    up(d.vpos, c[40], v.vpos, 3 * v.nverts), up(d.vvel, c[41], v.vvel, 3 * v.nverts);
    up(d.tri_v, c[42], v.tri_v, 3 * v.ntris), up(d.tri_e, c[43], v.tri_e, 3 * v.ntris);
    up(d.tri_mat, c[44], v.tri_mat, v.ntris), up(d.tri_wall, c[45], v.tri_wall, v.ntris);
    up(d.wkey, c[46], v.wkey, ns), up(d.wshear, c[47], v.wshear, 3 * ns);
    ensure(d.wf, c[48], 3 * ns), ensure(d.wp, c[49], 3 * ns), ensure(d.wb, c[50], 3 * ns);
    ensure(d.wtri, c[51], ns);
    up(d.wcount, c[52], v.wcount, n);
    if (v.wroll) up(d.wroll, c[38], v.wroll, 3 * ns);
  }
  b->walls_moving = d.walls && v.walls_moving;
  d.walls_moving = b->walls_moving && v.nwalls > 0;
  b->nverts = d.walls ? v.nverts : 0;
  b->flex_nodes = b->walls_moving ? v.flex_nodes : 0;
  d.flex_nodes = b->flex_nodes;
  d.flex_vbase = static_cast<std::int64_t>(v.flex_vbase);
  b->resident = false;  // until the advance() that uploaded it has downloaded its results
}

void cuda_begin_advance(CudaBackend* b, const GpuHostView& v) {
  std::size_t* c = b->cap;
  Dev& d = b->d;
  // moving walls and the flexible mesh: reference vertices, motions, node kinematics of this
  // advance(); the node force output starts at zero (as on the CPU)
  b->flex_average = v.flex_average, b->flex_inv = v.flex_inv_substeps;
  if (b->walls_moving) {
    up_async(d.vref, c[56], v.vref, 3 * v.nverts, b->stream);
    up_async(d.vwall, c[57], v.vwall, v.nverts, b->stream);
    up_async(d.motion, c[58], v.motion, v.nwalls, b->stream);
    if (b->flex_nodes > 0) {
      const std::size_t n3 = 3 * b->flex_nodes;
      up_async(d.flex_v, c[59], v.flex_v, n3, b->stream);
      up_async(d.flex_a, c[60], v.flex_a, n3, b->stream);
      ensure(d.flex_force, c[61], n3), ensure(d.node_buf, c[62], n3);
      check(cudaMemsetAsync(d.flex_force, 0, n3 * sizeof(double), b->stream), "cudaMemset");
      check(cudaMemsetAsync(d.node_buf, 0, n3 * sizeof(double), b->stream), "cudaMemset");
    }
  }
  // the maxima of this advance() start at zero (the graph is captured again if an array moved)
  check(cudaMemsetAsync(d.flex_max_ov, 0, sizeof(unsigned long long), b->stream), "cudaMemset");
  check(cudaMemsetAsync(d.adv_max_ov, 0, sizeof(unsigned long long), b->stream), "cudaMemset");
  check(cudaMemsetAsync(d.adv_max_rel, 0, sizeof(unsigned long long), b->stream), "cudaMemset");
  check(cudaMemsetAsync(d.max_ov, 0, sizeof(unsigned long long), b->stream), "cudaMemset");
}

bool cuda_resident(CudaBackend* b, std::size_t n, std::size_t npairs) {
  return b->resident && b->n == n && b->npairs == npairs;
}

void cuda_set_resident(CudaBackend* b, bool resident) {
  b->resident = resident;
}

void cuda_upload_lists(CudaBackend* b, const GpuHostView& v) {
  const std::size_t n = v.n, np = v.npairs;
  b->npairs = np;
  std::size_t* c = b->cap;
  Dev& d = b->d;
  up(d.row, c[26], v.row, n + 1), up(d.trow, c[27], v.trow, n + 1);
  up(d.tpair, c[28], v.tpair, np), up(d.nbr, c[29], v.nbr, np);
  up(d.bx, c[30], v.bx, n), up(d.by, c[31], v.by, n), up(d.bz, c[32], v.bz, n);
  ensure(d.pf, c[33], 3 * np);
  if (v.ntris > 0) up(d.prow, c[53], v.prow, n + 1), up(d.ptri, c[54], v.ptri, v.nptri);
  b->nptri = v.ntris > 0 ? v.nptri : 0;
  if (v.ntris > 0 && v.walls_moving) up(d.vbuild, c[55], v.vbuild, 3 * v.nverts);
  if (v.poly) {
    up(d.paxis, c[82], v.paxis, 3 * np), up(d.pfeat, c[83], v.pfeat, 6 * np);
    ensure(d.ptj, c[84], 3 * np), ensure(d.pt, c[35], 3 * np);
  }
  if (v.friction) {
    up(d.shear, c[34], v.shear, 3 * np);
    ensure(d.pt, c[35], 3 * np), ensure(d.pr, c[36], 3 * np);
    if (v.rhist) up(d.rhist, c[37], v.rhist, 3 * np);
  }
}

void cuda_download_state(CudaBackend* b, const GpuHostView& v) {
  const std::size_t n = v.n;
  const Dev& d = b->d;
  check(cudaStreamSynchronize(b->stream), "cudaStreamSynchronize");
  down(v.px, d.px, n), down(v.py, d.py, n), down(v.pz, d.pz, n);
  down(v.vx, d.vx, n), down(v.vy, d.vy, n), down(v.vz, d.vz, n);
  down(v.wx, d.wx, n), down(v.wy, d.wy, n), down(v.wz, d.wz, n);
  down(v.qw, d.qw, n), down(v.qx, d.qx, n), down(v.qy, d.qy, n), down(v.qz, d.qz, n);
  down(v.fx, d.fx, n), down(v.fy, d.fy, n), down(v.fz, d.fz, n);
  down(v.tx, d.tx, n), down(v.ty, d.ty, n), down(v.tz, d.tz, n);
  if (v.periodic && d.periodic) down(v.image, d.image, 3 * n);
  if (v.friction && v.shear && b->npairs == v.npairs) down(v.shear, d.shear, 3 * v.npairs);
  if (v.rhist && b->npairs == v.npairs) down(v.rhist, d.rhist, 3 * v.npairs);
  if (v.poly && b->npairs == v.npairs) {
    down(v.paxis, d.paxis, 3 * v.npairs), down(v.pfeat, d.pfeat, 6 * v.npairs);
    down(v.ptj, d.ptj, 3 * v.npairs);
  }
  if (v.ntris > 0) {
    const std::size_t ns = static_cast<std::size_t>(phys::kMaxWallContacts) * n;
    down(v.wkey, d.wkey, ns), down(v.wshear, d.wshear, 3 * ns), down(v.wf, d.wf, 3 * ns);
    down(v.wp, d.wp, 3 * ns), down(v.wb, d.wb, 3 * ns), down(v.wtri, d.wtri, ns);
    down(v.wcount, d.wcount, n);
    if (v.wroll) down(v.wroll, d.wroll, 3 * ns);
  }
  if (v.ntris > 0 && v.walls_moving && b->walls_moving && b->nverts == v.nverts) {
    down(v.vpos, d.vpos, 3 * v.nverts), down(v.vvel, d.vvel, 3 * v.nverts);
    if (v.flex_force && b->flex_nodes == v.flex_nodes)
      down(v.flex_force, d.flex_force, 3 * v.flex_nodes);
  }
}

namespace {
// The arrays a list build may move (the captured step holds their addresses).
std::array<const void*, 17> list_arrays(const Dev& d) {
  return {d.row, d.trow, d.tpair, d.nbr,   d.bx,    d.by,  d.bz,   d.pf,  d.shear,
          d.pt,  d.pr,   d.rhist, d.paxis, d.pfeat, d.ptj, d.prow, d.ptri};
}
}  // namespace

std::size_t cuda_build_lists(CudaBackend* b, double skin, double rmax) {
  const std::size_t n = b->n;
  std::size_t* c = b->cap;
  Dev& d = b->d;
  check(cudaStreamSynchronize(b->stream), "cudaStreamSynchronize");  // the drift is done
  DeviceListInput in;
  in.n = n, in.px = d.px, in.py = d.py, in.pz = d.pz, in.radius = d.radius;
  in.rmax = rmax, in.skin = skin;
  in.box = d.pbox, in.periodic = d.periodic;
  in.old_npairs = b->npairs, in.old_row = d.row, in.old_nbr = d.nbr;
  in.ntris = d.walls ? b->ntris : 0, in.vpos = d.vpos, in.tri_v = d.tri_v;
  const DeviceListCounts counts = b->list.count(in);
  const auto before = list_arrays(d);
  const std::size_t np = counts.npairs, old = b->npairs;
  const std::size_t keep = np > old ? np : old;  // histories: old values in, new values out
  ensure(d.row, c[26], n + 1), ensure(d.trow, c[27], n + 1);
  ensure(d.tpair, c[28], np), ensure(d.nbr, c[29], np);
  ensure(d.bx, c[30], n), ensure(d.by, c[31], n), ensure(d.bz, c[32], n);
  ensure(d.pf, c[33], 3 * np);
  DeviceListOutput out;
  out.row = d.row, out.trow = d.trow, out.tpair = d.tpair, out.nbr = d.nbr;
  out.bx = d.bx, out.by = d.by, out.bz = d.bz;
  if (b->friction) {
    ensure_keep(d.shear, c[34], 3 * keep, 3 * old);
    ensure(d.pt, c[35], 3 * np), ensure(d.pr, c[36], 3 * np);
    out.hist[0].values = d.shear;
    if (b->rolling) {
      ensure_keep(d.rhist, c[37], 3 * keep, 3 * old);
      out.hist[1].values = d.rhist;
    }
  }
  if (d.poly) {
    ensure_keep(d.paxis, c[82], 3 * keep, 3 * old), ensure_keep(d.pfeat, c[83], 6 * keep, 6 * old);
    ensure(d.ptj, c[84], 3 * np), ensure(d.pt, c[35], 3 * np);
    out.hist[2].values = d.paxis;
    out.feat.values = d.pfeat;
  }
  if (in.ntris > 0) {
    ensure(d.prow, c[53], n + 1), ensure(d.ptri, c[54], counts.nptri);
    out.prow = d.prow, out.ptri = d.ptri;
  }
  b->list.fill(in, out);
  if (in.ntris > 0 && b->walls_moving)  // the wall vertices at the build
    check(cudaMemcpy(d.vbuild, d.vpos, 3 * b->nverts * sizeof(double), cudaMemcpyDeviceToDevice),
          "cudaMemcpy");
  check(cudaDeviceSynchronize(), "list build");
  b->npairs = np, b->nptri = counts.nptri;
  // the captured step holds the arrays' addresses: capture again only when one moved
  if (b->graph && before != list_arrays(d)) cudaGraphExecDestroy(b->graph), b->graph = nullptr;
  return np;
}

void cuda_list_sizes(CudaBackend* b, std::size_t* npairs, std::size_t* nptri) {
  *npairs = b->npairs;
  *nptri = b->nptri;
}

void cuda_download_lists(CudaBackend* b, const GpuListDownload& v) {
  const std::size_t n = b->n;
  const Dev& d = b->d;
  check(cudaStreamSynchronize(b->stream), "cudaStreamSynchronize");
  down(v.row, d.row, n + 1), down(v.nbr, d.nbr, b->npairs);
  down(v.bx, d.bx, n), down(v.by, d.by, n), down(v.bz, d.bz, n);
  if (v.prow != nullptr && b->ntris > 0)
    down(v.prow, d.prow, n + 1), down(v.ptri, d.ptri, b->nptri);
  if (v.vbuild != nullptr && b->walls_moving) down(v.vbuild, d.vbuild, 3 * b->nverts);
}

namespace {
constexpr int kBlock = 128;

void enqueue_forces(CudaBackend* b, bool force) {
  const std::size_t n = b->n;
  const unsigned grid = static_cast<unsigned>((n + kBlock - 1) / kBlock);
  if (grid == 0) return;
  if (b->friction) {
    k_pairs<true><<<grid, kBlock, 0, b->stream>>>(b->d, n, b->nmat, b->dt, b->rolling, force);
    k_gather_kick<true><<<grid, kBlock, 0, b->stream>>>(b->d, n, b->nmat, b->dt, b->g[0], b->g[1],
                                                        b->g[2], b->rolling, force);
  } else {
    k_pairs<false><<<grid, kBlock, 0, b->stream>>>(b->d, n, b->nmat, b->dt, b->rolling, force);
    k_gather_kick<false><<<grid, kBlock, 0, b->stream>>>(b->d, n, b->nmat, b->dt, b->g[0], b->g[1],
                                                         b->g[2], b->rolling, force);
  }
  if (b->nfrozen > 0) {  // their second half kick undone
    const unsigned gridh = static_cast<unsigned>((b->nfrozen + kBlock - 1) / kBlock);
    k_hold<<<gridh, kBlock, 0, b->stream>>>(b->d, b->nfrozen, force);
  }
  if (b->flex_nodes > 0) {
    const std::size_t n3 = 3 * b->flex_nodes;
    const unsigned gridf = static_cast<unsigned>((n3 + kBlock - 1) / kBlock);
    k_flex_fold<<<gridf, kBlock, 0, b->stream>>>(b->d, n3, b->flex_average, b->flex_inv, force);
  }
}

void enqueue_step(CudaBackend* b, double skin) {
  const std::size_t n = b->n;
  const unsigned grid = static_cast<unsigned>((n + kBlock - 1) / kBlock);
  const double half_skin = 0.5 * skin;
  k_kick_drift<<<grid, kBlock, 0, b->stream>>>(b->d, n, b->dt, half_skin * half_skin, b->friction,
                                               b->orientation, b->walls_moving);
  if (b->nfrozen > 0) {
    const unsigned gridh = static_cast<unsigned>((b->nfrozen + kBlock - 1) / kBlock);
    k_hold<<<gridh, kBlock, 0, b->stream>>>(b->d, b->nfrozen, false);
  }
  if (b->walls_moving && b->nverts > 0) {
    const unsigned gridv = static_cast<unsigned>((b->nverts + kBlock - 1) / kBlock);
    k_walls<<<gridv, kBlock, 0, b->stream>>>(b->d, b->nverts, b->dt);
  }
  k_latch<<<1, 1, 0, b->stream>>>(b->d, b->dt, skin, b->walls_moving);
  enqueue_forces(b, false);
}
}  // namespace

namespace {
// The graph of one step: captured again when an argument it holds changed (the device
// pointers in Dev, which a list build or an upload may move; the skin; the ForceMode fold).
void ensure_graph(CudaBackend* b, double skin) {
  if (b->graph && b->graph_skin == skin && b->graph_flex_average == b->flex_average &&
      b->graph_flex_inv == b->flex_inv && std::memcmp(&b->graph_dev, &b->d, sizeof(Dev)) == 0)
    return;
  if (b->graph) cudaGraphExecDestroy(b->graph), b->graph = nullptr;
  cudaGraph_t g;
  check(cudaStreamBeginCapture(b->stream, cudaStreamCaptureModeThreadLocal), "capture");
  enqueue_step(b, skin);
  check(cudaStreamEndCapture(b->stream, &g), "capture");
  check(cudaGraphInstantiate(&b->graph, g, 0), "cudaGraphInstantiate");
  cudaGraphDestroy(g);
  b->graph_skin = skin;
  b->graph_flex_average = b->flex_average, b->graph_flex_inv = b->flex_inv;
  std::memcpy(&b->graph_dev, &b->d, sizeof(Dev));
}

// The summary into pinned memory, and the event that says it has arrived (no wait).
void copy_summary(CudaBackend* b) {
  check(cudaMemcpyAsync(b->summary_host, b->summary_dev, sizeof(DeviceSummary),
                        cudaMemcpyDeviceToHost, b->stream),
        "summary");
  check(cudaEventRecord(b->chunk_done, b->stream), "cudaEventRecord");
}

// Whether all work enqueued so far is done and its summary asks for a list build (a query,
// not a wait: the device goes on with what is queued).
bool stop_seen(CudaBackend* b) {
  const cudaError_t e = cudaEventQuery(b->chunk_done);
  if (e == cudaErrorNotReady) return false;
  check(e, "cudaEventQuery");
  return b->summary_host->stop[0] != 0;
}

constexpr std::int64_t kChunk = 256;  // steps enqueued between two looks at cancel and stop
}  // namespace

std::int64_t cuda_run_steps(CudaBackend* b, std::int64_t steps, double skin, double t, double tau,
                            const std::atomic<bool>* cancel) {
  if (b->n == 0) return steps;
  check(cudaMemsetAsync(b->d.stop, 0, 2 * sizeof(int), b->stream), "cudaMemset");
  check(cudaMemsetAsync(b->d.steps_done, 0, sizeof(unsigned long long), b->stream), "cudaMemset");
  check(cudaMemsetAsync(b->d.pdisp2, 0, sizeof(unsigned long long), b->stream), "cudaMemset");
  check(cudaMemsetAsync(b->d.wdisp2, 0, sizeof(unsigned long long), b->stream), "cudaMemset");
  // The clock of the host (pageable source: the call returns once it has been staged).
  const double clock[2] = {t, tau};
  check(cudaMemcpyAsync(b->d.clock, clock, sizeof(clock), cudaMemcpyHostToDevice, b->stream),
        "clock");
  ensure_graph(b, skin);
  // One batch of steps, then one wait. Steps after a build request return at once on the
  // device, so a batch is capped at twice the steps between the last two builds (all steps
  // while the list lasts, as in a settled bed: one wait per advance()). Within the batch the
  // host looks, every kChunk steps and without waiting, at the cancel flag and at the summary
  // of the work already done, and stops enqueueing when either says so.
  const std::int64_t cap = 2 * b->steps_between_builds > kChunk ? 2 * b->steps_between_builds
                                                                : kChunk;
  const std::int64_t batch = steps < cap ? steps : cap;
  for (std::int64_t queued = 0; queued < batch;) {
    const std::int64_t chunk = batch - queued < kChunk ? batch - queued : kChunk;
    for (std::int64_t k = 0; k < chunk; ++k) check(cudaGraphLaunch(b->graph, b->stream), "launch");
    queued += chunk;
    copy_summary(b);
    if (cancel != nullptr && cancel->load(std::memory_order_relaxed)) break;  // a stop request
    if (queued < batch && stop_seen(b)) break;
  }
  check(cudaStreamSynchronize(b->stream), "cudaStreamSynchronize");  // the batch's one wait
  const std::int64_t done = static_cast<std::int64_t>(b->summary_host->steps_done);
  b->steps_since_build += done;
  if (b->summary_host->stop[0]) {
    b->steps_between_builds = b->steps_since_build;
    b->steps_since_build = 0;
  }
  return done;
}

bool cuda_build_pending(CudaBackend* b) {
  return b->summary_host->stop[0] != 0;
}

void cuda_finish_step(CudaBackend* b) {
  enqueue_forces(b, true);
  check(cudaMemsetAsync(b->d.stop, 0, 2 * sizeof(int), b->stream), "cudaMemset");
  copy_summary(b);
  check(cudaStreamSynchronize(b->stream), "cudaStreamSynchronize");
}

void cuda_upload_wall_vertices(CudaBackend* b, const GpuHostView& v) {
  if (b->nverts != v.nverts) throw std::logic_error("cuda_upload_wall_vertices: vertex count");
  up_async(b->d.vpos, b->cap[40], v.vpos, 3 * v.nverts, b->stream);
  up_async(b->d.vvel, b->cap[41], v.vvel, 3 * v.nverts, b->stream);
}

void cuda_download_wall_contacts(CudaBackend* b, const GpuHostView& v) {
  const Dev& d = b->d;
  check(cudaStreamSynchronize(b->stream), "cudaStreamSynchronize");
  const std::size_t ns = static_cast<std::size_t>(phys::kMaxWallContacts) * b->n;
  down(v.wf, d.wf, 3 * ns), down(v.wp, d.wp, 3 * ns), down(v.wb, d.wb, 3 * ns);
  down(v.wtri, d.wtri, ns), down(v.wcount, d.wcount, b->n);
}

namespace {
double bits_value(unsigned long long bits) {
  double v = 0.0;
  std::memcpy(&v, &bits, sizeof(v));
  return v;
}
}  // namespace

// The maxima of the summary read at the last wait (no transfer).
double cuda_max_overlap(CudaBackend* b) {
  return bits_value(b->summary_host->max_ov);
}

double cuda_flex_max_overlap(CudaBackend* b) {
  return bits_value(b->summary_host->flex_max_ov);
}

double cuda_advance_max_overlap(CudaBackend* b) {
  return bits_value(b->summary_host->adv_max_ov);
}

double cuda_advance_max_relative_overlap(CudaBackend* b) {
  return bits_value(b->summary_host->adv_max_rel);
}

}  // namespace demfem::dem
