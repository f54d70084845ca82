// CUDA backend: exact direct sum, one thread per target, sources staged through shared memory in
// tiles (the classic all-pairs scheme, e.g. Nyland, Harris & Prins, GPU Gems 3 ch. 31). Each
// target sums its sources in index order, so results do not depend on the launch configuration.

#include <cuda_runtime.h>

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "gravity/cuda/direct_sum.cuh"
#include "gravity/cuda/interactions.cuh"

namespace rubble::gravity::cuda::detail {
namespace {

constexpr int kBlock = 128;

/// One source: position and mass (our own type: CUDA 13 deprecates Source).
struct alignas(32) Source {
  double x, y, z, w;
};

__global__ void direct_kernel(const Source* __restrict__ src, int n, double eps2, double G, double* __restrict__ acc,
                              double* __restrict__ pot) {
  __shared__ Source tile[kBlock];
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  const Source me = i < n ? src[i] : Source{0, 0, 0, 0};
  double ax = 0, ay = 0, az = 0, phi = 0;
  for (int base = 0; base < n; base += kBlock) {
    const int j = base + threadIdx.x;
    tile[threadIdx.x] = j < n ? src[j] : Source{0, 0, 0, 0};  // w = mass 0: no effect
    __syncthreads();
    const int count = min(kBlock, n - base);
    for (int k = 0; k < count; ++k) {
      const Source s = tile[k];
      add_particle(me.x, me.y, me.z, s.x, s.y, s.z, s.w, eps2, ax, ay, az, phi);  // self term removed below
    }
    __syncthreads();
  }
  if (i < n) {
    if (eps2 > 0.0) phi -= me.w * rsqrt(eps2);
    acc[3 * i] = -G * ax;
    acc[3 * i + 1] = -G * ay;
    acc[3 * i + 2] = -G * az;
    if (pot) pot[i] = -G * phi;
  }
}

void check(cudaError_t e, const char* what) {
  if (e != cudaSuccess) throw std::runtime_error(std::string("CUDA backend: ") + what + ": " + cudaGetErrorString(e));
}

/// Device memory released on scope exit.
template <class T>
struct DeviceBuffer {
  T* ptr = nullptr;
  explicit DeviceBuffer(std::size_t n) {
    if (n > 0) check(cudaMalloc(&ptr, n * sizeof(T)), "cudaMalloc");
  }
  ~DeviceBuffer() {
    if (ptr) cudaFree(ptr);
  }
  DeviceBuffer(const DeviceBuffer&) = delete;
  DeviceBuffer& operator=(const DeviceBuffer&) = delete;
};

}  // namespace

int device_count(std::string* reason) {
  int count = 0;
  const cudaError_t e = cudaGetDeviceCount(&count);
  if (e != cudaSuccess) {
    cudaGetLastError();  // clear the "no device / no driver" error
    if (reason) *reason = std::string("no usable CUDA device: ") + cudaGetErrorString(e);
    return 0;
  }
  if (count == 0 && reason) *reason = "no CUDA device found";
  return count;
}

void direct_sum(const double* pos, const double* mass, std::size_t n, double eps2, double G, double* acc, double* pot) {
  if (n == 0) return;
  if (n > static_cast<std::size_t>(INT32_MAX / 3)) throw std::runtime_error("CUDA backend: N too large");
  std::vector<Source> host(n);
  for (std::size_t i = 0; i < n; ++i) host[i] = Source{pos[3 * i], pos[3 * i + 1], pos[3 * i + 2], mass[i]};
  DeviceBuffer<Source> src(n);
  DeviceBuffer<double> dacc(3 * n), dpot(pot ? n : 0);
  check(cudaMemcpy(src.ptr, host.data(), n * sizeof(Source), cudaMemcpyHostToDevice), "copy in");
  const int blocks = static_cast<int>((n + kBlock - 1) / kBlock);
  direct_kernel<<<blocks, kBlock>>>(src.ptr, static_cast<int>(n), eps2, G, dacc.ptr, dpot.ptr);
  check(cudaGetLastError(), "kernel launch");
  check(cudaMemcpy(acc, dacc.ptr, 3 * n * sizeof(double), cudaMemcpyDeviceToHost), "copy out");
  if (pot) check(cudaMemcpy(pot, dpot.ptr, n * sizeof(double), cudaMemcpyDeviceToHost), "copy out");
}

}  // namespace rubble::gravity::cuda::detail
