// Tests of the interaction kernels (gravity/kernels.cpp) on their own: the several-target particle
// kernels against the one-target ones, to the bit; the quadrupole kernel against its formulas.

#include "gravity/kernels.hpp"

#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "gravity/gravity.hpp"

namespace g = rubble::gravity;

namespace {

/// Sources and targets drawn in [-1, 1]^3; the first targets sit on sources (the self term).
struct KernelInput {
  std::vector<double> x, y, z, m;  ///< sources
  std::vector<double> tx, ty, tz;  ///< targets
};

KernelInput draw(std::mt19937_64& rng, std::size_t sources, std::size_t targets) {
  std::uniform_real_distribution<double> u(-1.0, 1.0), mass(0.1, 2.0);
  KernelInput in;
  for (std::size_t j = 0; j < sources; ++j) {
    in.x.push_back(u(rng)), in.y.push_back(u(rng)), in.z.push_back(u(rng)), in.m.push_back(mass(rng));
  }
  for (std::size_t t = 0; t < targets; ++t) {
    const bool on_source = t < sources && t % 3 == 0;
    in.tx.push_back(on_source ? in.x[t] : u(rng));
    in.ty.push_back(on_source ? in.y[t] : u(rng));
    in.tz.push_back(on_source ? in.z[t] : u(rng));
  }
  return in;
}

/// The four sums of a and b are the same doubles, bit for bit.
bool same_bits(const g::detail::Accum& a, const g::detail::Accum& b) {
  const auto bits = [](double v) { return std::bit_cast<std::uint64_t>(v); };
  return bits(a.ax) == bits(b.ax) && bits(a.ay) == bits(b.ay) && bits(a.az) == bits(b.az) && bits(a.phi) == bits(b.phi);
}

}  // namespace

// p2p_targets and p2p_approximate_targets read the sources once for several targets (four at a
// time on AVX-512 CPUs, the rest one by one); each target's sums must be those of p2p and
// p2p_approximate called for it alone, to the bit: the direct sum and the tree rely on it for
// results that do not depend on how targets are grouped. Source counts cover the 8-lane tails,
// target counts the groups of four and their remainders, with and without softening.
TEST(Kernels, SeveralTargetsGiveTheBitsOfOneAtATime) {
  std::mt19937_64 rng(17);
  std::vector<std::size_t> source_counts;
  for (std::size_t n = 1; n <= 37; ++n) source_counts.push_back(n);
  source_counts.push_back(1003);
  for (std::size_t n : source_counts) {
    for (std::size_t targets = 1; targets <= 9; ++targets) {
      const KernelInput in = draw(rng, n, targets);
      for (double eps2 : {0.0, 1e-4}) {
        for (bool approximate : {false, true}) {
          std::vector<g::detail::Accum> together(targets), alone(targets);
          const auto many = approximate ? g::detail::p2p_approximate_targets : g::detail::p2p_targets;
          const auto one = approximate ? g::detail::p2p_approximate : g::detail::p2p;
          many(in.x.data(), in.y.data(), in.z.data(), in.m.data(), n, in.tx.data(), in.ty.data(), in.tz.data(), targets,
               eps2, together.data());
          for (std::size_t t = 0; t < targets; ++t) {
            one(in.x.data(), in.y.data(), in.z.data(), in.m.data(), n, in.tx[t], in.ty[t], in.tz[t], eps2, alone[t]);
          }
          for (std::size_t t = 0; t < targets; ++t) {
            EXPECT_TRUE(same_bits(together[t], alone[t]))
                << "n " << n << ", target " << t << " of " << targets << ", eps2 " << eps2 << ", approximate "
                << approximate << ": ax " << together[t].ax << " vs " << alone[t].ax;
          }
        }
      }
    }
  }
}

// The quadrupole kernel against its formulas (kernels.hpp) evaluated term by term in long double.
// On AVX-512 CPUs its 1/sqrt(r^2 + eps2) is VRSQRT14PD with one Newton step (relative error
// < 5.6e-9; D^7 then within 7 times that); elsewhere sqrt and a division. Each sum must be within
// 1e-7 of the sum of its terms' magnitudes, far below the expansion's own error (>= 1e-6 at any
// practical theta). Cell counts cover the 8-lane tails; cells sit 2-4 units from the target, as
// accepted cells are well separated.
TEST(Kernels, QuadrupoleKernelWithinItsBoundOfTheFormula) {
  std::mt19937_64 rng(23);
  std::uniform_real_distribution<double> u(-1.0, 1.0), distance(2.0, 4.0), mass(0.1, 2.0), moment(-0.05, 0.05);
  for (std::size_t n = 1; n <= 37; ++n) {
    std::vector<double> cx(n), cy(n), cz(n), cm(n), q[6];
    for (auto& values : q) values.resize(n);
    const double xi = u(rng), yi = u(rng), zi = u(rng);
    for (std::size_t j = 0; j < n; ++j) {
      double dx = u(rng), dy = u(rng), dz = u(rng);
      const double scale = distance(rng) / std::sqrt(dx * dx + dy * dy + dz * dz);
      cx[j] = xi + scale * dx, cy[j] = yi + scale * dy, cz[j] = zi + scale * dz, cm[j] = mass(rng);
      for (int k : {0, 3, 5}) q[k][j] = cm[j] * (0.1 + std::abs(moment(rng)));  // diagonal: positive
      for (int k : {1, 2, 4}) q[k][j] = cm[j] * moment(rng);
    }
    for (double eps2 : {0.0, 1e-4}) {
      g::detail::Accum kernel;
      g::detail::m2p_quadrupole(cx.data(), cy.data(), cz.data(), cm.data(), q[0].data(), q[1].data(), q[2].data(),
                                q[3].data(), q[4].data(), q[5].data(), n, xi, yi, zi, eps2, kernel);
      long double ax = 0, ay = 0, az = 0, phi = 0, a_scale = 0, phi_scale = 0;
      for (std::size_t j = 0; j < n; ++j) {
        const long double rx = xi - cx[j], ry = yi - cy[j], rz = zi - cz[j];
        const long double d1 = 1.0L / std::sqrt(rx * rx + ry * ry + rz * rz + eps2);
        const long double d3 = d1 * d1 * d1, d5 = d3 * d1 * d1, d7 = d5 * d1 * d1;
        const long double xx = q[0][j], xy = q[1][j], xz = q[2][j], yy = q[3][j], yz = q[4][j], zz = q[5][j];
        const long double mrx = xx * rx + xy * ry + xz * rz, mry = xy * rx + yy * ry + yz * rz,
                          mrz = xz * rx + yz * ry + zz * rz;
        const long double rmr = rx * mrx + ry * mry + rz * mrz, tr = xx + yy + zz;
        const long double radial = cm[j] * d3 - 1.5L * d5 * tr + 7.5L * d7 * rmr;
        ax += radial * rx - 3 * d5 * mrx, ay += radial * ry - 3 * d5 * mry, az += radial * rz - 3 * d5 * mrz;
        phi += cm[j] * d1 + 1.5L * d5 * rmr - 0.5L * d3 * tr;
        const long double r = std::sqrt(rx * rx + ry * ry + rz * rz);
        a_scale += (cm[j] * d3 + 1.5L * d5 * std::abs(tr) + 7.5L * d7 * std::abs(rmr)) * r +
                   3 * d5 * std::sqrt(mrx * mrx + mry * mry + mrz * mrz);
        phi_scale += cm[j] * d1 + 1.5L * d5 * std::abs(rmr) + 0.5L * d3 * std::abs(tr);
      }
      const double tol_a = 1e-7 * static_cast<double>(a_scale), tol_phi = 1e-7 * static_cast<double>(phi_scale);
      EXPECT_NEAR(kernel.ax, static_cast<double>(ax), tol_a) << n << " cells, eps2 " << eps2;
      EXPECT_NEAR(kernel.ay, static_cast<double>(ay), tol_a) << n << " cells, eps2 " << eps2;
      EXPECT_NEAR(kernel.az, static_cast<double>(az), tol_a) << n << " cells, eps2 " << eps2;
      EXPECT_NEAR(kernel.phi, static_cast<double>(phi), tol_phi) << n << " cells, eps2 " << eps2;
    }
  }
}

// kernel_instruction_set() names the kernels that run: with "avx512" p2p_approximate takes one
// Newton step after VRSQRT14PD where p2p takes two, so some sums differ in their last bits; on any
// other set p2p_approximate is p2p, to the bit. The determinism test picks its tree golden by this
// name, so it must be the set the kernels really run.
TEST(Kernels, InstructionSetNameMatchesTheKernelsThatRun) {
  const std::string set = g::kernel_instruction_set();
  ASSERT_TRUE(set == "avx512" || set == "x86-64-v3" || set == "baseline" || set.starts_with("avx512 (")) << set;
  std::mt19937_64 rng(11);
  const KernelInput in = draw(rng, 64, 64);
  int differing = 0;
  for (std::size_t t = 0; t < in.tx.size(); ++t) {
    g::detail::Accum exact, approximate;
    g::detail::p2p(in.x.data(), in.y.data(), in.z.data(), in.m.data(), in.x.size(), in.tx[t], in.ty[t], in.tz[t], 1e-4,
                   exact);
    g::detail::p2p_approximate(in.x.data(), in.y.data(), in.z.data(), in.m.data(), in.x.size(), in.tx[t], in.ty[t],
                               in.tz[t], 1e-4, approximate);
    differing += same_bits(exact, approximate) ? 0 : 1;
  }
  if (set.starts_with("avx512")) {
    EXPECT_GT(differing, 0) << set;
  } else {
    EXPECT_EQ(differing, 0) << set;
  }
}
