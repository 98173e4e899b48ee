// cuda_available() and, in builds without CUDA, the backend entry points (which are never
// reached: DemSystem refuses backend = "cuda" when cuda_available() is false).

#include <stdexcept>

#include "dem_cuda_backend.hpp"
#include "demfem/dem/dem_system.hpp"

namespace demfem::dem {

bool cuda_available() {
#ifdef DEMFEM_HAVE_CUDA
  return cuda_device_present();
#else
  return false;
#endif
}

#ifndef DEMFEM_HAVE_CUDA
namespace {
[[noreturn]] void no_cuda() {
  throw std::runtime_error("DemSystem: this build has no CUDA backend (DEMFEM_CUDA=OFF)");
}
}  // namespace
bool cuda_device_present() {
  return false;
}
CudaBackend* cuda_backend_create() {
  no_cuda();
}
void cuda_backend_destroy(CudaBackend*) {}
void cuda_upload_state(CudaBackend*, const GpuHostView&) {
  no_cuda();
}
void cuda_upload_lists(CudaBackend*, const GpuHostView&) {
  no_cuda();
}
void cuda_begin_advance(CudaBackend*, const GpuHostView&) {
  no_cuda();
}
bool cuda_resident(CudaBackend*, std::size_t, std::size_t) {
  return false;
}
void cuda_set_resident(CudaBackend*, bool) {}
void cuda_download_state(CudaBackend*, const GpuHostView&) {
  no_cuda();
}
std::int64_t cuda_run_steps(CudaBackend*, std::int64_t, double, double, double,
                            const std::atomic<bool>*) {
  no_cuda();
}
std::size_t cuda_build_lists(CudaBackend*, double, double) {
  no_cuda();
}
void cuda_list_sizes(CudaBackend*, std::size_t*, std::size_t*) {
  no_cuda();
}
void cuda_download_lists(CudaBackend*, const GpuListDownload&) {
  no_cuda();
}
bool cuda_build_pending(CudaBackend*) {
  no_cuda();
}
void cuda_finish_step(CudaBackend*) {
  no_cuda();
}
void cuda_upload_wall_vertices(CudaBackend*, const GpuHostView&) {
  no_cuda();
}
void cuda_download_wall_contacts(CudaBackend*, const GpuHostView&) {
  no_cuda();
}
double cuda_max_overlap(CudaBackend*) {
  no_cuda();
}
double cuda_flex_max_overlap(CudaBackend*) {
  no_cuda();
}
double cuda_advance_max_overlap(CudaBackend*) {
  return 0.0;
}
double cuda_advance_max_relative_overlap(CudaBackend*) {
  return 0.0;
}
#endif

}  // namespace demfem::dem
