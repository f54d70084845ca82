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

/// Pairs of random polyhedra (d = 1, 10-70 vertices), pair k = bodies (2k, 2k+1), at poses near
/// contact: B is moved along a random direction until the common-plane gap is uniform in
/// [-0.02, 0.05] d (the pairs a broad phase passes on in a dense pack).
struct PairsNearContact {
  Model model;  ///< the polyhedra
  State state;  ///< their poses
};

PairsNearContact pairs_near_contact(int pairs, std::mt19937_64& rng) {
  PairsNearContact out;
  Model& model = out.model;
  State& state = out.state;
  model.materials.push_back({"rock", 1000.0});
  model.contact_laws.reset(1, ContactLaw{});
  RandomPolyhedronOptions options;
  for (int k = 0; k < 2 * pairs; ++k)
    add_polyhedron_grain(model, generate_random_polyhedron(options, static_cast<std::uint64_t>(k % 256)), 0);
  state.resize(model.body_count());
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::normal_distribution<double> normal;
  for (int k = 0; k < pairs; ++k) {
    const std::size_t a = 2 * static_cast<std::size_t>(k), b = a + 1;
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
  return out;
}

/// What one timed loop over the pairs measured.
struct PairRate {
  double pairs_per_second = 0.0;                 ///< per CPU second of the thread
  double contacts_per_pair = 0.0;                ///< contact points found (collide loops only)
  std::uint64_t hash = 14695981039346656037ull;  ///< of the first round's results
};

/// collide_polyhedron_polyhedron over every pair for 2 s of wall time: cold (normal from the line
/// of centres; the common normals are written to `normals`) or warm (from `normals`).
PairRate collide_rate(const PairsNearContact& p, int pairs, double alert, bool warm, std::vector<Vec3>& normals,
                      PolyhedronScratch& scratch) {
  PairRate rate;
  ContactList list;
  std::size_t contacts = 0;
  Vec3 out;
  const auto start = Clock::now();
  const double cpu_start = thread_cpu_seconds();
  int rounds = 0;
  do {
    for (int k = 0; k < pairs; ++k) {
      list.clear();
      Vec3& normal = warm ? out : normals[static_cast<std::size_t>(k)];
      collide_polyhedron_polyhedron(p.model, p.state, static_cast<std::uint32_t>(2 * k),
                                    static_cast<std::uint32_t>(2 * k + 1), alert,
                                    warm ? &normals[static_cast<std::size_t>(k)] : nullptr, list, normal, scratch);
      contacts += list.size();
      if (rounds == 0) {
        for (const Contact& c : list) hash_contact(rate.hash, c);
        for (int i = 0; i < 3; ++i) hash_bytes(rate.hash, normal[i]);
      }
    }
    ++rounds;
  } while (seconds(start) < 2.0);
  rate.pairs_per_second = rounds * pairs / (thread_cpu_seconds() - cpu_start);
  rate.contacts_per_pair = static_cast<double>(contacts) / (rounds * pairs);
  return rate;
}

/// find_common_plane alone (no contact points) over every pair for 2 s of wall time, cold or warm
/// (from `normals`), its hash going on from `hash`; adds the gaps to `sink` so that the work is not
/// optimised away.
PairRate plane_rate(const PairsNearContact& p, int pairs, double alert, bool warm, const std::vector<Vec3>& normals,
                    PolyhedronScratch& scratch, std::uint64_t hash, double& sink) {
  PairRate rate;
  rate.hash = hash;
  const auto start = Clock::now();
  const double cpu_start = thread_cpu_seconds();
  int rounds = 0;
  do {
    for (int k = 0; k < pairs; ++k) {
      const std::size_t a = 2 * static_cast<std::size_t>(k), b = a + 1;
      const PolyhedronInWorld pa{&p.model.polyhedra[a], p.state.position[a], p.state.orientation[a].toRotationMatrix()};
      const PolyhedronInWorld pb{&p.model.polyhedra[b], p.state.position[b], p.state.orientation[b].toRotationMatrix()};
      place_pair(pa, pb, scratch.pair);
      const Vec3* previous = warm ? &normals[static_cast<std::size_t>(k)] : nullptr;
      const CommonPlane plane = find_common_plane(scratch.pair, previous, alert);
      sink += plane.gap;
      if (rounds == 0) {
        for (int i = 0; i < 3; ++i) hash_bytes(rate.hash, plane.normal[i]);
        hash_bytes(rate.hash, plane.gap);
        hash_bytes(rate.hash, plane.complete);
        hash_bytes(rate.hash, plane.source);
      }
    }
    ++rounds;
  } while (seconds(start) < 2.0);
  rate.pairs_per_second = rounds * pairs / (thread_cpu_seconds() - cpu_start);
  return rate;
}

/// Throughput of collide_polyhedron_polyhedron and of find_common_plane alone on pairs near
/// contact, cold (normal from the line of centres) and warm (last step's normal after a small
/// motion), with hashes of the results.
int narrow(int pairs) {
  std::mt19937_64 rng(3);
  PairsNearContact p = pairs_near_contact(pairs, rng);
  const double alert = 0.05;
  std::vector<Vec3> normals(static_cast<std::size_t>(pairs));
  PolyhedronScratch scratch;  // one per thread, reused from pair to pair as in detect_contacts
  const PairRate cold = collide_rate(p, pairs, alert, false, normals, scratch);
  // Warm: a small motion (1e-3 d, 1e-3 rad), then the remembered normal.
  std::normal_distribution<double> normal;
  for (int k = 0; k < pairs; ++k) {
    const std::size_t b = 2 * static_cast<std::size_t>(k) + 1;
    p.state.position[b] += 1e-3 * Vec3(normal(rng), normal(rng), normal(rng));
    p.state.orientation[b] =
        (quaternion_exp(1e-3 * Vec3(normal(rng), normal(rng), normal(rng))) * p.state.orientation[b]).normalized();
  }
  const PairRate warm = collide_rate(p, pairs, alert, true, normals, scratch);
  double sink = 0.0;
  // One hash over both plane loops, cold then warm.
  const PairRate plane_cold = plane_rate(p, pairs, alert, false, normals, scratch, PairRate{}.hash, sink);
  const PairRate plane_warm = plane_rate(p, pairs, alert, true, normals, scratch, plane_cold.hash, sink);
  std::printf("narrow phase, %d pairs near contact (gap in [-0.02, 0.05] d, alert 0.05 d), one thread,\n", pairs);
  std::printf("pairs per CPU second of the thread (CLOCK_THREAD_CPUTIME_ID), each loop run for 2 s of wall time\n");
  std::printf("  collide_polyhedron_polyhedron  cold %.0f pairs/s   warm %.0f pairs/s   (%.2f contact points/pair)\n",
              cold.pairs_per_second, warm.pairs_per_second, cold.contacts_per_pair);
  std::printf("  find_common_plane only         cold %.0f pairs/s   warm %.0f pairs/s   (checksum %.3g)\n",
              plane_cold.pairs_per_second, plane_warm.pairs_per_second, sink);
  std::printf("  result hashes (first round): contacts+normals cold %016llx warm %016llx, planes %016llx\n",
              static_cast<unsigned long long>(cold.hash), static_cast<unsigned long long>(warm.hash),
              static_cast<unsigned long long>(plane_warm.hash));
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
  wall_ids.reserve(4);
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
    const int column = cell % per_side, row = cell / per_side;  // of the grid cell
    state.position[b] =
        Vec3((column - 0.5 * (per_side - 1)) * pitch, (row - 0.5 * (per_side - 1)) * pitch, 0.06 + layer * pitch);
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
