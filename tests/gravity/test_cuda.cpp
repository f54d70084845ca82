// Tests of the CUDA backend (gravity/cuda/direct_sum.cu). Without the backend or without a GPU the
// numerical tests are skipped with a message saying why; the fallback behaviour is still checked.

#include "gravity/cuda.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "gravity/direct_sum.hpp"
#include "test_support.hpp"

namespace g = rubble::gravity;

namespace {

g::GravityOptions direct_options() {
  g::GravityOptions o;
  o.method = g::Method::direct;
  o.G = 1.0;
  return o;
}

}  // namespace

TEST(Cuda, DirectSumMatchesCpu) {
  if (!g::cuda::compiled()) GTEST_SKIP() << "CUDA backend not built: " << g::cuda::unavailable_reason();
  if (!g::cuda::available()) GTEST_SKIP() << "no GPU on this machine: " << g::cuda::unavailable_reason();
  for (double eps : {0.0, 0.01}) {
    const auto p = g::testing::plummer_sphere(3000, 1.0, 1.0, 81);
    auto o = direct_options();
    if (eps > 0) o.softening = {g::Softening::Kind::plummer, eps};
    std::vector<double> a_cpu(3 * p.size()), a_gpu(3 * p.size()), f_cpu(p.size()), f_gpu(p.size());
    g::direct_sum(o, p.pos, p.mass, a_cpu, f_cpu);
    g::cuda::direct_sum(o, p.pos, p.mass, a_gpu, f_gpu);
    // Same sum in a different rounding order (FMA, rsqrt): relative agreement ~1e-13.
    const auto e = g::testing::relative_errors(a_gpu, a_cpu);
    EXPECT_LT(e.max, 1e-11) << "eps " << eps;
    for (std::size_t i = 0; i < p.size(); ++i) EXPECT_NEAR(f_gpu[i], f_cpu[i], 1e-11 * std::abs(f_cpu[i]));
  }
}

TEST(Cuda, UnavailableBackendThrowsWithAReason) {
  if (g::cuda::available()) GTEST_SKIP() << "a GPU is present: the fallback path is not exercised";
  EXPECT_FALSE(g::cuda::unavailable_reason().empty());
  EXPECT_EQ(g::cuda::device_count(), 0);
  const std::vector<double> pos{0, 0, 0, 1, 0, 0}, m{1, 1};
  std::vector<double> a(6);
  EXPECT_THROW(g::cuda::direct_sum(direct_options(), pos, m, a, {}), g::GravityError);
}
