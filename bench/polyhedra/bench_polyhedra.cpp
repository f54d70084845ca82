// Polyhedra benchmark (plain timed executable; results in bench/RESULTS.md, "Polyhedra").
//   bench_polyhedra narrow [pairs]          narrow-phase throughput, cold and warm-started
//   bench_polyhedra deposit [grains] [steps] a box deposit of random polyhedra: steps/s, contacts,
//                                            NLGS sweeps, time per stage
// Both print a hash of their results (every contact's id, point, frame and gap and the common
// normals; the deposit's final state), so two builds can be checked to give the same bits.
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <random>
#include <string>

#include "contact_detection/common_plane.hpp"
#include "contact_detection/narrow_phase_polyhedra.hpp"
#include "core/polyhedron.hpp"
#include "preprocessing/random_polyhedron.hpp"
#include "simulation/checkpoint.hpp"
#include "simulation/step.hpp"

namespace {

using namespace rubble;
using Clock = std::chrono::steady_clock;

double seconds(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

/// CPU seconds of the calling thread: the narrow-phase rates are per CPU second, so that other
/// processes sharing the core do not count against the code measured.
double thread_cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

/// FNV-1a over the bytes of a value: a result hash to compare two builds bit for bit.
template <class T>
void hash_bytes(std::uint64_t& hash, const T& value) {
  unsigned char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  for (unsigned char byte : bytes) hash = (hash ^ byte) * 1099511628211ull;
}

/// Hash of what the narrow phase outputs for a contact: id, point, frame, gap.
void hash_contact(std::uint64_t& hash, const Contact& c) {
  hash_bytes(hash, c.id.body_a);
  hash_bytes(hash, c.id.body_b);
  hash_bytes(hash, c.id.feature_a);
  hash_bytes(hash, c.id.feature_b);
  for (int k = 0; k < 3; ++k) hash_bytes(hash, c.point[k]);
  for (int k = 0; k < 9; ++k) hash_bytes(hash, c.frame.data()[k]);
  hash_bytes(hash, c.gap);
}

Quat random_rotation(std::mt19937_64& rng) {
  std::normal_distribution<double> normal;
  return Quat(normal(rng), normal(rng), normal(rng), normal(rng)).normalized();
}

/// Pairs of random polyhedra (d = 1, 10-70 vertices) at poses near contact: B is moved along a
/// random direction until the common-plane gap is uniform in [-0.02, 0.05] d (the pairs a
/// broad phase passes on in a dense pack). Throughput of collide_polyhedron_polyhedron, cold
/// (normal from the line of centres) and warm (last step's normal after a small motion).
int narrow(int pairs) {
  Model model;
  model.materials.push_back({"rock", 1000.0});
  model.contact_laws.reset(1, ContactLaw{});
  RandomPolyhedronOptions options;
  for (int k = 0; k < 2 * pairs; ++k)
    add_polyhedron_grain(model, generate_random_polyhedron(options, static_cast<std::uint64_t>(k % 256)), 0);
  State state;
  state.resize(model.body_count());
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::normal_distribution<double> normal;
  for (int k = 0; k < pairs; ++k) {
    const auto a = static_cast<std::size_t>(2 * k), b = a + 1;
    state.position[a] = Vec3(10.0 * k, 0, 0);
    state.orientation[a] = random_rotation(rng);
    state.orientation[b] = random_rotation(rng);
    const Vec3 direction = Vec3(normal(rng), normal(rng), normal(rng)).normalized();
    const double target = -0.02 + 0.07 * uniform(rng);
    // Bisection on the centre distance for the target gap.
    double lo = 0.0, hi = 2.0;
    for (int it = 0; it < 60; ++it) {
      const double mid = 0.5 * (lo + hi);
      state.position[b] = state.position[a] + mid * direction;
      const PolyhedronInWorld pa{&model.polyhedra[a], state.position[a], state.orientation[a].toRotationMatrix()};
      const PolyhedronInWorld pb{&model.polyhedra[b], state.position[b], state.orientation[b].toRotationMatrix()};
      (find_common_plane(pa, pb, nullptr, 10.0).gap < target ? lo : hi) = mid;
    }
    state.position[b] = state.position[a] + hi * direction;
  }
  const double alert = 0.05;
  std::vector<Vec3> normals(static_cast<std::size_t>(pairs));
  std::size_t contacts = 0;
  ContactList list;
  PolyhedronScratch scratch;  // one per thread, reused from pair to pair as in detect_contacts
  std::uint64_t hash_cold = 14695981039346656037ull, hash_warm = hash_cold, hash_plane = hash_cold;
  // Cold.
  auto t0 = Clock::now();
  double cpu0 = thread_cpu_seconds();
  int rounds = 0;
  do {
    for (int k = 0; k < pairs; ++k) {
      list.clear();
      collide_polyhedron_polyhedron(model, state, static_cast<std::uint32_t>(2 * k),
                                    static_cast<std::uint32_t>(2 * k + 1), alert, nullptr, list,
                                    normals[static_cast<std::size_t>(k)], scratch);
      contacts += list.size();
      if (rounds == 0) {
        for (const Contact& c : list) hash_contact(hash_cold, c);
        for (int i = 0; i < 3; ++i) hash_bytes(hash_cold, normals[static_cast<std::size_t>(k)][i]);
      }
    }
    ++rounds;
  } while (seconds(t0) < 2.0);
  const double cold = rounds * pairs / (thread_cpu_seconds() - cpu0);
  const double contacts_per_pair = static_cast<double>(contacts) / (rounds * pairs);
  // Warm: a small motion (1e-3 d, 1e-3 rad), then the remembered normal.
  for (int k = 0; k < pairs; ++k) {
    const auto b = static_cast<std::size_t>(2 * k + 1);
    state.position[b] += 1e-3 * Vec3(normal(rng), normal(rng), normal(rng));
    state.orientation[b] =
        (quaternion_exp(1e-3 * Vec3(normal(rng), normal(rng), normal(rng))) * state.orientation[b]).normalized();
  }
  t0 = Clock::now();
  cpu0 = thread_cpu_seconds();
  rounds = 0;
  Vec3 out;
  do {
    for (int k = 0; k < pairs; ++k) {
      list.clear();
      collide_polyhedron_polyhedron(model, state, static_cast<std::uint32_t>(2 * k),
                                    static_cast<std::uint32_t>(2 * k + 1), alert, &normals[static_cast<std::size_t>(k)],
                                    list, out, scratch);
      if (rounds == 0) {
        for (const Contact& c : list) hash_contact(hash_warm, c);
        for (int i = 0; i < 3; ++i) hash_bytes(hash_warm, out[i]);
      }
    }
    ++rounds;
  } while (seconds(t0) < 2.0);
  const double warm = rounds * pairs / (thread_cpu_seconds() - cpu0);
  // Common plane alone (no contact points), cold (no previous normal) and warm.
  double sink = 0.0;
  const auto planes_per_second = [&](bool warm_start) {
    const auto start = Clock::now();
    const double cpu_start = thread_cpu_seconds();
    int loops = 0;
    do {
      for (int k = 0; k < pairs; ++k) {
        const auto a = static_cast<std::size_t>(2 * k), b = a + 1;
        const PolyhedronInWorld pa{&model.polyhedra[a], state.position[a], state.orientation[a].toRotationMatrix()};
        const PolyhedronInWorld pb{&model.polyhedra[b], state.position[b], state.orientation[b].toRotationMatrix()};
        place_pair(pa, pb, scratch.pair);
        const Vec3* previous = warm_start ? &normals[static_cast<std::size_t>(k)] : nullptr;
        const CommonPlane plane = find_common_plane(scratch.pair, previous, alert);
        sink += plane.gap;
        if (loops == 0) {
          for (int i = 0; i < 3; ++i) hash_bytes(hash_plane, plane.normal[i]);
          hash_bytes(hash_plane, plane.gap);
          hash_bytes(hash_plane, plane.complete);
          hash_bytes(hash_plane, plane.source);
        }
      }
      ++loops;
    } while (seconds(start) < 2.0);
    return loops * pairs / (thread_cpu_seconds() - cpu_start);
  };
  const double plane_cold = planes_per_second(false);
  const double plane_warm = planes_per_second(true);
  std::printf("narrow phase, %d pairs near contact (gap in [-0.02, 0.05] d, alert 0.05 d), one thread,\n", pairs);
  std::printf("pairs per CPU second of the thread (CLOCK_THREAD_CPUTIME_ID), each loop run for 2 s of wall time\n");
  std::printf("  collide_polyhedron_polyhedron  cold %.0f pairs/s   warm %.0f pairs/s   (%.2f contact points/pair)\n",
              cold, warm, contacts_per_pair);
  std::printf("  find_common_plane only         cold %.0f pairs/s   warm %.0f pairs/s   (checksum %.3g)\n", plane_cold,
              plane_warm, sink);
  std::printf("  result hashes (first round): contacts+normals cold %016llx warm %016llx, planes %016llx\n",
              static_cast<unsigned long long>(hash_cold), static_cast<unsigned long long>(hash_warm),
              static_cast<unsigned long long>(hash_plane));
  return 0;
}

/// `grains` random polyhedra (d in [7.5, 10] cm uniform, 10-70 vertices) in a grid above a floor,
/// inside 4 side walls, poured under gravity for `steps` steps of 5e-4 s (mu = 0.5, e = 0).
int deposit(int grains, int steps) {
  Model model;
  model.materials.push_back({"rock", 2500.0});
  model.contact_laws.reset(1, ContactLaw{0.5, 0.0});
  const int per_side = static_cast<int>(std::ceil(std::sqrt(grains / 10.0)));
  const double pitch = 0.11;
  const double half = 0.5 * per_side * pitch + 0.02;
  const int floor = add_plane_wall(model, Vec3::UnitZ(), 0);
  std::vector<std::pair<Vec3, int>> walls = {
      {Vec3(-half, 0, 0), 0}, {Vec3(half, 0, 0), 0}, {Vec3(0, -half, 0), 0}, {Vec3(0, half, 0), 0}};
  const Vec3 normals[4] = {Vec3::UnitX(), -Vec3::UnitX(), Vec3::UnitY(), -Vec3::UnitY()};
  std::vector<int> wall_ids;
  for (int k = 0; k < 4; ++k) wall_ids.push_back(add_plane_wall(model, normals[k], 0));
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  RandomPolyhedronOptions options;
  std::vector<int> ids;
  for (int k = 0; k < grains; ++k) {
    options.diameter = 0.075 + 0.025 * uniform(rng);
    ids.push_back(add_polyhedron_grain(model, generate_random_polyhedron(options, static_cast<std::uint64_t>(k)), 0));
  }
  State state;
  state.resize(model.body_count());
  state.position[static_cast<std::size_t>(floor)] = Vec3::Zero();
  for (int k = 0; k < 4; ++k)
    state.position[static_cast<std::size_t>(wall_ids[static_cast<std::size_t>(k)])] =
        walls[static_cast<std::size_t>(k)].first;
  for (int k = 0; k < grains; ++k) {
    const int layer = k / (per_side * per_side), cell = k % (per_side * per_side);
    const auto b = static_cast<std::size_t>(ids[static_cast<std::size_t>(k)]);
    state.position[b] = Vec3((cell % per_side - 0.5 * (per_side - 1)) * pitch,
                             (cell / per_side - 0.5 * (per_side - 1)) * pitch, 0.06 + layer * pitch);
    state.orientation[b] = random_rotation(rng);
  }
  StepOptions step_options;
  step_options.integrator.time_step = 5e-4;
  step_options.gravity.kind = GravitySettings::Kind::uniform;
  step_options.gravity.acceleration = Vec3(0, 0, -9.81);
  step_options.detection.alert_distance = 0.005;
  step_options.solver.tolerance = 1e-4;
  step_options.solver.max_iterations = 1000;
  StepWorkspace workspace;
  std::array<double, static_cast<std::size_t>(Stage::count)> stage{};
  double contacts = 0.0, sweeps = 0.0, max_contacts = 0.0;
  const auto t0 = Clock::now();
  for (int k = 0; k < steps; ++k) {
    const StepReport report = step(model, state, workspace, step_options);
    for (std::size_t s = 0; s < stage.size(); ++s) stage[s] += report.stage_seconds[s];
    contacts += static_cast<double>(report.contacts);
    max_contacts = std::max(max_contacts, static_cast<double>(report.contacts));
    sweeps += report.solver.iterations;
    if ((k + 1) % 500 == 0) {
      std::printf("  step %d: %zu contacts, %d sweeps, %.3f s so far\n", k + 1, report.contacts,
                  report.solver.iterations, seconds(t0));
      std::fflush(stdout);
    }
  }
  const double wall = seconds(t0);
  std::printf("deposit: %d polyhedra, %d steps of 5e-4 s (t = %.2f s), %.2f steps/s\n", grains, steps, state.time,
              steps / wall);
  std::printf("  contacts per step: mean %.0f, max %.0f; NLGS sweeps per step: mean %.1f\n", contacts / steps,
              max_contacts, sweeps / steps);
  std::printf("  time per step by stage (ms):");
  for (std::size_t s = 0; s < stage.size(); ++s) {
    std::printf(" %s %.2f", std::string(stage_name(static_cast<Stage>(s))).c_str(), 1e3 * stage[s] / steps);
  }
  std::printf("\n  final state hash %016llx\n", static_cast<unsigned long long>(state_hash(state)));
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string mode = argc > 1 ? argv[1] : "narrow";
  if (mode == "narrow") return narrow(argc > 2 ? std::atoi(argv[2]) : 2000);
  if (mode == "deposit") return deposit(argc > 2 ? std::atoi(argv[2]) : 2000, argc > 3 ? std::atoi(argv[3]) : 2000);
  std::fprintf(stderr, "usage: bench_polyhedra narrow [pairs] | deposit [grains] [steps]\n");
  return 2;
}
