#pragma once
// The particle-particle interaction of the GPU kernels (direct_sum.cu, tree_walk.cu): one
// definition, so the direct sum and the tree's opened leaves compute the same terms.

namespace rubble::gravity::cuda::detail {

/// Adds the field of a source of mass sm at (sx, sy, sz) at the target (x, y, z), without the
/// factor -G: m r / (r^2 + eps2)^{3/2} to (ax, ay, az) and m / (r^2 + eps2)^{1/2} to phi,
/// r = target - source. r^2 + eps2 == 0 (the target itself, or a coincident particle, without
/// softening) contributes nothing, as in the CPU kernels; with softening the caller removes the
/// target's own m / eps from phi.
__device__ __forceinline__ void add_particle(double x, double y, double z, double sx, double sy, double sz, double sm,
                                             double eps2, double& ax, double& ay, double& az, double& phi) {
  const double dx = x - sx, dy = y - sy, dz = z - sz;
  const double r2 = dx * dx + dy * dy + dz * dz + eps2;
  const double inv = r2 > 0.0 ? rsqrt(r2) : 0.0;
  const double m_inv = sm * inv;
  const double m_inv3 = m_inv * inv * inv;
  ax += dx * m_inv3;
  ay += dy * m_inv3;
  az += dz * m_inv3;
  phi += m_inv;
}

}  // namespace rubble::gravity::cuda::detail
