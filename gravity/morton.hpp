#pragma once
// Morton (Z-order) keys of the Barnes-Hut tree, one definition for the host build (tree.cpp) and
// the GPU build (cuda/tree_build.cu): both must give every particle the same key for the two trees
// to be the same. C++17 and no std:: calls that device code lacks, so that nvcc compiles it too.

#include <cmath>
#include <cstdint>

#if defined(__CUDACC__)
#define RUBBLE_GRAVITY_HOST_DEVICE __host__ __device__
#else
#define RUBBLE_GRAVITY_HOST_DEVICE
#endif

namespace rubble::gravity::morton {

/// Bits per axis: 3 x 21 = 63-bit keys.
constexpr int kBitsPerAxis = 21;
/// Cells per axis of the key grid over the particles' bounding cube.
constexpr double kCells = static_cast<double>(1u << kBitsPerAxis);

/// Spreads the low 21 bits of v so that bit b moves to bit 3b (Morton interleaving by the usual
/// shift-and-mask sequence).
RUBBLE_GRAVITY_HOST_DEVICE inline std::uint64_t spread_bits(std::uint64_t v) {
  v &= 0x1fffffULL;
  v = (v | (v << 32)) & 0x1f00000000ffffULL;
  v = (v | (v << 16)) & 0x1f0000ff0000ffULL;
  v = (v | (v << 8)) & 0x100f00f00f00f00fULL;
  v = (v | (v << 4)) & 0x10c30c30c30c30c3ULL;
  v = (v | (v << 2)) & 0x1249249249249249ULL;
  return v;
}

/// The key of point p in the grid of kCells per axis from corner lo, scale = kCells / the cube's
/// side (0 when all points coincide). The x bit is the most significant of each octal digit.
RUBBLE_GRAVITY_HOST_DEVICE inline std::uint64_t key(const double p[3], const double lo[3], double scale) {
  std::uint64_t key = 0;
  for (int d = 0; d < 3; ++d) {
    const double q = floor((p[d] - lo[d]) * scale);
    const auto c = static_cast<std::uint64_t>(fmin(fmax(q, 0.0), kCells - 1.0));
    key |= spread_bits(c) << (2 - d);
  }
  return key;
}

}  // namespace rubble::gravity::morton
