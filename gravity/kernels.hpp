#pragma once
// Interaction kernels shared by the direct sum and the tree (internal to rubble::gravity).
//
// Sources are given as structure-of-arrays so that the loop over sources vectorizes (one target
// per call, sources in SIMD lanes). The sums use `omp simd reduction`, so their order depends only
// on the SIMD width of the instruction set chosen at run time (same machine -> same bits), never
// on the number of threads.

#include <cstddef>

namespace rubble::gravity::detail {

/// Field accumulated at one target: acceleration without the factor -G, potential without -G.
struct Accum {
  double ax = 0, ay = 0, az = 0, phi = 0;
};

/// Particle-particle: adds sum_j m_j r_ij / (r_ij^2 + eps2)^{3/2} (r_ij = x_i - x_j) to (ax,ay,az)
/// and sum_j m_j / (r_ij^2 + eps2)^{1/2} to phi, over sources j in [0, n). A source with
/// r_ij^2 + eps2 == 0 (the target itself when eps2 == 0) contributes nothing. When eps2 > 0 the
/// target itself, if among the sources, contributes m_i / eps to phi (zero to a): the caller
/// removes it.
void p2p(const double* sx, const double* sy, const double* sz, const double* sm, std::size_t n, double xi, double yi,
         double zi, double eps2, Accum& acc);

/// p2p for the tree: each term may be smaller than p2p's by a relative 1.7e-8 at most (on AVX-512
/// CPUs 1/sqrt(r^2) takes one Newton step instead of two; elsewhere it is p2p). The tree's own
/// error is >= 1e-6 at any practical theta, so this changes no quoted tree error, and it saves
/// 3 of the 16 multiply/FMA instructions per 8 pairs that bound the kernel.
void p2p_approximate(const double* sx, const double* sy, const double* sz, const double* sm, std::size_t n, double xi,
                     double yi, double zi, double eps2, Accum& acc);

/// p2p for `targets` targets (xi[t], yi[t], zi[t]) over the same sources: acc[t] receives to the
/// bit what p2p(..., xi[t], yi[t], zi[t], eps2, acc[t]) adds. On AVX-512 CPUs the sources are read
/// once for every four targets, whose arithmetic interleaves (~1.15x the rate of one target a pass).
void p2p_targets(const double* sx, const double* sy, const double* sz, const double* sm, std::size_t n,
                 const double* xi, const double* yi, const double* zi, std::size_t targets, double eps2, Accum* acc);

/// p2p_approximate for several targets, as p2p_targets is p2p for several: the same bits as
/// p2p_approximate target by target.
void p2p_approximate_targets(const double* sx, const double* sy, const double* sz, const double* sm, std::size_t n,
                             const double* xi, const double* yi, const double* zi, std::size_t targets, double eps2,
                             Accum* acc);

/// Quadrupole cell-particle: adds the field of n cells, each with mass m, centre of mass c and
/// second moment M_ab = sum_k m_k (y_k - c)_a (y_k - c)_b (not trace-free, so that the softened
/// kernel 1/sqrt(r^2 + eps2) is expanded exactly to second order). With D = (r^2 + eps2)^{-1/2},
/// r = x - c (Taylor expansion of the potential about c; first-order term vanishes at the centre
/// of mass):
///   phi/(-G) = m D + (3/2) D^5 (r.M.r) - (1/2) D^3 tr M
///   a/G      = -m D^3 r + 3 D^5 (M r) + (3/2) D^5 tr M r - (15/2) D^7 (r.M.r) r
/// The accumulated values follow the sign convention of p2p (a/(-G), phi/(-G)). On AVX-512 CPUs D
/// comes from VRSQRT14PD and one Newton step, as in p2p_approximate (relative error < 5.6e-9, far
/// below the expansion's >= 1e-6 at any practical theta); elsewhere from sqrt and a division.
/// q points to 6 arrays: Mxx, Mxy, Mxz, Myy, Myz, Mzz, each of length n.
void m2p_quadrupole(const double* cx, const double* cy, const double* cz, const double* cm, const double* qxx,
                    const double* qxy, const double* qxz, const double* qyy, const double* qyz, const double* qzz,
                    std::size_t n, double xi, double yi, double zi, double eps2, Accum& acc);

/// p2p in single precision, for the tree's KernelPrecision::single: sources and target as floats
/// (the tree passes offsets from the group's centre in scaled units, so that neither the range nor
/// the cancellation of x_i - x_j costs digits), sums in float lanes restarted every 1 024 sources,
/// each block's lanes added to acc in double. Each term within a relative ~1e-6 of p2p's
/// (1/sqrt from VRSQRT14PS and one Newton step on AVX-512 CPUs). A source at r^2 + eps2 == 0
/// contributes nothing, as in p2p.
void p2p_single(const float* sx, const float* sy, const float* sz, const float* sm, std::size_t n, float xi, float yi,
                float zi, float eps2, Accum& acc);

/// m2p_quadrupole in single precision (see p2p_single): same formulas, float arrays.
void m2p_quadrupole_single(const float* cx, const float* cy, const float* cz, const float* cm, const float* qxx,
                           const float* qxy, const float* qxz, const float* qyy, const float* qyz, const float* qzz,
                           std::size_t n, float xi, float yi, float zi, float eps2, Accum& acc);

}  // namespace rubble::gravity::detail
