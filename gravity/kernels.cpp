#include "gravity/kernels.hpp"

#include <cmath>

// The kernels are compiled several times (function multi-versioning): the loader picks the widest
// instruction set the CPU has, so one portable binary still runs 8-wide AVX-512 on CPUs that have
// it. The choice is fixed per machine, hence so is the order of the SIMD reductions.
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && !defined(RUBBLE_GRAVITY_NO_CLONES)
#define RUBBLE_GRAVITY_CLONES __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#else
#define RUBBLE_GRAVITY_CLONES
#endif

namespace rubble::gravity::detail {

RUBBLE_GRAVITY_CLONES
void p2p(const double* sx, const double* sy, const double* sz, const double* sm, std::size_t n,
         double xi, double yi, double zi, double eps2, Accum& acc) {
  double ax = 0, ay = 0, az = 0, phi = 0;
#pragma omp simd reduction(+ : ax, ay, az, phi)
  for (std::size_t j = 0; j < n; ++j) {
    const double dx = xi - sx[j];
    const double dy = yi - sy[j];
    const double dz = zi - sz[j];
    const double r2 = dx * dx + dy * dy + dz * dz + eps2;
    // r2 == 0 only for the target itself (or an exactly coincident particle) without softening:
    // its contribution is defined as zero. Select before and after the division so that no lane
    // ever divides by zero and the branch becomes a blend.
    const bool valid = r2 > 0.0;
    const double inv = valid ? 1.0 / std::sqrt(valid ? r2 : 1.0) : 0.0;
    const double m_inv = sm[j] * inv;
    const double m_inv3 = m_inv * inv * inv;
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
void m2p_quadrupole(const double* cx, const double* cy, const double* cz, const double* cm,
                    const double* qxx, const double* qxy, const double* qxz, const double* qyy,
                    const double* qyz, const double* qzz, std::size_t n, double xi, double yi,
                    double zi, double eps2, Accum& acc) {
  double ax = 0, ay = 0, az = 0, phi = 0;
#pragma omp simd reduction(+ : ax, ay, az, phi)
  for (std::size_t j = 0; j < n; ++j) {
    const double rx = xi - cx[j];
    const double ry = yi - cy[j];
    const double rz = zi - cz[j];
    // Accepted cells are always well separated (distance > b_max / theta > 0): no guard needed.
    const double r2 = rx * rx + ry * ry + rz * rz + eps2;
    const double d1 = 1.0 / std::sqrt(r2);
    const double d2 = d1 * d1;
    const double d3 = d1 * d2;
    const double d5 = d3 * d2;
    const double d7 = d5 * d2;
    // M r and r.M.r with the symmetric second moment.
    const double mrx = qxx[j] * rx + qxy[j] * ry + qxz[j] * rz;
    const double mry = qxy[j] * rx + qyy[j] * ry + qyz[j] * rz;
    const double mrz = qxz[j] * rx + qyz[j] * ry + qzz[j] * rz;
    const double rmr = rx * mrx + ry * mry + rz * mrz;
    const double tr = qxx[j] + qyy[j] + qzz[j];
    // a/(-G) = (m D^3 - 3/2 D^5 trM + 15/2 D^7 rMr) r - 3 D^5 M r
    const double radial = cm[j] * d3 - 1.5 * d5 * tr + 7.5 * d7 * rmr;
    const double d5x3 = 3.0 * d5;
    ax += radial * rx - d5x3 * mrx;
    ay += radial * ry - d5x3 * mry;
    az += radial * rz - d5x3 * mrz;
    // phi/(-G) = m D + 3/2 D^5 rMr - 1/2 D^3 trM
    phi += cm[j] * d1 + 1.5 * d5 * rmr - 0.5 * d3 * tr;
  }
  acc.ax += ax;
  acc.ay += ay;
  acc.az += az;
  acc.phi += phi;
}

}  // namespace rubble::gravity::detail
