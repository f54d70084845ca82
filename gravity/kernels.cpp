#include "gravity/kernels.hpp"

#include <algorithm>
#include <cmath>

#include "gravity/gravity.hpp"

// The kernels are compiled several times (function multi-versioning): the loader picks the widest
// instruction set the CPU has, so one portable binary still runs 8-wide AVX-512 on CPUs that have
// it. The choice is fixed per machine, hence so is the order of the SIMD reductions.
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && !defined(RUBBLE_GRAVITY_NO_CLONES)
#define RUBBLE_GRAVITY_HAS_CLONES 1
#define RUBBLE_GRAVITY_CLONES __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#else
#define RUBBLE_GRAVITY_CLONES
#endif

// On CPUs with AVX-512, p2p runs a hand-vectorized version instead (p2p_targets_avx512): 1/sqrt(r^2)
// by the 14-bit estimate VRSQRT14PD refined by two Newton steps (14 -> 28 -> 56 bits: within a few
// ulps of 1/std::sqrt, so the direct sum stays exact to ~1e-15), in place of a square root and a
// division, whose throughput bounded the kernel (Zen 4 at 2.6 GHz: 1.1e9 pairs per CPU second
// with them, 1.3e9 without). Its bound is then its 16 multiply/FMA instructions per 8 pairs; what
// kept it at ~58 % of that bound (Zen 5) was the masked loads of every block and the latency of
// one target's chain: full blocks load plainly (the last one masked), and several targets share
// one pass, their chains interleaved (79-81 % of the bound: bench/RESULTS.md). m2p_quadrupole
// (AVX-512, m2p_quadrupole_avx512) takes the same one-Newton-step 1/sqrt as p2p_approximate in
// place of its square root and division, and full blocks without masks: 10-14 % off the
// quadrupole tree rows (Zen 5; on Zen 4, with every block masked, the estimate had not paid).
// The choice is made once per process from the CPU, so results still depend only on the machine,
// never on the thread count.
#if defined(__GNUC__) && defined(__x86_64__) && !defined(RUBBLE_GRAVITY_NO_CLONES)
#define RUBBLE_GRAVITY_AVX512 1
#include <immintrin.h>
#endif

namespace rubble::gravity::detail {

/// Sources per float accumulation: p2p_single and m2p_quadrupole_single hand their kernels blocks
/// of kFloatBlock sources and add each block's lane sums in double, so that no float sum has more
/// than kFloatBlock / lanes terms and its rounding error stays ~1e-7 relative however long the
/// interaction list.
constexpr std::size_t kFloatBlock = 1024;

#ifdef RUBBLE_GRAVITY_AVX512
namespace {

bool cpu_has_avx512() {
  static const bool has = __builtin_cpu_supports("avx512f");
  return has;
}

/// 1/sqrt(x) for x > 0: VRSQRT14PD (relative error < 2^-14), then Newton steps
/// y <- y (3/2 - x/2 y^2), each squaring the relative error and leaving y below 1/sqrt(x):
/// -(3/2)(2^-14)^2 = -5.6e-9 after one step, ~1e-16 (a few ulps) after two.
template <int kNewtonSteps>
__attribute__((target("avx512f"))) inline __m512d rsqrt_newton(__m512d x) {
  const __m512d half_x = _mm512_mul_pd(_mm512_set1_pd(0.5), x);
  const __m512d three_halves = _mm512_set1_pd(1.5);
  // The maskz form: GCC 12's plain _mm512_rsqrt14_pd trips -Wuninitialized (_mm512_undefined_pd).
  __m512d y = _mm512_maskz_rsqrt14_pd(static_cast<__mmask8>(0xff), x);
  for (int k = 0; k < kNewtonSteps; ++k)
    y = _mm512_mul_pd(y, _mm512_fnmadd_pd(half_x, _mm512_mul_pd(y, y), three_halves));
  return y;
}

/// Sum of the 8 lanes in a fixed order (pairs, then pairs of pairs). Through memory: GCC 12's
/// _mm512_reduce_add_pd trips -Wuninitialized; this runs once per target, not per source.
__attribute__((target("avx512f"))) inline double lane_sum(__m512d v) {
  alignas(64) double t[8];
  _mm512_store_pd(t, v);
  return ((t[0] + t[1]) + (t[2] + t[3])) + ((t[4] + t[5]) + (t[6] + t[7]));
}

/// 1/sqrt(x) for x > 0 in single precision: VRSQRT14PS (relative error < 2^-14) and one Newton
/// step (error ~(3/2) 2^-28 = 5.6e-9, below float's own rounding of 6e-8).
__attribute__((target("avx512f"))) inline __m512 rsqrt_newton_single(__m512 x) {
  const __m512 half_x = _mm512_mul_ps(_mm512_set1_ps(0.5F), x);
  const __m512 y = _mm512_maskz_rsqrt14_ps(static_cast<__mmask16>(0xffff), x);
  return _mm512_mul_ps(y, _mm512_fnmadd_ps(half_x, _mm512_mul_ps(y, y), _mm512_set1_ps(1.5F)));
}

/// Sum of the 16 float lanes of v in double: widened, lane k added to lane k + 8, then lane_sum.
__attribute__((target("avx512f"))) inline double lane_sum_single(__m512 v) {
  // The maskz forms: GCC 12's plain cast/extract/convert intrinsics trip -Wmaybe-uninitialized.
  const __m512d bits = _mm512_castps_pd(v);
  const __m256 low = _mm256_castpd_ps(_mm512_maskz_extractf64x4_pd(static_cast<__mmask8>(0xf), bits, 0));
  const __m256 high = _mm256_castpd_ps(_mm512_maskz_extractf64x4_pd(static_cast<__mmask8>(0xf), bits, 1));
  const __m512d sum = _mm512_add_pd(_mm512_maskz_cvtps_pd(static_cast<__mmask8>(0xff), low),
                                    _mm512_maskz_cvtps_pd(static_cast<__mmask8>(0xff), high));
  return lane_sum(sum);
}

/// The AVX-512 operations of the particle and quadrupole kernels in each precision (8 double or 16
/// float lanes), so that one block function of each kernel serves both.
template <typename Real>
struct Avx512;

template <>
struct Avx512<double> {
  using Vector = __m512d;
  using Mask = __mmask8;
  static constexpr std::size_t width = 8;
  static constexpr Mask all = 0xff;
  __attribute__((target("avx512f"), always_inline)) static Vector set1(double v) { return _mm512_set1_pd(v); }
  __attribute__((target("avx512f"), always_inline)) static Vector add(Vector a, Vector b) {
    return _mm512_add_pd(a, b);
  }
  __attribute__((target("avx512f"), always_inline)) static Vector sub(Vector a, Vector b) {
    return _mm512_sub_pd(a, b);
  }
  __attribute__((target("avx512f"), always_inline)) static Vector mul(Vector a, Vector b) {
    return _mm512_mul_pd(a, b);
  }
  /// a b + c, -(a b) + c and a b - c, each rounded once.
  __attribute__((target("avx512f"), always_inline)) static Vector fmadd(Vector a, Vector b, Vector c) {
    return _mm512_fmadd_pd(a, b, c);
  }
  __attribute__((target("avx512f"), always_inline)) static Vector fnmadd(Vector a, Vector b, Vector c) {
    return _mm512_fnmadd_pd(a, b, c);
  }
  __attribute__((target("avx512f"), always_inline)) static Vector fmsub(Vector a, Vector b, Vector c) {
    return _mm512_fmsub_pd(a, b, c);
  }
  /// b's lanes where `mask` is set, a's elsewhere.
  __attribute__((target("avx512f"), always_inline)) static Vector blend(Vector a, Mask mask, Vector b) {
    return _mm512_mask_mov_pd(a, mask, b);
  }
  /// 1/sqrt(x): VRSQRT14 and kNewtonSteps Newton steps.
  template <int kNewtonSteps>
  __attribute__((target("avx512f"), always_inline)) static Vector rsqrt(Vector x) {
    return rsqrt_newton<kNewtonSteps>(x);
  }
  /// The lanes where v > 0 (of the `live` ones unless kFull).
  template <bool kFull>
  __attribute__((target("avx512f"), always_inline)) static Mask positive(Vector v, Mask live) {
    if constexpr (kFull) return _mm512_cmp_pd_mask(v, _mm512_setzero_pd(), _CMP_GT_OQ);
    return _mm512_mask_cmp_pd_mask(live, v, _mm512_setzero_pd(), _CMP_GT_OQ);
  }
  /// v's lanes where `mask` is set, 0 elsewhere.
  __attribute__((target("avx512f"), always_inline)) static Vector zero_unless(Mask mask, Vector v) {
    return _mm512_maskz_mov_pd(mask, v);
  }
  /// `width` values from p (kFull), or its `live` lanes and zeros.
  template <bool kFull>
  __attribute__((target("avx512f"), always_inline)) static Vector load(const double* p, Mask live) {
    if constexpr (kFull) return _mm512_loadu_pd(p);
    return _mm512_maskz_loadu_pd(live, p);
  }
  /// The first `count` (< width) lanes.
  static Mask tail(std::size_t count) { return static_cast<Mask>((1u << count) - 1u); }
  __attribute__((target("avx512f"), always_inline)) static double sum(Vector v) { return lane_sum(v); }
};

template <>
struct Avx512<float> {
  using Vector = __m512;
  using Mask = __mmask16;
  static constexpr std::size_t width = 16;
  static constexpr Mask all = 0xffff;
  __attribute__((target("avx512f"), always_inline)) static Vector set1(float v) { return _mm512_set1_ps(v); }
  __attribute__((target("avx512f"), always_inline)) static Vector add(Vector a, Vector b) {
    return _mm512_add_ps(a, b);
  }
  __attribute__((target("avx512f"), always_inline)) static Vector sub(Vector a, Vector b) {
    return _mm512_sub_ps(a, b);
  }
  __attribute__((target("avx512f"), always_inline)) static Vector mul(Vector a, Vector b) {
    return _mm512_mul_ps(a, b);
  }
  __attribute__((target("avx512f"), always_inline)) static Vector fmadd(Vector a, Vector b, Vector c) {
    return _mm512_fmadd_ps(a, b, c);
  }
  __attribute__((target("avx512f"), always_inline)) static Vector fnmadd(Vector a, Vector b, Vector c) {
    return _mm512_fnmadd_ps(a, b, c);
  }
  __attribute__((target("avx512f"), always_inline)) static Vector fmsub(Vector a, Vector b, Vector c) {
    return _mm512_fmsub_ps(a, b, c);
  }
  __attribute__((target("avx512f"), always_inline)) static Vector blend(Vector a, Mask mask, Vector b) {
    return _mm512_mask_mov_ps(a, mask, b);
  }
  template <int kNewtonSteps>
  __attribute__((target("avx512f"), always_inline)) static Vector rsqrt(Vector x) {
    static_assert(kNewtonSteps == 1, "float's 1/sqrt takes one Newton step (float's own precision)");
    return rsqrt_newton_single(x);
  }
  template <bool kFull>
  __attribute__((target("avx512f"), always_inline)) static Mask positive(Vector v, Mask live) {
    if constexpr (kFull) return _mm512_cmp_ps_mask(v, _mm512_setzero_ps(), _CMP_GT_OQ);
    return _mm512_mask_cmp_ps_mask(live, v, _mm512_setzero_ps(), _CMP_GT_OQ);
  }
  __attribute__((target("avx512f"), always_inline)) static Vector zero_unless(Mask mask, Vector v) {
    return _mm512_maskz_mov_ps(mask, v);
  }
  template <bool kFull>
  __attribute__((target("avx512f"), always_inline)) static Vector load(const float* p, Mask live) {
    if constexpr (kFull) return _mm512_loadu_ps(p);
    return _mm512_maskz_loadu_ps(live, p);
  }
  static Mask tail(std::size_t count) { return static_cast<Mask>((1u << count) - 1u); }
  __attribute__((target("avx512f"), always_inline)) static double sum(Vector v) { return lane_sum_single(v); }
};

/// Targets p2p_targets_avx512 takes per pass over the sources: four targets' broadcast
/// coordinates and accumulators (28 registers) still fit AVX-512's 32, and each block of sources
/// is loaded once for the four; with more the accumulators spill.
constexpr int kTargetsPerPass = 4;

/// kTargets targets' broadcast coordinates and their running lane sums (a/(-G), phi/(-G)).
template <typename Real, int kTargets>
struct P2PLanes {
  using Vector = typename Avx512<Real>::Vector;
  Vector x[kTargets], y[kTargets], z[kTargets];
  Vector ax[kTargets], ay[kTargets], az[kTargets], phi[kTargets];
};

/// One block of sources (8 doubles or 16 floats) against every target of `lanes`. kFull: the
/// whole block is there, so plain loads and no lane masks (the masked form in every block cost
/// ~20 % of the kernel's time); else the `live` lanes, absent ones loaded as mass 0 at the origin.
/// Every target's lanes see the same operations in the same order as with one target per pass,
/// so each target's sums are the same to the bit however the targets are grouped.
template <typename Real, int kNewtonSteps, int kTargets, bool kFull>
__attribute__((target("avx512f"), always_inline)) inline void p2p_block_avx512(const Real* sx, const Real* sy,
                                                                               const Real* sz, const Real* sm,
                                                                               typename Avx512<Real>::Mask live,
                                                                               typename Avx512<Real>::Vector eps2,
                                                                               P2PLanes<Real, kTargets>& lanes) {
  using S = Avx512<Real>;
  using V = typename S::Vector;
  const V x = S::template load<kFull>(sx, live), y = S::template load<kFull>(sy, live),
          z = S::template load<kFull>(sz, live), m = S::template load<kFull>(sm, live);
  // Staged by target (all differences, then all square roots, then all sums): the four chains
  // interleave and the core overlaps their latencies.
  V dx[kTargets], dy[kTargets], dz[kTargets], r2[kTargets], inv[kTargets];
  typename S::Mask valid[kTargets];
  for (int t = 0; t < kTargets; ++t) {
    dx[t] = S::sub(lanes.x[t], x);
    dy[t] = S::sub(lanes.y[t], y);
    dz[t] = S::sub(lanes.z[t], z);
    r2[t] = S::fmadd(dz[t], dz[t], S::fmadd(dy[t], dy[t], S::fmadd(dx[t], dx[t], eps2)));
    // r2 == 0 (the target itself without softening) contributes nothing, like the scalar kernel:
    // its 1/sqrt is inf, the Newton steps make it NaN, and the mask makes it 0.
    valid[t] = S::template positive<kFull>(r2[t], live);
  }
  for (int t = 0; t < kTargets; ++t) inv[t] = S::zero_unless(valid[t], S::template rsqrt<kNewtonSteps>(r2[t]));
  for (int t = 0; t < kTargets; ++t) {
    const V m_inv = S::mul(m, inv[t]);
    const V m_inv3 = S::mul(m_inv, S::mul(inv[t], inv[t]));
    lanes.ax[t] = S::fmadd(dx[t], m_inv3, lanes.ax[t]);
    lanes.ay[t] = S::fmadd(dy[t], m_inv3, lanes.ay[t]);
    lanes.az[t] = S::fmadd(dz[t], m_inv3, lanes.az[t]);
    lanes.phi[t] = S::add(lanes.phi[t], m_inv);
  }
}

/// p2p for kTargets targets in one pass over n sources: full blocks, then the rest; each target's
/// lane sums added to its acc in double.
template <typename Real, int kNewtonSteps, int kTargets>
__attribute__((target("avx512f"))) void p2p_targets_avx512(const Real* sx, const Real* sy, const Real* sz,
                                                           const Real* sm, std::size_t n, const Real* xi,
                                                           const Real* yi, const Real* zi, Real eps2, Accum* acc) {
  using S = Avx512<Real>;
  const typename S::Vector veps2 = S::set1(eps2), zero = S::set1(Real(0));
  P2PLanes<Real, kTargets> lanes;
  for (int t = 0; t < kTargets; ++t) {
    lanes.x[t] = S::set1(xi[t]), lanes.y[t] = S::set1(yi[t]), lanes.z[t] = S::set1(zi[t]);
    lanes.ax[t] = zero, lanes.ay[t] = zero, lanes.az[t] = zero, lanes.phi[t] = zero;
  }
  std::size_t j = 0;
  for (; j + S::width <= n; j += S::width) {
    p2p_block_avx512<Real, kNewtonSteps, kTargets, true>(sx + j, sy + j, sz + j, sm + j, S::all, veps2, lanes);
  }
  if (j < n) {
    p2p_block_avx512<Real, kNewtonSteps, kTargets, false>(sx + j, sy + j, sz + j, sm + j, S::tail(n - j), veps2, lanes);
  }
  for (int t = 0; t < kTargets; ++t) {
    acc[t].ax += S::sum(lanes.ax[t]);
    acc[t].ay += S::sum(lanes.ay[t]);
    acc[t].az += S::sum(lanes.az[t]);
    acc[t].phi += S::sum(lanes.phi[t]);
  }
}

/// Any number of targets: kTargetsPerPass at a time, the rest one by one.
template <typename Real, int kNewtonSteps>
void p2p_many_avx512(const Real* sx, const Real* sy, const Real* sz, const Real* sm, std::size_t n, const Real* xi,
                     const Real* yi, const Real* zi, std::size_t targets, Real eps2, Accum* acc) {
  std::size_t t = 0;
  for (; t + kTargetsPerPass <= targets; t += kTargetsPerPass) {
    p2p_targets_avx512<Real, kNewtonSteps, kTargetsPerPass>(sx, sy, sz, sm, n, xi + t, yi + t, zi + t, eps2, acc + t);
  }
  for (; t < targets; ++t) {
    p2p_targets_avx512<Real, kNewtonSteps, 1>(sx, sy, sz, sm, n, xi + t, yi + t, zi + t, eps2, acc + t);
  }
}

/// The quadrupole kernel's arrays (cells' centres, masses, second moments).
template <typename Real>
struct QuadrupoleSources {
  const Real *cx, *cy, *cz, *cm, *qxx, *qxy, *qxz, *qyy, *qyz, *qzz;
};

/// The quadrupole kernel's target and softening (broadcast) and running lane sums (a/(-G), phi/(-G)).
template <typename Real>
struct QuadrupoleLanes {
  typename Avx512<Real>::Vector x, y, z, eps2, ax, ay, az, phi;
};

/// One block of cells from `j` (kFull: all `width` there; else the `live` lanes, absent ones loaded
/// as mass and moments 0 with r2 = 1 for the 1/sqrt). Formulas in kernels.hpp; 1/sqrt(r^2 + eps2)
/// from VRSQRT14 and one Newton step, as in p2p_approximate (in double a relative error < 5.6e-9,
/// against the expansion's own >= 1e-6 at any practical theta), in place of a square root and a
/// division.
template <typename Real, bool kFull>
__attribute__((target("avx512f"), always_inline)) inline void m2p_quadrupole_block_avx512(
    const QuadrupoleSources<Real>& c, std::size_t j, typename Avx512<Real>::Mask live, QuadrupoleLanes<Real>& l) {
  using S = Avx512<Real>;
  using V = typename S::Vector;
  const V one = S::set1(Real(1)), c15 = S::set1(Real(1.5)), c75 = S::set1(Real(7.5)), c3 = S::set1(Real(3)),
          c05 = S::set1(Real(0.5));
  const V rx = S::sub(l.x, S::template load<kFull>(c.cx + j, live));
  const V ry = S::sub(l.y, S::template load<kFull>(c.cy + j, live));
  const V rz = S::sub(l.z, S::template load<kFull>(c.cz + j, live));
  const V m = S::template load<kFull>(c.cm + j, live);
  const V mxx = S::template load<kFull>(c.qxx + j, live), mxy = S::template load<kFull>(c.qxy + j, live),
          mxz = S::template load<kFull>(c.qxz + j, live), myy = S::template load<kFull>(c.qyy + j, live),
          myz = S::template load<kFull>(c.qyz + j, live), mzz = S::template load<kFull>(c.qzz + j, live);
  V r2 = S::fmadd(rz, rz, S::fmadd(ry, ry, S::fmadd(rx, rx, l.eps2)));
  if constexpr (!kFull) r2 = S::blend(one, live, r2);
  const V d1 = S::template rsqrt<1>(r2);
  const V d2 = S::mul(d1, d1);
  const V d3 = S::mul(d1, d2);
  const V d5 = S::mul(d3, d2);
  const V d7 = S::mul(d5, d2);
  const V mrx = S::fmadd(mxz, rz, S::fmadd(mxy, ry, S::mul(mxx, rx)));
  const V mry = S::fmadd(myz, rz, S::fmadd(myy, ry, S::mul(mxy, rx)));
  const V mrz = S::fmadd(mzz, rz, S::fmadd(myz, ry, S::mul(mxz, rx)));
  const V rmr = S::fmadd(rz, mrz, S::fmadd(ry, mry, S::mul(rx, mrx)));
  const V tr = S::add(S::add(mxx, myy), mzz);
  // radial = m D^3 - 3/2 D^5 trM + 15/2 D^7 rMr
  const V radial = S::fmadd(S::mul(c75, d7), rmr, S::fnmadd(S::mul(c15, d5), tr, S::mul(m, d3)));
  const V d5x3 = S::mul(c3, d5);
  l.ax = S::add(l.ax, S::fmsub(radial, rx, S::mul(d5x3, mrx)));
  l.ay = S::add(l.ay, S::fmsub(radial, ry, S::mul(d5x3, mry)));
  l.az = S::add(l.az, S::fmsub(radial, rz, S::mul(d5x3, mrz)));
  // phi = m D + 3/2 D^5 rMr - 1/2 D^3 trM
  l.phi = S::add(l.phi, S::fnmadd(S::mul(c05, d3), tr, S::fmadd(S::mul(c15, d5), rmr, S::mul(m, d1))));
}

/// The quadrupole kernel over n cells: full blocks, then the rest; the lanes' sums added to acc
/// in double.
template <typename Real>
__attribute__((target("avx512f"))) void m2p_quadrupole_avx512(const QuadrupoleSources<Real>& c, std::size_t n, Real xi,
                                                              Real yi, Real zi, Real eps2, Accum& acc) {
  using S = Avx512<Real>;
  const typename S::Vector zero = S::set1(Real(0));
  QuadrupoleLanes<Real> l{S::set1(xi), S::set1(yi), S::set1(zi), S::set1(eps2), zero, zero, zero, zero};
  std::size_t j = 0;
  for (; j + S::width <= n; j += S::width) m2p_quadrupole_block_avx512<Real, true>(c, j, S::all, l);
  if (j < n) m2p_quadrupole_block_avx512<Real, false>(c, j, S::tail(n - j), l);
  acc.ax += S::sum(l.ax);
  acc.ay += S::sum(l.ay);
  acc.az += S::sum(l.az);
  acc.phi += S::sum(l.phi);
}

}  // namespace
#endif

namespace {

/// The portable particle kernel's loop, in double or float. Always inlined into the
/// instruction-set clones below, so that each clone compiles it for its own vector width.
template <typename Real>
__attribute__((always_inline)) inline void p2p_loop(const Real* sx, const Real* sy, const Real* sz, const Real* sm,
                                                    std::size_t n, Real xi, Real yi, Real zi, Real eps2, Accum& acc) {
  Real ax = 0, ay = 0, az = 0, phi = 0;
#pragma omp simd reduction(+ : ax, ay, az, phi)
  for (std::size_t j = 0; j < n; ++j) {
    const Real dx = xi - sx[j];
    const Real dy = yi - sy[j];
    const Real dz = zi - sz[j];
    const Real r2 = dx * dx + dy * dy + dz * dz + eps2;
    // r2 == 0 only for the target itself (or an exactly coincident particle) without softening:
    // its contribution is defined as zero. Select before and after the division so that no lane
    // ever divides by zero and the branch becomes a blend.
    const bool valid = r2 > Real(0);
    const Real inv = valid ? Real(1) / std::sqrt(valid ? r2 : Real(1)) : Real(0);
    const Real m_inv = sm[j] * inv;
    const Real m_inv3 = m_inv * inv * inv;
    ax += dx * m_inv3;
    ay += dy * m_inv3;
    az += dz * m_inv3;
    phi += m_inv;
  }
  acc.ax += ax;
  acc.ay += ay;
  acc.az += az;
  acc.phi += phi;
}

RUBBLE_GRAVITY_CLONES
void p2p_portable(const double* sx, const double* sy, const double* sz, const double* sm, std::size_t n, double xi,
                  double yi, double zi, double eps2, Accum& acc) {
  p2p_loop(sx, sy, sz, sm, n, xi, yi, zi, eps2, acc);
}

RUBBLE_GRAVITY_CLONES
void p2p_single_portable(const float* sx, const float* sy, const float* sz, const float* sm, std::size_t n, float xi,
                         float yi, float zi, float eps2, Accum& acc) {
  p2p_loop(sx, sy, sz, sm, n, xi, yi, zi, eps2, acc);
}

/// The quadrupole kernel's loop (formulas in kernels.hpp), in double or float; inlined like
/// p2p_loop.
template <typename Real>
__attribute__((always_inline)) inline void m2p_quadrupole_loop(const Real* cx, const Real* cy, const Real* cz,
                                                               const Real* cm, const Real* qxx, const Real* qxy,
                                                               const Real* qxz, const Real* qyy, const Real* qyz,
                                                               const Real* qzz, std::size_t n, Real xi, Real yi,
                                                               Real zi, Real eps2, Accum& acc) {
  Real ax = 0, ay = 0, az = 0, phi = 0;
#pragma omp simd reduction(+ : ax, ay, az, phi)
  for (std::size_t j = 0; j < n; ++j) {
    const Real rx = xi - cx[j];
    const Real ry = yi - cy[j];
    const Real rz = zi - cz[j];
    // Accepted cells are always well separated (distance > b_max / theta > 0): no guard needed.
    const Real r2 = rx * rx + ry * ry + rz * rz + eps2;
    const Real d1 = Real(1) / std::sqrt(r2);
    const Real d2 = d1 * d1;
    const Real d3 = d1 * d2;
    const Real d5 = d3 * d2;
    const Real d7 = d5 * d2;
    // M r and r.M.r with the symmetric second moment.
    const Real mrx = qxx[j] * rx + qxy[j] * ry + qxz[j] * rz;
    const Real mry = qxy[j] * rx + qyy[j] * ry + qyz[j] * rz;
    const Real mrz = qxz[j] * rx + qyz[j] * ry + qzz[j] * rz;
    const Real rmr = rx * mrx + ry * mry + rz * mrz;
    const Real tr = qxx[j] + qyy[j] + qzz[j];
    // a/(-G) = (m D^3 - 3/2 D^5 trM + 15/2 D^7 rMr) r - 3 D^5 M r
    const Real radial = cm[j] * d3 - Real(1.5) * d5 * tr + Real(7.5) * d7 * rmr;
    const Real d5x3 = Real(3) * d5;
    ax += radial * rx - d5x3 * mrx;
    ay += radial * ry - d5x3 * mry;
    az += radial * rz - d5x3 * mrz;
    // phi/(-G) = m D + 3/2 D^5 rMr - 1/2 D^3 trM
    phi += cm[j] * d1 + Real(1.5) * d5 * rmr - Real(0.5) * d3 * tr;
  }
  acc.ax += ax;
  acc.ay += ay;
  acc.az += az;
  acc.phi += phi;
}

RUBBLE_GRAVITY_CLONES
void m2p_quadrupole_portable(const double* cx, const double* cy, const double* cz, const double* cm, const double* qxx,
                             const double* qxy, const double* qxz, const double* qyy, const double* qyz,
                             const double* qzz, std::size_t n, double xi, double yi, double zi, double eps2,
                             Accum& acc) {
  m2p_quadrupole_loop(cx, cy, cz, cm, qxx, qxy, qxz, qyy, qyz, qzz, n, xi, yi, zi, eps2, acc);
}

RUBBLE_GRAVITY_CLONES
void m2p_quadrupole_single_portable(const float* cx, const float* cy, const float* cz, const float* cm,
                                    const float* qxx, const float* qxy, const float* qxz, const float* qyy,
                                    const float* qyz, const float* qzz, std::size_t n, float xi, float yi, float zi,
                                    float eps2, Accum& acc) {
  m2p_quadrupole_loop(cx, cy, cz, cm, qxx, qxy, qxz, qyy, qyz, qzz, n, xi, yi, zi, eps2, acc);
}

}  // namespace

void p2p(const double* sx, const double* sy, const double* sz, const double* sm, std::size_t n, double xi, double yi,
         double zi, double eps2, Accum& acc) {
#ifdef RUBBLE_GRAVITY_AVX512
  if (cpu_has_avx512()) return p2p_targets_avx512<double, 2, 1>(sx, sy, sz, sm, n, &xi, &yi, &zi, eps2, &acc);
#endif
  p2p_portable(sx, sy, sz, sm, n, xi, yi, zi, eps2, acc);
}

void p2p_approximate(const double* sx, const double* sy, const double* sz, const double* sm, std::size_t n, double xi,
                     double yi, double zi, double eps2, Accum& acc) {
#ifdef RUBBLE_GRAVITY_AVX512
  if (cpu_has_avx512()) return p2p_targets_avx512<double, 1, 1>(sx, sy, sz, sm, n, &xi, &yi, &zi, eps2, &acc);
#endif
  p2p_portable(sx, sy, sz, sm, n, xi, yi, zi, eps2, acc);
}

void p2p_targets(const double* sx, const double* sy, const double* sz, const double* sm, std::size_t n,
                 const double* xi, const double* yi, const double* zi, std::size_t targets, double eps2, Accum* acc) {
#ifdef RUBBLE_GRAVITY_AVX512
  if (cpu_has_avx512()) return p2p_many_avx512<double, 2>(sx, sy, sz, sm, n, xi, yi, zi, targets, eps2, acc);
#endif
  for (std::size_t t = 0; t < targets; ++t) p2p_portable(sx, sy, sz, sm, n, xi[t], yi[t], zi[t], eps2, acc[t]);
}

void p2p_approximate_targets(const double* sx, const double* sy, const double* sz, const double* sm, std::size_t n,
                             const double* xi, const double* yi, const double* zi, std::size_t targets, double eps2,
                             Accum* acc) {
#ifdef RUBBLE_GRAVITY_AVX512
  if (cpu_has_avx512()) return p2p_many_avx512<double, 1>(sx, sy, sz, sm, n, xi, yi, zi, targets, eps2, acc);
#endif
  for (std::size_t t = 0; t < targets; ++t) p2p_portable(sx, sy, sz, sm, n, xi[t], yi[t], zi[t], eps2, acc[t]);
}

void m2p_quadrupole(const double* cx, const double* cy, const double* cz, const double* cm, const double* qxx,
                    const double* qxy, const double* qxz, const double* qyy, const double* qyz, const double* qzz,
                    std::size_t n, double xi, double yi, double zi, double eps2, Accum& acc) {
#ifdef RUBBLE_GRAVITY_AVX512
  if (cpu_has_avx512())
    return m2p_quadrupole_avx512<double>({cx, cy, cz, cm, qxx, qxy, qxz, qyy, qyz, qzz}, n, xi, yi, zi, eps2, acc);
#endif
  m2p_quadrupole_portable(cx, cy, cz, cm, qxx, qxy, qxz, qyy, qyz, qzz, n, xi, yi, zi, eps2, acc);
}

// The float kernels run kFloatBlock sources at a time; each block's sums go into acc in double.

void p2p_single(const float* sx, const float* sy, const float* sz, const float* sm, std::size_t n, float xi, float yi,
                float zi, float eps2, Accum& acc) {
  // One target a pass: four, as in double, measured no faster in float (16 lanes).
  for (std::size_t b = 0; b < n; b += kFloatBlock) {
    const std::size_t count = std::min(kFloatBlock, n - b);
#ifdef RUBBLE_GRAVITY_AVX512
    if (cpu_has_avx512()) {
      p2p_targets_avx512<float, 1, 1>(sx + b, sy + b, sz + b, sm + b, count, &xi, &yi, &zi, eps2, &acc);
      continue;
    }
#endif
    p2p_single_portable(sx + b, sy + b, sz + b, sm + b, count, xi, yi, zi, eps2, acc);
  }
}

void m2p_quadrupole_single(const float* cx, const float* cy, const float* cz, const float* cm, const float* qxx,
                           const float* qxy, const float* qxz, const float* qyy, const float* qyz, const float* qzz,
                           std::size_t n, float xi, float yi, float zi, float eps2, Accum& acc) {
  for (std::size_t b = 0; b < n; b += kFloatBlock) {
    const std::size_t count = std::min(kFloatBlock, n - b);
#ifdef RUBBLE_GRAVITY_AVX512
    if (cpu_has_avx512()) {
      m2p_quadrupole_avx512<float>(
          {cx + b, cy + b, cz + b, cm + b, qxx + b, qxy + b, qxz + b, qyy + b, qyz + b, qzz + b}, count, xi, yi, zi,
          eps2, acc);
      continue;
    }
#endif
    m2p_quadrupole_single_portable(cx + b, cy + b, cz + b, cm + b, qxx + b, qxy + b, qxz + b, qyy + b, qyz + b, qzz + b,
                                   count, xi, yi, zi, eps2, acc);
  }
}

}  // namespace rubble::gravity::detail

namespace rubble::gravity {

std::string kernel_instruction_set() {
  // The dispatch's own tests: detail::cpu_has_avx512() for the hand-vectorized kernels, GCC's
  // target_clones resolver (the ISA levels) for the others. Without the clones (clang, or
  // RUBBLE_GRAVITY_NO_CLONES) the other kernels are the baseline build whatever the CPU.
#if defined(RUBBLE_GRAVITY_AVX512)
  const bool avx512 = detail::cpu_has_avx512();
#else
  const bool avx512 = false;
#endif
#if defined(RUBBLE_GRAVITY_HAS_CLONES)
  if (!avx512) return __builtin_cpu_supports("x86-64-v3") ? "x86-64-v3" : "baseline";
  return __builtin_cpu_supports("x86-64-v4") ? "avx512" : "avx512 (other kernels x86-64-v3)";
#else
  return avx512 ? "avx512 (other kernels baseline)" : "baseline";
#endif
}

}  // namespace rubble::gravity
