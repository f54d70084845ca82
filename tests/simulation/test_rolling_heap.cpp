// A small heap with and without rolling resistance (ContactLaw::rolling_friction): the multi-contact
// counterpart of the single-sphere closed forms of tests/nlgs_solver/test_rotation_resistance.cpp.
// Rolling resistance stands in for the shape spheres lack and steepens their heaps (Zhou et al. 2001,
// "Numerical investigation of the angle of repose of monosized spheres": increasing the rolling
// friction coefficient increases the angle of repose); examples/angle-of-repose/ measures the angle
// of 2 000-sphere pours. Here 50 spheres (radius 4.5-5.5 mm, mu = 0.5) released as a column of 2 x 2
// grains per layer collapse onto a rough floor (fixed spheres of radius 5 mm on a square lattice,
// heights +-1 mm) and settle; the only difference between the two runs is mu_r, so without a working
// rolling resistance they would be the same heap bit for bit.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <iostream>
#include <vector>

#include "support/test_scene.hpp"

namespace rubble {
namespace {

using testing::TestScene;

/// A number in [0, 1) from an integer, the same on every platform (SplitMix64's finaliser), so the
/// heap does not depend on a standard library's random distributions.
double unit_hash(std::uint64_t k) {
  k += 0x9e3779b97f4a7c15ULL;
  k = (k ^ (k >> 30)) * 0xbf58476d1ce4e5b9ULL;
  k = (k ^ (k >> 27)) * 0x94d049bb133111ebULL;
  k ^= k >> 31;
  return static_cast<double>(k >> 11) * 0x1.0p-53;
}

struct Heap {
  double height = 0.0;       ///< m, top of the highest grain above the floor spheres' top
  double mean_radius = 0.0;  ///< m, mean horizontal distance of the grains from their centroid
  double speed = 0.0;        ///< m/s, 90th percentile of |v| + |w| r at the end
  /// The heap's height over its mean radius: grows with its slope, and shrinks as grains roll away.
  double aspect() const { return height / mean_radius; }
};

/// The heap of 50 spheres released in the column arrangement drawn from hash number `arrangement`.
Heap settle_heap(double rolling_friction, std::uint64_t arrangement) {
  constexpr int grains = 50;
  constexpr double floor_radius = 0.005, pitch = 0.0105, floor_extent = 0.12, cell = 0.0121;
  TestScene s(2500.0, 0.5, 0.0);
  ContactLaw law{0.5, 0.0};
  law.rolling_friction = rolling_friction;
  s.model.contact_laws.reset(1, law);
  s.uniform_gravity();
  s.options.integrator.time_step = 1e-3;
  s.options.solver.tolerance = 1e-3;
  s.options.solver.max_iterations = 1000;
  s.options.detection.alert_distance = 1.5e-3;
  const int lattice = static_cast<int>(floor_extent / pitch);
  std::uint64_t k = 0;
  for (int i = -lattice; i <= lattice; ++i) {
    for (int j = -lattice; j <= lattice; ++j) {
      const double x = i * pitch, y = j * pitch;
      if (std::hypot(x, y) > floor_extent) continue;
      const int id = s.sphere(floor_radius, Vec3(x, y, 0.002 * unit_hash(1000000 + k++) - 0.001));
      s.drive(id, Vec3::Zero());
    }
  }
  s.plane(Vec3(0, 0, -0.0065), Vec3::UnitZ());  // catches a grain that rolls off the floor's edge
  std::vector<int> ids;
  for (int g = 0; g < grains; ++g) {
    const int layer = g / 4, column = g % 4;
    const std::uint64_t n = 1000 * arrangement + 3 * static_cast<std::uint64_t>(g);
    const double radius = 0.0045 + 0.001 * unit_hash(n);
    const double jitter = 0.5 * (cell - 2 * radius);  // the grain stays inside its cell
    const int ix = column % 2, iy = column / 2;       // the grain's cell of the column's 2 x 2
    const Vec3 centre((ix - 0.5) * cell, (iy - 0.5) * cell, 0.012 + layer * cell);
    const double ux = unit_hash(n + 1), uy = unit_hash(n + 2);
    const Vec3 offset(jitter * (2 * ux - 1), jitter * (2 * uy - 1), 0.0);
    ids.push_back(s.sphere(radius, centre + offset));
  }
  s.run(1.0);
  double cx = 0.0, cy = 0.0;
  for (const int id : ids) {
    cx += s.state.position[static_cast<std::size_t>(id)].x() / grains;
    cy += s.state.position[static_cast<std::size_t>(id)].y() / grains;
  }
  Heap heap;
  std::vector<double> speeds;
  for (const int id : ids) {
    const auto b = static_cast<std::size_t>(id);
    const double r = s.model.bounding_radius[b];
    heap.height = std::max(heap.height, s.state.position[b].z() + r - (floor_radius + 0.001));
    heap.mean_radius += std::hypot(s.state.position[b].x() - cx, s.state.position[b].y() - cy) / grains;
    speeds.push_back(s.state.velocity[b].norm() + s.state.angular_velocity[b].norm() * r);
  }
  std::sort(speeds.begin(), speeds.end());
  heap.speed = speeds[static_cast<std::size_t>(0.9 * grains)];
  return heap;
}

// Reference: a heap's slope grows with its height over its radius, and rolling resistance steepens it;
// without it the grains at the foot roll away. A heap of 50 grains is too small for a fitted angle, and
// one column arrangement alone is noisy (the ratio below ranged 1.29-2.06 over twenty arrangements taken
// one at a time), so the test averages four. Pass: the mean over four arrangements of height / mean radius (height: the
// highest grain's top) is at least 20% larger with mu_r = 0.2 than with mu_r = 0 (measured: 0.635
// against 0.391, ratio 1.62; 1.58-1.83 for the next four groups of four arrangements), and each heap
// has come to rest: 90% of its grains slower than 1 cm/s at t = 1 s (measured: below 1e-6 m/s; the
// collapse is over by 0.8 s, and with mu_r = 0 a grain may still roll across the floor). About 6 s of
// CPU on the shared 2-core machine.
TEST(RollingHeap, RollingResistanceMakesASteeperHeap) {
  double free = 0.0, held = 0.0;
  for (std::uint64_t arrangement = 0; arrangement < 4; ++arrangement) {
    const Heap a = settle_heap(0.0, arrangement);
    const Heap b = settle_heap(0.2, arrangement);
    std::cout << "50-sphere heap " << arrangement << ": mu_r = 0: height " << a.height << " m, mean radius "
              << a.mean_radius << " m, aspect " << a.aspect() << ", p90 speed " << a.speed
              << " m/s; mu_r = 0.2: height " << b.height << " m, mean radius " << b.mean_radius << " m, aspect "
              << b.aspect() << ", p90 speed " << b.speed << " m/s\n";
    EXPECT_LT(a.speed, 0.01);
    EXPECT_LT(b.speed, 0.01);
    free += a.aspect() / 4;
    held += b.aspect() / 4;
  }
  std::cout << "mean aspect: mu_r = 0: " << free << ", mu_r = 0.2: " << held << ", ratio " << held / free << "\n";
  EXPECT_GT(held, 1.2 * free);
}

}  // namespace
}  // namespace rubble
