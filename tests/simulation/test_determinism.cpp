// Golden determinism test: a fixed scene (1 100 spheres dropped into an open box, 250 steps of 1 ms) run
// with 1 and with 2 OpenMP threads must end in the same state to the bit, and that state must
// hash to the committed golden value.
//
// The hash is FNV-1a 64 (Fowler-Noll-Vo: h = 14695981039346656037; per byte h = (h ^ byte) *
// 1099511628211 mod 2^64) over the bytes of time, step and, body by body, position (x, y, z),
// orientation (w, x, y, z), velocity and angular velocity, as IEEE-754 doubles in the machine's
// byte order (little-endian on x86-64 and aarch64).
//
// Updating the golden value: only when the physics or the numerics change on purpose (a new
// contact law, a different sweep order, ...). Run the test; on failure it prints the new hash
// (`golden_hash` below); check that the 1- and 2-thread hashes agree, paste the value and say
// why in the commit message. The value depends on the floating-point code the compiler emits:
// it is recorded for x86-64 with g++ 12 (-O2/-O3, no -march, no -ffast-math); the equality
// between thread counts must hold everywhere.
#include <gtest/gtest.h>
#include <omp.h>

#include <cstdint>
#include <cstring>
#include <iomanip>
#include <sstream>

#include "support/test_scene.hpp"

namespace rubble {
namespace {

using testing::TestScene;

/// The committed hash of the final state (see the header comment before changing it).
constexpr std::uint64_t golden_hash = 0xba0b258aa1b6aa87ULL;

/// FNV-1a 64 of a byte range, continuing from `hash`.
std::uint64_t fnv1a(std::uint64_t hash, const void* data, std::size_t size) {
  const auto* bytes = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < size; ++i) {
    hash ^= bytes[i];
    hash *= 1099511628211ULL;
  }
  return hash;
}

std::uint64_t state_hash(const State& state) {
  std::uint64_t h = 14695981039346656037ULL;
  h = fnv1a(h, &state.time, sizeof state.time);
  h = fnv1a(h, &state.step, sizeof state.step);
  for (std::size_t b = 0; b < state.body_count(); ++b) {
    const Quat& q = state.orientation[b];
    const double orientation[4] = {q.w(), q.x(), q.y(), q.z()};
    h = fnv1a(h, state.position[b].data(), 3 * sizeof(double));
    h = fnv1a(h, orientation, sizeof orientation);
    h = fnv1a(h, state.velocity[b].data(), 3 * sizeof(double));
    h = fnv1a(h, state.angular_velocity[b].data(), 3 * sizeof(double));
  }
  return h;
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
State run_scene(int threads) {
  omp_set_num_threads(threads);
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
        const Vec3 velocity(0.1 * static_cast<double>((i * 31) % 7 - 3), 0.1 * static_cast<double>((i * 17) % 5 - 2), -0.5);
        s.sphere(radius, position, velocity);
      }
    }
  }
  s.steps(250);
  return s.state;
}

TEST(Determinism, FinalStateIsIdenticalForOneAndTwoThreadsAndMatchesTheGoldenHash) {
  const int previous = omp_get_max_threads();
  const State one = run_scene(1);
  const State two = run_scene(2);
  omp_set_num_threads(previous);
  const std::uint64_t h1 = state_hash(one), h2 = state_hash(two);
  EXPECT_EQ(h1, h2) << "1 thread: " << hex(h1) << ", 2 threads: " << hex(h2);
  // The scene did something: the grains fell and collided (not a trivial hash of a resting state).
  double lowest = 1e9;
  for (std::size_t b = 5; b < one.body_count(); ++b) lowest = std::min(lowest, one.position[b].z());
  EXPECT_LT(lowest, 0.07);
  EXPECT_EQ(h1, golden_hash) << "final state hash " << hex(h1)
                             << "; if the physics changed on purpose, update golden_hash (see the header comment)";
}

}  // namespace
}  // namespace rubble
