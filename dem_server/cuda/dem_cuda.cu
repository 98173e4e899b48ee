// CUDA backend of DemSystem: the same physics headers as the CPU backend
// (physics/contact.hpp, physics/integrator.hpp) over device structure-of-arrays state.
// Static rigid walls use the shared sphere-triangle contact set (physics/wall_contact.hpp)
// inside the gather kernel. One step is three kernels (kick+drift, pair forces per CSR row,
// gather+kick), captured once into a CUDA graph and replayed without host synchronisation; the host
// reads one flag per chunk of steps to learn whether the neighbour list must be rebuilt. Sums are
// in a fixed order (per-pair slots gathered per particle), so results are deterministic; the only
// atomics are integer ones (flags, step counter, the bit pattern of the max overlap).

#include <cuda_runtime.h>

#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <string>

#include "core/dem_cuda_backend.hpp"
#include "demfem/dem/physics/contact.hpp"
#include "demfem/dem/physics/integrator.hpp"
#include "demfem/dem/physics/pair.hpp"

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
  int* stop;
  unsigned long long* steps_done;
  unsigned long long* max_ov;
};

__global__ void k_kick_drift(Dev d, std::size_t n, double dt, double half_skin2, bool friction) {
  if (*d.stop) return;
  const std::size_t i = blockIdx.x * static_cast<std::size_t>(blockDim.x) + threadIdx.x;
  if (i == 0) *d.max_ov = 0ull;  // max overlap of this step (read after the pair kernel)
  if (i >= n) return;
  const double h = 0.5 * dt;
  phys::kick(d.vx[i], d.vy[i], d.vz[i], d.fx[i], d.fy[i], d.fz[i], h / d.mass[i]);
  d.px[i] += dt * d.vx[i];
  d.py[i] += dt * d.vy[i];
  d.pz[i] += dt * d.vz[i];
  if (friction) phys::kick(d.wx[i], d.wy[i], d.wz[i], d.tx[i], d.ty[i], d.tz[i], h / d.inertia[i]);
  phys::rotate_quaternion(d.qw[i], d.qx[i], d.qy[i], d.qz[i], d.wx[i], d.wy[i], d.wz[i], dt);
  const double dx = d.px[i] - d.bx[i], dy = d.py[i] - d.by[i], dz = d.pz[i] - d.bz[i];
  if (dx * dx + dy * dy + dz * dz > half_skin2) atomicExch(d.stop + 1, 1);
}

// Promotes a pending rebuild request (stop[1]) to a stop of the following kernels.
__global__ void k_latch(Dev d) {
  if (d.stop[1] && !d.stop[0]) d.stop[0] = 2;  // 2: drift of this step done, forces pending
}

template <bool Friction>
__global__ void k_pairs(Dev d, std::size_t n, std::size_t nmat, double dt, bool rolling,
                        bool force) {
  if (*d.stop && !force) return;
  const std::size_t i = blockIdx.x * static_cast<std::size_t>(blockDim.x) + threadIdx.x;
  if (i >= n) return;
  double ax = 0, ay = 0, az = 0, qx = 0, qy = 0, qz = 0, mo = 0;
  const double ri = d.radius[i];
  const std::size_t mrow = static_cast<std::size_t>(d.material[i]) * nmat;
  const phys::ParticleView view{d.px, d.py, d.pz, d.vx,     d.vy,  d.vz,
                                d.wx, d.wy, d.wz, d.radius, d.mass};
  for (std::int64_t p = d.row[i]; p < d.row[i + 1]; ++p) {
    const std::int32_t j = d.nbr[p];
    double* f = d.pf + 3 * p;
    phys::Vec3 sh{0, 0, 0}, rh{0, 0, 0};
    if (Friction) sh = phys::Vec3{d.shear[3 * p], d.shear[3 * p + 1], d.shear[3 * p + 2]};
    if (Friction && rolling)
      rh = phys::Vec3{d.rhist[3 * p], d.rhist[3 * p + 1], d.rhist[3 * p + 2]};
    phys::ContactResult r;
    double delta = 0.0;
    if (!phys::sphere_sphere<Friction>(view, static_cast<int>(i), j, d.pc[mrow + d.material[j]], dt,
                                       sh, rh, r, delta)) {
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
  if (mo > 0.0) atomicMax(d.max_ov, static_cast<unsigned long long>(__double_as_longlong(mo)));
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
  if (Friction) qx = d.acct[3 * i], qy = d.acct[3 * i + 1], qz = d.acct[3 * i + 2];
  const double ri = d.radius[i];
  for (std::int64_t k = d.trow[i]; k < d.trow[i + 1]; ++k) {
    const std::int64_t p = d.tpair[k];
    fx -= d.pf[3 * p], fy -= d.pf[3 * p + 1], fz -= d.pf[3 * p + 2];
    if (Friction) {
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
    phys::Vec3 f{fx, fy, fz}, q{qx, qy, qz};
    double mo = 0.0, fmo = 0.0;
    phys::wall_contacts<Friction>(view, wv, static_cast<std::int64_t>(i),
                                  d.pc + static_cast<std::size_t>(d.material[i]) * nmat, dt, f, q,
                                  mo, fmo);
    fx = f.x, fy = f.y, fz = f.z;
    qx = q.x, qy = q.y, qz = q.z;
    if (mo > 0.0) atomicMax(d.max_ov, static_cast<unsigned long long>(__double_as_longlong(mo)));
  }
  const double m = d.mass[i];
  fx += m * gx, fy += m * gy, fz += m * gz;
  d.fx[i] = fx, d.fy[i] = fy, d.fz[i] = fz;
  const double h = 0.5 * dt;
  phys::kick(d.vx[i], d.vy[i], d.vz[i], fx, fy, fz, h / m);
  if (Friction) {
    d.tx[i] = qx, d.ty[i] = qy, d.tz[i] = qz;
    phys::kick(d.wx[i], d.wy[i], d.wz[i], qx, qy, qz, h / d.inertia[i]);
  }
}

}  // namespace

struct CudaBackend {
  Dev d{};
  std::size_t cap[64] = {};
  std::size_t n = 0, npairs = 0, nmat = 0;
  double dt = 0, g[3] = {0, 0, 0};
  bool friction = false, rolling = false;
  cudaStream_t stream = nullptr;
  cudaGraphExec_t graph = nullptr;
  double graph_half_skin = -1.0;
  int* host_flags = nullptr;  // pinned: stop[2], steps_done (as 2 ints)
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
  check(cudaMalloc(&b->d.stop, 2 * sizeof(int)), "cudaMalloc");
  check(cudaMalloc(&b->d.steps_done, sizeof(unsigned long long)), "cudaMalloc");
  check(cudaMalloc(&b->d.max_ov, sizeof(unsigned long long)), "cudaMalloc");
  check(cudaMemset(b->d.stop, 0, 2 * sizeof(int)), "cudaMemset");
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
  cudaFree(b->d.nbr), cudaFree(b->d.pc), cudaFree(b->d.stop), cudaFree(b->d.steps_done);
  cudaFree(b->d.max_ov);
  cudaFree(b->d.vpos), cudaFree(b->d.vvel), cudaFree(b->d.tri_v), cudaFree(b->d.tri_e);
  cudaFree(b->d.tri_mat), cudaFree(b->d.tri_wall), cudaFree(b->d.prow), cudaFree(b->d.ptri);
  cudaFree(b->d.wkey), cudaFree(b->d.wshear), cudaFree(b->d.wf), cudaFree(b->d.wp);
  cudaFree(b->d.wb), cudaFree(b->d.wtri), cudaFree(b->d.wcount);
  cudaFree(b->d.rhist), cudaFree(b->d.wroll);
  if (b->stream) cudaStreamDestroy(b->stream);
  delete b;
}

namespace {
template <class T>
void up(T*& dst, std::size_t& cap, const T* src, std::size_t n) {
  ensure(dst, cap, n);
  if (n) check(cudaMemcpy(dst, src, n * sizeof(T), cudaMemcpyHostToDevice), "upload");
}
template <class T>
void down(T* dst, const T* src, std::size_t n) {
  if (n) check(cudaMemcpy(dst, src, n * sizeof(T), cudaMemcpyDeviceToHost), "download");
}
}  // namespace

void cuda_upload_state(CudaBackend* b, const GpuHostView& v) {
  const std::size_t n = v.n;
  b->n = n, b->nmat = v.nmat, b->dt = v.dt, b->friction = v.friction, b->rolling = v.rolling;
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
  d.walls = v.ntris > 0;
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
  check(cudaMemset(d.max_ov, 0, sizeof(unsigned long long)), "cudaMemset");
  if (b->graph) cudaGraphExecDestroy(b->graph), b->graph = nullptr;  // pointers may move
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
  if (v.friction) {
    up(d.shear, c[34], v.shear, 3 * np);
    ensure(d.pt, c[35], 3 * np), ensure(d.pr, c[36], 3 * np);
    if (v.rhist) up(d.rhist, c[37], v.rhist, 3 * np);
  }
  if (b->graph) cudaGraphExecDestroy(b->graph), b->graph = nullptr;
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
  if (v.friction && v.shear && b->npairs == v.npairs) down(v.shear, d.shear, 3 * v.npairs);
  if (v.rhist && b->npairs == v.npairs) down(v.rhist, d.rhist, 3 * v.npairs);
  if (v.ntris > 0) {
    const std::size_t ns = static_cast<std::size_t>(phys::kMaxWallContacts) * n;
    down(v.wkey, d.wkey, ns), down(v.wshear, d.wshear, 3 * ns), down(v.wf, d.wf, 3 * ns);
    down(v.wp, d.wp, 3 * ns), down(v.wb, d.wb, 3 * ns), down(v.wtri, d.wtri, ns);
    down(v.wcount, d.wcount, n);
    if (v.wroll) down(v.wroll, d.wroll, 3 * ns);
  }
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
}

void enqueue_step(CudaBackend* b, double half_skin) {
  const std::size_t n = b->n;
  const unsigned grid = static_cast<unsigned>((n + kBlock - 1) / kBlock);
  k_kick_drift<<<grid, kBlock, 0, b->stream>>>(b->d, n, b->dt, half_skin * half_skin, b->friction);
  k_latch<<<1, 1, 0, b->stream>>>(b->d);
  enqueue_forces(b, false);
}
}  // namespace

std::int64_t cuda_run_steps(CudaBackend* b, std::int64_t steps, double half_skin) {
  if (b->n == 0) return steps;
  check(cudaMemsetAsync(b->d.stop, 0, 2 * sizeof(int), b->stream), "cudaMemset");
  check(cudaMemsetAsync(b->d.steps_done, 0, sizeof(unsigned long long), b->stream), "cudaMemset");
  if (!b->graph || b->graph_half_skin != half_skin) {
    if (b->graph) cudaGraphExecDestroy(b->graph), b->graph = nullptr;
    cudaGraph_t g;
    check(cudaStreamBeginCapture(b->stream, cudaStreamCaptureModeThreadLocal), "capture");
    enqueue_step(b, half_skin);
    check(cudaStreamEndCapture(b->stream, &g), "capture");
    check(cudaGraphInstantiate(&b->graph, g, 0), "cudaGraphInstantiate");
    cudaGraphDestroy(g);
    b->graph_half_skin = half_skin;
  }
  // Replay in chunks; steps after a rebuild request return at once on the device.
  std::int64_t done = 0;
  int flags[2] = {0, 0};
  unsigned long long count = 0;
  while (done < steps) {
    const std::int64_t chunk = steps - done < 256 ? steps - done : 256;
    for (std::int64_t k = 0; k < chunk; ++k) check(cudaGraphLaunch(b->graph, b->stream), "launch");
    check(cudaMemcpyAsync(flags, b->d.stop, 2 * sizeof(int), cudaMemcpyDeviceToHost, b->stream),
          "flags");
    check(
        cudaMemcpyAsync(&count, b->d.steps_done, sizeof(count), cudaMemcpyDeviceToHost, b->stream),
        "flags");
    check(cudaStreamSynchronize(b->stream), "cudaStreamSynchronize");
    done = static_cast<std::int64_t>(count);
    if (flags[0]) break;
  }
  return done;
}

void cuda_finish_step(CudaBackend* b) {
  enqueue_forces(b, true);
  check(cudaMemsetAsync(b->d.stop, 0, 2 * sizeof(int), b->stream), "cudaMemset");
  check(cudaStreamSynchronize(b->stream), "cudaStreamSynchronize");
}

double cuda_max_overlap(CudaBackend* b) {
  unsigned long long bits = 0;
  check(cudaMemcpy(&bits, b->d.max_ov, sizeof(bits), cudaMemcpyDeviceToHost), "max_overlap");
  double v = 0.0;
  std::memcpy(&v, &bits, sizeof(v));
  return v;
}

}  // namespace demfem::dem
