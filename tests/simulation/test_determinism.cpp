// Golden determinism tests: three fixed scenes, each run with 1 and with 2 OpenMP threads, must end
// in the same state to the bit, and that state must hash to its committed golden value:
//   spheres   1 100 spheres dropped into an open box, 250 steps of 1 ms;
//   polyhedra 98 random polyhedra poured into a box (the stability tests' pour), 1 200 steps of 0.25 ms;
//   tree      1 331 spheres on a grid collapsing under Barnes-Hut self-gravity, 60 steps.
//
// The hash is the checkpoint's own state_hash (simulation/checkpoint.hpp: CRC-64 of the state as a
// checkpoint stores it, time and step and every body's position, orientation, velocity and angular
// velocity), the value `rubble run` prints at the end of a run.
//
// Updating a golden value: only when the physics or the numerics change on purpose (a new
// contact law, a different sweep order, ...). Run the test; on failure it prints the new hash;
// check that the 1- and 2-thread hashes agree, paste the value and say why in the commit message.
// The value depends on the floating-point code the compiler emits: it is recorded for x86-64 with
// g++ 12 (-O2/-O3, no -march, no -ffast-math); the equality between thread counts must hold
// everywhere. The tree scene's value also depends on the CPU: the gravity kernels run the version
// compiled for its instruction set (gravity::kernel_instruction_set()), whose last bits differ, so
// it has one golden per set (AVX-512 and x86-64-v3 recorded; on another set only the thread counts
// are compared, and the test says so).
#include <gtest/gtest.h>
#include <omp.h>

#include <cstdint>
#include <functional>
#include <iomanip>
#include <iostream>
#include <optional>
#include <sstream>
#include <string>

#include "gravity/gravity.hpp"
#include "simulation/checkpoint.hpp"
#include "support/polyhedra_pour.hpp"
#include "support/test_scene.hpp"

namespace rubble {
namespace {

using testing::TestScene;

/// The committed hashes of the final states (see the header comment before changing them).
constexpr std::uint64_t golden_spheres = 0xcd05f3c5c0e5a5b9ULL;
constexpr std::uint64_t golden_polyhedra = 0xadb63ba1fdad365cULL;

/// The tree scene's golden for the gravity kernels' instruction set; none for a set not recorded.
std::optional<std::uint64_t> golden_tree(const std::string& instruction_set) {
  if (instruction_set == "avx512") return 0x159a48d4d1fbc21cULL;
  if (instruction_set == "x86-64-v3") return 0xd7e4ed38fbff4bfeULL;
  return std::nullopt;
}

std::string hex(std::uint64_t value) {
  std::ostringstream s;
  s << "0x" << std::hex << std::setw(16) << std::setfill('0') << value << "ULL";
  return s.str();
}

// 1 100 spheres (radii 4-6 cm by a fixed integer rule, no random generator whose output could
// differ between standard libraries) on an 11 x 10 x 10 grid of 12 cm cells, with a small
// deterministic sideways velocity, dropped into an open 1.5 m x 1.3 m box. More bodies than
// min_parallel_items (1 024) bodies so the threaded loops really run on two threads.
State spheres_in_a_box() {
  TestScene s(2500.0, 0.4, 0.1);
  s.uniform_gravity(9.81);
  s.options.integrator.time_step = 1e-3;
  s.options.solver.tolerance = 1e-4;
  s.options.solver.max_iterations = 200;
  s.plane(Vec3::Zero(), Vec3::UnitZ());
  s.plane(Vec3(-0.75, 0, 0), Vec3::UnitX());
  s.plane(Vec3(0.75, 0, 0), -Vec3::UnitX());
  s.plane(Vec3(0, -0.65, 0), Vec3::UnitY());
  s.plane(Vec3(0, 0.65, 0), -Vec3::UnitY());
  int i = 0;
  for (int z = 0; z < 10; ++z) {
    for (int y = 0; y < 10; ++y) {
      for (int x = 0; x < 11; ++x, ++i) {
        const double radius = 0.04 + 0.02 * static_cast<double>((i * 7919) % 17) / 16.0;
        const Vec3 position(-0.66 + 0.12 * x, -0.54 + 0.12 * y, 0.07 + 0.12 * z);
        const Vec3 velocity(0.1 * static_cast<double>((i * 31) % 7 - 3), 0.1 * static_cast<double>((i * 17) % 5 - 2),
                            -0.5);
        s.sphere(radius, position, velocity);
      }
    }
  }
  s.steps(250);
  double lowest = 1e9;  // the grains fell and collided: not the hash of a trivial state
  for (std::size_t b = 5; b < s.state.body_count(); ++b) lowest = std::min(lowest, s.state.position[b].z());
  EXPECT_LT(lowest, 0.07);
  return s.state;
}

// The polyhedral pour of the stability tests (random shapes from fixed seeds: the generator is
// ours, preprocessing/random_polyhedron.hpp, on std::mt19937_64, whose output the standard fixes),
// with every solver setting at its default: common-plane detection, the sweeps' block order, the
// Newton polish.
State polyhedra_in_a_box() {
  TestScene s(2500.0, 0.5, 0.0);
  s.uniform_gravity(9.81);
  s.options.integrator.time_step = 2.5e-4;
  s.options.solver = SolverOptions{};
  testing::add_polyhedra_pour(s, 98, 0.1, 1000, 7);
  std::size_t most_contacts = 0;
  for (int k = 0; k < 1200; ++k) most_contacts = std::max(most_contacts, s.advance().contacts);
  EXPECT_GT(most_contacts, 50u);  // the grains met the floor and each other
  return s.state;
}

// 11^3 spheres of radius 0.45 m on a 1 m grid (G = 1, density 1: a free-fall time of order 1 s)
// collapsing under the Barnes-Hut tree's quadrupole field; 60 steps of 10 ms bring the first
// contacts. More bodies than min_parallel_items, and the tree's walk runs on both threads.
State tree_gravity_cloud() {
  TestScene s(1.0, 0.3, 0.0);
  s.options.integrator.time_step = 1e-2;
  s.options.solver.tolerance = 1e-4;
  s.options.gravity.kind = GravitySettings::Kind::self;
  s.options.gravity.self_gravity.method = gravity::Method::tree;
  s.options.gravity.self_gravity.G = 1.0;
  for (int x = 0; x < 11; ++x)
    for (int y = 0; y < 11; ++y)
      for (int z = 0; z < 11; ++z) s.sphere(0.45, Vec3(x - 5.0, y - 5.0 + 0.01 * x, z - 5.0));
  s.steps(60);
  double farthest = 0.0;  // the cloud contracted (its corners started at 5 sqrt(3) = 8.66 m)
  for (std::size_t b = 0; b < s.state.body_count(); ++b) farthest = std::max(farthest, s.state.position[b].norm());
  EXPECT_LT(farthest, 8.6);
  return s.state;
}

/// Runs `scene` with one thread and with two: success when both give the same state hash, equal
/// to `golden` when there is one; else the hashes, for the TEST to report.
::testing::AssertionResult same_for_both_thread_counts_and_golden(const std::function<State()>& scene,
                                                                  std::optional<std::uint64_t> golden,
                                                                  const char* name) {
  const int previous = omp_get_max_threads();
  omp_set_num_threads(1);
  const State one = scene();
  omp_set_num_threads(2);
  const State two = scene();
  omp_set_num_threads(previous);
  const std::uint64_t h1 = state_hash(one), h2 = state_hash(two);
  if (h1 != h2) return ::testing::AssertionFailure() << name << ": 1 thread " << hex(h1) << ", 2 threads " << hex(h2);
  if (golden && h1 != *golden) {
    return ::testing::AssertionFailure() << name << ": final state hash " << hex(h1) << ", golden " << hex(*golden)
                                         << "; if the physics changed on purpose, update its golden value (see the "
                                            "header comment)";
  }
  return ::testing::AssertionSuccess();
}

TEST(Determinism, SpheresInABoxSameForOneAndTwoThreadsAndGolden) {
  EXPECT_TRUE(same_for_both_thread_counts_and_golden(spheres_in_a_box, golden_spheres, "spheres"));
}

TEST(Determinism, PolyhedraInABoxSameForOneAndTwoThreadsAndGolden) {
  EXPECT_TRUE(same_for_both_thread_counts_and_golden(polyhedra_in_a_box, golden_polyhedra, "polyhedra"));
}

TEST(Determinism, TreeGravityCloudSameForOneAndTwoThreadsAndGolden) {
  const std::string instruction_set = gravity::kernel_instruction_set();
  const std::optional<std::uint64_t> golden = golden_tree(instruction_set);
  if (!golden) {
    std::cout << "no tree golden recorded for the gravity kernels' instruction set \"" << instruction_set
              << "\": only the 1- and 2-thread hashes are compared\n";
  }
  EXPECT_TRUE(same_for_both_thread_counts_and_golden(tree_gravity_cloud, golden, "tree"));
}

}  // namespace
}  // namespace rubble
