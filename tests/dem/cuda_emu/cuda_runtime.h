#pragma once
// Test double of the CUDA runtime for the CUDA backend (dem_server/cuda/dem_cuda.cu) without a
// GPU: make_emu_source.cmake turns each launch `k<<<grid, block, shmem, stream>>>(args)` into
// EMU_LAUNCH(grid, block, shmem, stream, k, args); the kernels then run here one thread after
// another on the host, device memory is host memory, a stream runs its work at once and a
// captured graph is the list of its launches (arguments taken at capture, as CUDA does).
// Warp shuffles return the lane's own value and every thread counts as lane 0, so a warp
// reduction followed by one atomic from lane 0 becomes one atomic per thread (the same result).
// What this checks: the host orchestration and the kernels' arithmetic and indexing. What it
// does not: concurrency, the real warp shuffle, the device's sin/cos, memory limits.
// It also counts what a device would cost the host (emu_counters): the times the host waits
// for queued device work (an explicit synchronisation, or a blocking transfer, while work is
// queued: on a device such a call waits for that work), the bytes copied to the device and
// the graph captures. Device work here is done at once; `busy` records that some would be
// queued on a device.

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <set>
#include <vector>

#define DEMFEM_CUDA_EMULATION 1

#define __global__
#define __device__
#define __host__
#define __forceinline__ inline

struct EmuIndex {
  unsigned value = 0;
  operator unsigned() const { return value; }  // NOLINT: used as an integer by the kernels
};
inline unsigned operator&(EmuIndex, unsigned) {
  return 0;  // every thread is lane 0 of its warp (see above)
}
struct EmuDim3 {
  EmuIndex x;
};
inline thread_local EmuDim3 blockIdx, threadIdx, blockDim;

struct EmuCounters {
  long host_waits = 0;              // waits for queued device work
  unsigned long long bytes_to_device = 0;
  long captures = 0;                // stream captures (graphs built)
  bool busy = false;                // device work queued since the last wait
  std::set<const void*> pinned;     // host memory from cudaMallocHost
};
inline EmuCounters emu_counters;
inline void emu_enqueue() {
  emu_counters.busy = true;
}
inline void emu_wait() {
  if (emu_counters.busy) ++emu_counters.host_waits;
  emu_counters.busy = false;
}

using cudaError_t = int;
constexpr cudaError_t cudaSuccess = 0;
constexpr cudaError_t cudaErrorNotReady = 600;
inline const char* cudaGetErrorString(cudaError_t) {
  return "emulated CUDA error";
}
inline cudaError_t cudaGetLastError() {
  return cudaSuccess;
}
inline cudaError_t cudaGetDeviceCount(int* count) {
  *count = 1;
  return cudaSuccess;
}
enum cudaMemcpyKind { cudaMemcpyHostToDevice, cudaMemcpyDeviceToHost, cudaMemcpyDeviceToDevice };
enum cudaStreamCaptureMode { cudaStreamCaptureModeThreadLocal };

struct EmuGraph {
  std::vector<std::function<void()>> launches;
};
using cudaStream_t = EmuGraph*;  // unused handle
using cudaGraph_t = EmuGraph*;
using cudaGraphExec_t = EmuGraph*;
inline EmuGraph* emu_capture = nullptr;  // the graph being captured, if any

[[noreturn]] inline void emu_fail(const char* what) {
  std::fprintf(stderr, "CUDA emulation: %s\n", what);
  std::abort();
}

// Device memory is filled with a pattern, so that reading what was never written shows.
template <class T>
cudaError_t cudaMalloc(T** p, std::size_t bytes) {
  *p = static_cast<T*>(std::malloc(bytes));
  if (!*p) emu_fail("out of memory");
  std::memset(static_cast<void*>(*p), 0xA5, bytes);
  return cudaSuccess;
}
inline cudaError_t cudaFree(void* p) {
  std::free(p);
  return cudaSuccess;
}
template <class T>
cudaError_t cudaMallocHost(T** p, std::size_t bytes) {
  *p = static_cast<T*>(std::malloc(bytes));
  if (!*p) emu_fail("out of memory");
  emu_counters.pinned.insert(*p);
  return cudaSuccess;
}
inline cudaError_t cudaFreeHost(void* p) {
  emu_counters.pinned.erase(p);
  std::free(p);
  return cudaSuccess;
}
inline void emu_copy(void* dst, const void* src, std::size_t bytes, cudaMemcpyKind kind) {
  if (emu_capture) emu_fail("cudaMemcpy during stream capture");
  if (kind == cudaMemcpyHostToDevice) emu_counters.bytes_to_device += bytes;
  std::memcpy(dst, src, bytes);
}
// Blocking: waits for the queued work first.
inline cudaError_t cudaMemcpy(void* dst, const void* src, std::size_t bytes, cudaMemcpyKind kind) {
  emu_wait();
  emu_copy(dst, src, bytes, kind);
  return cudaSuccess;
}
// Queued, except a copy to pageable host memory, which returns once it is done (a wait).
inline cudaError_t cudaMemcpyAsync(void* dst, const void* src, std::size_t bytes,
                                   cudaMemcpyKind kind, cudaStream_t) {
  if (kind == cudaMemcpyDeviceToHost && emu_counters.pinned.count(dst) == 0) emu_wait();
  else emu_enqueue();
  emu_copy(dst, src, bytes, kind);
  return cudaSuccess;
}
inline cudaError_t cudaMemset(void* dst, int value, std::size_t bytes) {
  if (emu_capture) emu_fail("cudaMemset during stream capture");
  emu_enqueue();
  std::memset(dst, value, bytes);
  return cudaSuccess;
}
inline cudaError_t cudaMemsetAsync(void* dst, int value, std::size_t bytes, cudaStream_t) {
  return cudaMemset(dst, value, bytes);
}
inline cudaError_t cudaStreamCreate(cudaStream_t* s) {
  *s = nullptr;
  return cudaSuccess;
}
inline cudaError_t cudaStreamDestroy(cudaStream_t) {
  return cudaSuccess;
}
inline cudaError_t cudaStreamSynchronize(cudaStream_t) {
  emu_wait();
  return cudaSuccess;
}
inline cudaError_t cudaDeviceSynchronize() {
  emu_wait();
  return cudaSuccess;
}
// Events: the work before a record is done at once here, so a query finds it done.
using cudaEvent_t = int*;
constexpr unsigned cudaEventDisableTiming = 2;
inline cudaError_t cudaEventCreateWithFlags(cudaEvent_t* e, unsigned) {
  *e = new int(0);
  return cudaSuccess;
}
inline cudaError_t cudaEventDestroy(cudaEvent_t e) {
  delete e;
  return cudaSuccess;
}
inline cudaError_t cudaEventRecord(cudaEvent_t, cudaStream_t) {
  return cudaSuccess;
}
inline cudaError_t cudaEventQuery(cudaEvent_t) {
  return cudaSuccess;
}
inline cudaError_t cudaStreamBeginCapture(cudaStream_t, cudaStreamCaptureMode) {
  if (emu_capture) emu_fail("nested stream capture");
  emu_capture = new EmuGraph;
  ++emu_counters.captures;
  return cudaSuccess;
}
inline cudaError_t cudaStreamEndCapture(cudaStream_t, cudaGraph_t* g) {
  *g = emu_capture;
  emu_capture = nullptr;
  return cudaSuccess;
}
inline cudaError_t cudaGraphInstantiate(cudaGraphExec_t* exec, cudaGraph_t g, int) {
  *exec = new EmuGraph(*g);
  return cudaSuccess;
}
inline cudaError_t cudaGraphDestroy(cudaGraph_t g) {
  delete g;
  return cudaSuccess;
}
inline cudaError_t cudaGraphExecDestroy(cudaGraphExec_t g) {
  delete g;
  return cudaSuccess;
}
inline cudaError_t cudaGraphLaunch(cudaGraphExec_t g, cudaStream_t) {
  emu_enqueue();
  for (auto& launch : g->launches) launch();
  return cudaSuccess;
}

inline int atomicExch(int* p, int v) {
  const int old = *p;
  *p = v;
  return old;
}
inline unsigned long long atomicMax(unsigned long long* p, unsigned long long v) {
  const unsigned long long old = *p;
  if (v > old) *p = v;
  return old;
}
inline unsigned long long atomicAdd(unsigned long long* p, unsigned long long v) {
  const unsigned long long old = *p;
  *p += v;
  return old;
}
inline double atomicAdd(double* p, double v) {
  const double old = *p;
  *p += v;
  return old;
}
inline double __shfl_down_sync(unsigned, double v, int) {
  return v;  // the lane's own value (see above)
}
inline long long __double_as_longlong(double v) {
  long long r;
  std::memcpy(&r, &v, sizeof(r));
  return r;
}
inline double __longlong_as_double(long long v) {
  double r;
  std::memcpy(&r, &v, sizeof(r));
  return r;
}
using std::fmax;
using std::sqrt;

// Runs (or, while capturing, records) a kernel over grid x block threads; the arguments are
// copied now, as a launch does.
template <class Kernel, class... Args>
void emu_launch(unsigned grid, unsigned block, Kernel kernel, Args... args) {
  auto run = [=]() {
    for (unsigned b = 0; b < grid; ++b)
      for (unsigned t = 0; t < block; ++t) {
        blockIdx.x.value = b, threadIdx.x.value = t, blockDim.x.value = block;
        kernel(args...);
      }
  };
  if (emu_capture) {
    emu_capture->launches.push_back(run);
  } else {
    emu_enqueue();
    run();
  }
}
#define EMU_LAUNCH(grid, block, shmem, stream, kernel, ...) \
  emu_launch(static_cast<unsigned>(grid), static_cast<unsigned>(block), kernel, __VA_ARGS__)
