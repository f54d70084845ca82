// Tests of the CUDA backend (gravity/cuda/: the direct sum and the tree walk) and of the backend
// selection of compute_field(). Without the backend or without a GPU the numerical tests are
// skipped with a message saying why; the error path (BackendUnavailable) is checked everywhere.
// The GPU tests run where the device tool lends a GPU (bench/RESULTS.md, "GPU gravity", says when
// and on which card they last ran).

#include "gravity/cuda.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numeric>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "gravity/direct_sum.hpp"
#include "gravity/tree.hpp"
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

// ---- backend selection through compute_field()

TEST(Backend, CpuIsTheDefaultAndAlwaysAvailable) {
  g::GravityOptions o;
  EXPECT_EQ(o.backend, g::Backend::cpu);
  EXPECT_EQ(g::backend_unavailable_reason(o), "");
  o.method = g::Method::direct;
  EXPECT_EQ(g::backend_unavailable_reason(o), "");
  EXPECT_EQ(g::to_string(g::Backend::cpu), "cpu");
  EXPECT_EQ(g::to_string(g::Backend::cuda), "cuda");
}

TEST(Backend, CudaTreeWithoutGpuIsRefusedWithAReason) {
  if (g::cuda::available()) GTEST_SKIP() << "a GPU is present: the refusal is not exercised";
  g::GravityOptions o;
  o.method = g::Method::tree;
  o.backend = g::Backend::cuda;
  EXPECT_EQ(g::backend_unavailable_reason(o), g::cuda::unavailable_reason());
  const std::vector<double> pos{0, 0, 0, 1, 0, 0}, m{1, 1};
  std::vector<double> a(6, -7.0);
  try {
    g::compute_field(o, pos, m, a, {});
    FAIL() << "backend cuda with the tree method did not throw without a GPU";
  } catch (const g::BackendUnavailable& e) {
    EXPECT_NE(std::string(e.what()).find("backend cuda: "), std::string::npos) << e.what();
  }
  EXPECT_EQ(a, std::vector<double>(6, -7.0)) << "the outputs were written before the refusal";
}

TEST(Backend, CudaTreeRefusesSinglePrecision) {
  // The GPU kernels are double only: asking for float there is refused on every machine, GPU or
  // not, rather than silently computed in double.
  g::GravityOptions o;
  o.method = g::Method::tree;
  o.backend = g::Backend::cuda;
  o.precision = g::KernelPrecision::single_precision;
  const std::string reason = g::backend_unavailable_reason(o);
  EXPECT_NE(reason.find("double precision only"), std::string::npos) << reason;
  const std::vector<double> pos{0, 0, 0, 1, 0, 0}, m{1, 1};
  std::vector<double> a(6, -7.0);
  EXPECT_THROW(g::compute_field(o, pos, m, a, {}), g::BackendUnavailable);
  EXPECT_EQ(a, std::vector<double>(6, -7.0));
}

TEST(Backend, CudaWithoutGpuThrowsBackendUnavailable) {
  if (g::cuda::available()) GTEST_SKIP() << "a GPU is present: the refusal is not exercised";
  auto o = direct_options();
  o.backend = g::Backend::cuda;
  EXPECT_EQ(g::backend_unavailable_reason(o), g::cuda::unavailable_reason());
  const std::vector<double> pos{0, 0, 0, 1, 0, 0}, m{1, 1};
  std::vector<double> a(6);
  EXPECT_THROW(g::compute_field(o, pos, m, a, {}), g::BackendUnavailable);
  // Still a GravityError, so callers that catch bad input catch it too.
  EXPECT_THROW(g::compute_field(o, pos, m, a, {}), g::GravityError);
  // Invalid input is reported as such before the backend is looked at.
  const std::vector<double> bad_masses{1, -1};
  try {
    g::compute_field(o, pos, bad_masses, a, {});
    FAIL() << "a negative mass was accepted";
  } catch (const g::BackendUnavailable&) {
    FAIL() << "the backend was blamed for a negative mass";
  } catch (const g::GravityError&) {
  }
}

TEST(Backend, CudaDirectThroughComputeFieldMatchesCpuAndRepeats) {
  auto o = direct_options();
  o.backend = g::Backend::cuda;
  const std::string reason = g::backend_unavailable_reason(o);
  if (!reason.empty()) GTEST_SKIP() << "backend cuda cannot run here: " << reason;
  const auto p = g::testing::plummer_sphere(5000, 1.0, 1.0, 83);
  std::vector<double> a_cpu(3 * p.size()), a_gpu(3 * p.size()), a_again(3 * p.size());
  g::direct_sum(direct_options(), p.pos, p.mass, a_cpu, {});
  g::compute_field(o, p.pos, p.mass, a_gpu, {});
  g::compute_field(o, p.pos, p.mass, a_again, {});
  const auto e = g::testing::relative_errors(a_gpu, a_cpu);
  EXPECT_LT(e.max, 1e-11);
  // Each target is summed by one GPU thread in index order: the same bits run to run.
  EXPECT_EQ(std::memcmp(a_gpu.data(), a_again.data(), a_gpu.size() * sizeof(double)), 0);
}

TEST(Backend, CudaTreeErrorNoWorseThanCpuTree) {
  g::GravityOptions o;
  o.G = 1.0;
  o.method = g::Method::tree;
  o.theta = 0.5;
  o.order = 2;
  o.backend = g::Backend::cuda;
  const std::string reason = g::backend_unavailable_reason(o);
  if (!reason.empty()) GTEST_SKIP() << "backend cuda cannot run the tree here: " << reason;
  for (std::size_t n : {std::size_t{10000}, std::size_t{100000}, std::size_t{1000000}}) {
    const auto p = g::testing::uniform_sphere(n, 1.0, 1.0, 85);
    // Exact field on 2000 random targets (the direct sum over all N targets is too slow at 10^6).
    std::vector<std::size_t> targets(n);
    std::iota(targets.begin(), targets.end(), std::size_t{0});
    std::mt19937_64 rng(9);
    std::shuffle(targets.begin(), targets.end(), rng);
    targets.resize(2000);
    std::vector<double> ref(3 * targets.size());
    g::direct_sum_targets(direct_options(), p.pos, p.mass, targets, ref, {});
    auto errors_of = [&](g::Backend backend) {
      auto options = o;
      options.backend = backend;
      std::vector<double> a(3 * n), picked(3 * targets.size());
      g::compute_field(options, p.pos, p.mass, a, {});
      for (std::size_t k = 0; k < targets.size(); ++k)
        for (int c = 0; c < 3; ++c) picked[3 * k + c] = a[3 * targets[k] + c];
      return g::testing::relative_errors(picked, ref);
    };
    const auto cpu = errors_of(g::Backend::cpu), gpu = errors_of(g::Backend::cuda);
    // Same opening criterion, so the same errors up to float use and summation order: 10 % slack.
    EXPECT_LE(gpu.median, 1.1 * cpu.median) << "N " << n;
    EXPECT_LE(gpu.p99, 1.1 * cpu.p99) << "N " << n;
  }
}

namespace {

/// Field of `p` by the tree on `backend`, acceleration and potential.
struct Field {
  std::vector<double> acc, pot;
};
Field tree_field(const g::testing::Particles& p, g::GravityOptions o, g::Backend backend) {
  o.backend = backend;
  Field f{std::vector<double>(3 * p.size()), std::vector<double>(p.size())};
  g::compute_field(o, p.pos, p.mass, f.acc, f.pot);
  return f;
}

/// Largest |a_gpu - a_cpu| over (|a_cpu| + 1e-3 rms|a|) and largest relative potential difference:
/// the two trees accept the same nodes, so they differ by rounding only.
std::pair<double, double> tree_differences(const Field& gpu, const Field& cpu) {
  const std::size_t n = cpu.pot.size();
  double a2 = 0;
  for (double v : cpu.acc) a2 += v * v;
  const double floor = 1e-3 * std::sqrt(a2 / static_cast<double>(std::max<std::size_t>(n, 1)));
  double worst_a = 0, worst_phi = 0;
  for (std::size_t i = 0; i < n; ++i) {
    double d2 = 0, c2 = 0;
    for (std::size_t c = 0; c < 3; ++c) {
      d2 += std::pow(gpu.acc[3 * i + c] - cpu.acc[3 * i + c], 2);
      c2 += cpu.acc[3 * i + c] * cpu.acc[3 * i + c];
    }
    worst_a = std::max(worst_a, std::sqrt(d2) / (std::sqrt(c2) + floor));
    worst_phi = std::max(worst_phi, std::abs(gpu.pot[i] - cpu.pot[i]) / std::abs(cpu.pot[i]));
  }
  return {worst_a, worst_phi};
}

g::GravityOptions tree_options(int order, double eps) {
  g::GravityOptions o;
  o.G = 1.0;
  o.method = g::Method::tree;
  o.theta = 0.5;
  o.order = order;
  if (eps > 0) o.softening = {g::Softening::Kind::plummer, eps};
  return o;
}

}  // namespace

TEST(Cuda, TreeMatchesCpuTreeAndRepeatsBitForBit) {
  g::GravityOptions probe = tree_options(2, 0.0);
  probe.backend = g::Backend::cuda;
  const std::string reason = g::backend_unavailable_reason(probe);
  if (!reason.empty()) GTEST_SKIP() << "backend cuda cannot run the tree here: " << reason;
  const auto p = g::testing::plummer_sphere(20000, 1.0, 1.0, 87);
  for (int order : {1, 2})
    for (double eps : {0.0, 0.01}) {
      const g::GravityOptions o = tree_options(order, eps);
      const Field cpu = tree_field(p, o, g::Backend::cpu);
      const Field gpu = tree_field(p, o, g::Backend::cuda);
      const Field again = tree_field(p, o, g::Backend::cuda);
      // Same nodes accepted: rounding differences only (the CPU's one-Newton-step 1/sqrt is within
      // 1.7e-8 a term; a tree's own error is >= 1e-5 here).
      const auto [da, dphi] = tree_differences(gpu, cpu);
      EXPECT_LT(da, 1e-6) << "order " << order << " eps " << eps;
      EXPECT_LT(dphi, 1e-7) << "order " << order << " eps " << eps;
      EXPECT_EQ(std::memcmp(gpu.acc.data(), again.acc.data(), gpu.acc.size() * sizeof(double)), 0);
      EXPECT_EQ(std::memcmp(gpu.pot.data(), again.pot.data(), gpu.pot.size() * sizeof(double)), 0);
    }
}

TEST(Cuda, TreeHandlesTinyInputsAndALeafLargerThanAGroup) {
  g::GravityOptions o = tree_options(2, 0.0);
  o.backend = g::Backend::cuda;
  const std::string reason = g::backend_unavailable_reason(o);
  if (!reason.empty()) GTEST_SKIP() << "backend cuda cannot run the tree here: " << reason;
  {  // no particle, one particle (no force on itself), two (exact)
    std::vector<double> a;
    EXPECT_NO_THROW(g::compute_field(o, {}, {}, a, {}));
    std::vector<double> a1(3, 5.0), f1(1, 5.0);
    g::compute_field(o, std::vector<double>{1, 2, 3}, std::vector<double>{2}, a1, f1);
    EXPECT_EQ(a1, std::vector<double>(3, 0.0));
    EXPECT_EQ(f1[0], 0.0);
    std::vector<double> a2(6), f2(2);
    g::compute_field(o, std::vector<double>{0, 0, 0, 2, 0, 0}, std::vector<double>{1, 3}, a2, f2);
    EXPECT_DOUBLE_EQ(a2[0], 3.0 / 4.0);
    EXPECT_DOUBLE_EQ(a2[3], -1.0 / 4.0);
    EXPECT_DOUBLE_EQ(f2[0], -3.0 / 2.0);
  }
  // 300 coincident particles make one leaf (identical Morton keys) and one group of 300 targets,
  // more than a GPU block's 64 threads: each thread sums several targets. With softening they pull
  // on each other; against the CPU tree and the exact direct sum.
  auto p = g::testing::uniform_sphere(3000, 1.0, 1.0, 89);
  for (std::size_t i = 0; i < 300; ++i)
    for (std::size_t c = 0; c < 3; ++c) p.pos[3 * i + c] = 0.25;
  const g::GravityOptions soft = tree_options(2, 0.05);
  const Field cpu = tree_field(p, soft, g::Backend::cpu);
  const Field gpu = tree_field(p, soft, g::Backend::cuda);
  const auto [da, dphi] = tree_differences(gpu, cpu);
  EXPECT_LT(da, 1e-6);
  EXPECT_LT(dphi, 1e-7);
  g::GravityOptions exact = soft;
  exact.method = g::Method::direct;
  std::vector<double> a_exact(3 * p.size());
  g::direct_sum(exact, p.pos, p.mass, a_exact, {});
  EXPECT_LT(g::testing::relative_errors(gpu.acc, a_exact).median, 1e-3);
}

// The tree built on the GPU is gravity::Tree's: the same Morton order, the same node array (the
// GPU builds level by level, then numbers the nodes depth first as the host does) with the same
// moments to the last bit (tree_build.cu runs the host's formulas without fused multiply-adds), and
// the same groups. Ties in the keys (coincident particles) and a Plummer halo (deep, uneven tree)
// included.
TEST(Cuda, TreeBuiltOnTheGpuIsTheHostTree) {
  g::GravityOptions o = tree_options(2, 0.0);
  o.backend = g::Backend::cuda;
  const std::string reason = g::backend_unavailable_reason(o);
  if (!reason.empty()) GTEST_SKIP() << "backend cuda cannot run the tree here: " << reason;
  auto p = g::testing::plummer_sphere(50000, 1.0, 1.0, 91);
  for (std::size_t i = 0; i + 1 < 2000; i += 2)
    for (std::size_t c = 0; c < 3; ++c) p.pos[3 * (i + 1) + c] = p.pos[3 * i + c];
  for (int group_size : {64, 7}) {
    o.group_size = group_size;
    g::Tree host(o.leaf_size, o.group_size);
    host.build(p.pos, p.mass);
    const auto gpu = g::cuda::built_tree(o, p.pos, p.mass);
    EXPECT_EQ(gpu.order, host.order());
    ASSERT_EQ(gpu.nodes.size(), host.nodes().size());
    std::size_t mismatched = 0;
    for (std::size_t i = 0; i < gpu.nodes.size(); ++i) {
      const auto& b = gpu.nodes[i];
      const g::Tree::Node& h = host.nodes()[i];
      const auto& q = host.second_moments()[i];
      const bool same = b.begin == h.begin && b.count == h.count && b.num_children == h.num_children && b.cx == h.cx &&
                        b.cy == h.cy && b.cz == h.cz && b.mass == h.mass && b.bmax == h.bmax && b.size == h.size &&
                        b.delta == h.delta && std::equal(b.lo, b.lo + 3, h.lo.begin()) &&
                        std::equal(b.hi, b.hi + 3, h.hi.begin()) && std::equal(b.q, b.q + 6, q.begin());
      if (!same && mismatched++ == 0) ADD_FAILURE() << "first differing node " << i << ", group_size " << group_size;
    }
    EXPECT_EQ(mismatched, 0u) << "nodes differing from the host's, group_size " << group_size;
    ASSERT_EQ(gpu.groups.size(), host.groups().size());
    auto gpu_groups = gpu.groups;
    std::sort(gpu_groups.begin(), gpu_groups.end(), [](const auto& a, const auto& b) { return a.begin < b.begin; });
    auto host_groups = host.groups();
    std::sort(host_groups.begin(), host_groups.end(), [](const auto& a, const auto& b) { return a.begin < b.begin; });
    for (std::size_t k = 0; k < host_groups.size(); ++k) {
      EXPECT_EQ(gpu_groups[k].begin, host_groups[k].begin);
      EXPECT_EQ(gpu_groups[k].count, host_groups[k].count);
      EXPECT_TRUE(std::equal(gpu_groups[k].lo, gpu_groups[k].lo + 3, host_groups[k].lo.begin()) &&
                  std::equal(gpu_groups[k].hi, gpu_groups[k].hi + 3, host_groups[k].hi.begin()))
          << "group " << k;
    }
  }
}
