// Tests of the interaction kernels (gravity/kernels.cpp) on their own: the several-target particle
// kernels against the one-target ones, to the bit.

#include "gravity/kernels.hpp"

#include <gtest/gtest.h>

#include <bit>
#include <cstddef>
#include <cstdint>
#include <random>
#include <vector>

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
