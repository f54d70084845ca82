// Timed benchmark of rubble::gravity (plain executable, prints a Markdown table and a CSV).
//
//   bench_gravity [--n 1000,10000,100000,1000000] [--theta 0.3,0.5,0.7,1.0] [--order 1,2]
//                 [--threads 1,2] [--reps 3] [--dist uniform|plummer] [--subset 1000]
//                 [--csv FILE] [--direct-rate] [--leaf-size 16] [--group-size 64]
//                 [--precision double,single] [--backend cpu,cuda] [--write-reference DIR]
//                 [--fresh-workspace]
//
// Each tree figure is the best of --reps evaluations (tree build included), as wall-clock seconds
// and as process CPU seconds (all threads; on a loaded machine the latter measures the work). Errors are the
// per-particle |a_tree - a_direct| / |a_direct| against the exact direct sum over all targets
// (N <= 100000) or over --subset random targets (larger N).
//
// The reps of a row share one gravity::FieldWorkspace, as a run's steps do: the best of 2 or more
// reps is a call that reuses the tree's memory. --fresh-workspace gives every rep a new one (a
// caller that keeps none: every call faults in the tree's pages).
//
// --write-reference DIR: for each N, DIR/DIST-N.bin holds the particles, the error targets and the
// exact direct-sum accelerations on them (layout in write_reference), so that another code's tree
// can be timed and judged on the same set (bench/gravity/compare_pytreegrav.py).
//
// --backend cuda: the tree built and walked on the GPU (--threads sets the host's OpenMP threads,
// which only check the input); its seconds include the copies ("copies s": the particles to the GPU
// and the field back; "build s" and "walk s" the GPU's build and walk). With
// --direct-rate, the GPU direct sum's pair rate (the first call, which creates the CUDA context, is
// not timed: every figure is the best of --reps after one warm-up).

#include <omp.h>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#endif

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <fstream>
#include <numeric>
#include <random>
#include <sstream>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "gravity/direct_sum.hpp"
#include "gravity/gravity.hpp"
#include "gravity/tree.hpp"

namespace g = rubble::gravity;

namespace {

std::vector<double> parse_list(const std::string& s) {
  std::vector<double> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) out.push_back(std::stod(item));
  return out;
}

/// Uniform sphere of radius 1 and total mass 1, or a Plummer sphere (scale radius 1, truncated at
/// 20 scale radii) sampled by inverting its cumulative mass M(r) = r^3 / (1 + r^2)^{3/2}.
void make_particles(const std::string& dist, std::size_t n, std::uint64_t seed, std::vector<double>& pos,
                    std::vector<double>& mass) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  pos.resize(3 * n);
  mass.assign(n, 1.0 / static_cast<double>(n));
  for (std::size_t i = 0; i < n; ++i) {
    double r;
    if (dist == "plummer") {
      do {
        const double x = u(rng);
        r = 1.0 / std::sqrt(std::pow(x, -2.0 / 3.0) - 1.0);
      } while (!(r < 20.0));
    } else {
      r = std::cbrt(u(rng));
    }
    const double cz = 2.0 * u(rng) - 1.0, ph = 2.0 * M_PI * u(rng);
    const double sz = std::sqrt(1.0 - cz * cz);
    pos[3 * i] = r * sz * std::cos(ph);
    pos[3 * i + 1] = r * sz * std::sin(ph);
    pos[3 * i + 2] = r * cz;
  }
}

/// Process CPU time (all threads): on a shared machine it measures the work, not the waiting.
double cpu_now() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

double now() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }

double percentile(std::vector<double> v, double p) {
  std::sort(v.begin(), v.end());
  const auto k = static_cast<std::size_t>(
      std::clamp(p * static_cast<double>(v.size() - 1), 0.0, static_cast<double>(v.size() - 1)));
  return v[k];
}

/// "a,b" -> the values that `names` gives those words, in that order; exits with code 2 on a word
/// not in names (option: the option's name, for the message).
template <typename T>
std::vector<T> parse_choices(const std::string& text, const char* option,
                             const std::vector<std::pair<std::string, T>>& names) {
  std::vector<T> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    const auto it = std::find_if(names.begin(), names.end(), [&](const auto& n) { return n.first == item; });
    if (it == names.end()) {
      std::fprintf(stderr, "%s: expected %s or %s, got '%s'\n", option, names.front().first.c_str(),
                   names.back().first.c_str(), item.c_str());
      std::exit(2);
    }
    out.push_back(it->second);
  }
  return out;
}

}  // namespace

/// The command line's settings (see the usage at the top of this file).
struct Arguments {
  std::vector<double> ns{1e3, 1e4, 1e5, 1e6}, thetas{0.3, 0.5, 0.7, 1.0}, orders{1, 2}, threads{1, 2};
  int reps = 3, leaf_size = g::GravityOptions{}.leaf_size, group_size = g::GravityOptions{}.group_size;
  std::size_t subset = 1000;
  std::string dist = "uniform", csv_path, reference_dir;
  bool direct_rate = false;
  bool fresh_workspace = false;
  std::vector<g::KernelPrecision> precisions{g::KernelPrecision::double_precision};
  std::vector<g::Backend> backends{g::Backend::cpu};
};

/// Reads the command line; exits with code 2 on an unknown argument or a missing value.
Arguments parse_arguments(int argc, char** argv) {
  Arguments args;
  for (int a = 1; a < argc; ++a) {
    const std::string arg = argv[a];
    auto next = [&]() -> std::string {
      if (a + 1 >= argc) {
        std::fprintf(stderr, "missing value after %s\n", arg.c_str());
        std::exit(2);
      }
      return argv[++a];
    };
    if (arg == "--n")
      args.ns = parse_list(next());
    else if (arg == "--theta")
      args.thetas = parse_list(next());
    else if (arg == "--order")
      args.orders = parse_list(next());
    else if (arg == "--threads")
      args.threads = parse_list(next());
    else if (arg == "--reps")
      args.reps = std::stoi(next());
    else if (arg == "--leaf-size")
      args.leaf_size = std::stoi(next());
    else if (arg == "--group-size")
      args.group_size = std::stoi(next());
    else if (arg == "--subset")
      args.subset = std::stoul(next());
    else if (arg == "--dist")
      args.dist = next();
    else if (arg == "--csv")
      args.csv_path = next();
    else if (arg == "--write-reference")
      args.reference_dir = next();
    else if (arg == "--fresh-workspace")
      args.fresh_workspace = true;
    else if (arg == "--direct-rate")
      args.direct_rate = true;
    else if (arg == "--precision")
      args.precisions = parse_choices<g::KernelPrecision>(
          next(), "--precision",
          {{"double", g::KernelPrecision::double_precision}, {"single", g::KernelPrecision::single_precision}});
    else if (arg == "--backend")
      args.backends =
          parse_choices<g::Backend>(next(), "--backend", {{"cpu", g::Backend::cpu}, {"cuda", g::Backend::cuda}});
    else {
      std::fprintf(stderr, "unknown argument %s\n", arg.c_str());
      std::exit(2);
    }
  }
  return args;
}

/// Writes `path`: the 8 bytes "RUBGRAV1", then N and K as uint64, the positions (3N doubles, x y z
/// per particle), the masses (N), the K target indices (uint64) and the exact accelerations on them
/// (3K, G = 1), all in the machine's byte order (little-endian on x86-64, which the comparison
/// script assumes). Exits with code 1 if the file cannot be written.
void write_reference(const std::string& path, const std::vector<double>& pos, const std::vector<double>& mass,
                     const std::vector<std::size_t>& targets, const std::vector<double>& aref) {
  std::ofstream out(path, std::ios::binary);
  const std::uint64_t n = mass.size(), k = targets.size();
  const std::vector<std::uint64_t> indices(targets.begin(), targets.end());
  out.write("RUBGRAV1", 8);
  out.write(reinterpret_cast<const char*>(&n), sizeof n);
  out.write(reinterpret_cast<const char*>(&k), sizeof k);
  out.write(reinterpret_cast<const char*>(pos.data()), static_cast<std::streamsize>(pos.size() * sizeof(double)));
  out.write(reinterpret_cast<const char*>(mass.data()), static_cast<std::streamsize>(mass.size() * sizeof(double)));
  out.write(reinterpret_cast<const char*>(indices.data()),
            static_cast<std::streamsize>(indices.size() * sizeof(std::uint64_t)));
  out.write(reinterpret_cast<const char*>(aref.data()), static_cast<std::streamsize>(aref.size() * sizeof(double)));
  if (!out) {
    std::fprintf(stderr, "--write-reference: cannot write %s\n", path.c_str());
    std::exit(1);
  }
}

/// |a[i] - a_ref[k]| / |a_ref[k]| for each target i = targets[k].
std::vector<double> relative_errors(const std::vector<double>& acc, const std::vector<double>& aref,
                                    const std::vector<std::size_t>& targets) {
  std::vector<double> err(targets.size());
  for (std::size_t k = 0; k < targets.size(); ++k) {
    const std::size_t i = targets[k];
    double d2 = 0, a2 = 0;
    for (int c = 0; c < 3; ++c) {
      d2 += std::pow(acc[3 * i + c] - aref[3 * k + c], 2);
      a2 += aref[3 * k + c] * aref[3 * k + c];
    }
    err[k] = std::sqrt(d2 / a2);
  }
  return err;
}

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
/// Twelve independent chains of 512-bit FMAs (four cycles of latency, two pipes: eight in flight
/// keep both busy), `iterations` times: the core's FMA issue rate, measured rather than taken from
/// a datasheet (a virtual machine's clock is not the nominal one).
__attribute__((target("avx512f"), noinline)) double fma_chains(long iterations) {
  __m512d a0 = _mm512_set1_pd(1.00), a1 = _mm512_set1_pd(1.01), a2 = _mm512_set1_pd(1.02), a3 = _mm512_set1_pd(1.03),
          a4 = _mm512_set1_pd(1.04), a5 = _mm512_set1_pd(1.05), a6 = _mm512_set1_pd(1.06), a7 = _mm512_set1_pd(1.07),
          a8 = _mm512_set1_pd(1.08), a9 = _mm512_set1_pd(1.09), a10 = _mm512_set1_pd(1.10), a11 = _mm512_set1_pd(1.11);
  const __m512d b = _mm512_set1_pd(0.999999), c = _mm512_set1_pd(1e-7);
  for (long i = 0; i < iterations; ++i) {
    a0 = _mm512_fmadd_pd(a0, b, c), a1 = _mm512_fmadd_pd(a1, b, c), a2 = _mm512_fmadd_pd(a2, b, c);
    a3 = _mm512_fmadd_pd(a3, b, c), a4 = _mm512_fmadd_pd(a4, b, c), a5 = _mm512_fmadd_pd(a5, b, c);
    a6 = _mm512_fmadd_pd(a6, b, c), a7 = _mm512_fmadd_pd(a7, b, c), a8 = _mm512_fmadd_pd(a8, b, c);
    a9 = _mm512_fmadd_pd(a9, b, c), a10 = _mm512_fmadd_pd(a10, b, c), a11 = _mm512_fmadd_pd(a11, b, c);
  }
  const __m512d sum = _mm512_add_pd(_mm512_add_pd(_mm512_add_pd(_mm512_add_pd(a0, a1), _mm512_add_pd(a2, a3)),
                                                  _mm512_add_pd(_mm512_add_pd(a4, a5), _mm512_add_pd(a6, a7))),
                                    _mm512_add_pd(_mm512_add_pd(a8, a9), _mm512_add_pd(a10, a11)));
  alignas(64) double lanes[8];
  _mm512_store_pd(lanes, sum);
  return lanes[0];
}

/// 512-bit FMA instructions per CPU second of one thread (best of 3), or 0 without AVX-512.
double fma_rate() {
  if (!__builtin_cpu_supports("avx512f")) return 0.0;
  constexpr long iterations = 50'000'000;
  double best = 1e300, sink = 0.0;
  for (int r = 0; r < 3; ++r) {
    const double c0 = cpu_now();
    sink += fma_chains(iterations);
    best = std::min(best, cpu_now() - c0);
  }
  if (!std::isfinite(sink)) return 0.0;
  return 12.0 * static_cast<double>(iterations) / best;
}
#else
double fma_rate() { return 0.0; }
#endif

/// --direct-rate: pair interactions per second of the exact direct sum, per backend and thread count.
void run_direct_rate(const Arguments& args) {
  const auto& [ns, threads, reps, dist, backends] =
      std::tie(args.ns, args.threads, args.reps, args.dist, args.backends);
  std::printf(
      "| N | backend | threads | seconds | CPU seconds | pair interactions / s | per core (wall) | per CPU second "
      "| of the FMA bound |\n|---|---|---|---|---|---|---|---|---|\n");
  // The CPU kernel issues 16 multiply/FMA instructions per 8 pairs (kernels.cpp): at the core's
  // measured FMA rate F it cannot exceed F / 2 pairs per CPU second.
  const double pair_bound = fma_rate() / 2.0;
  for (double nd : ns) {
    const auto n = static_cast<std::size_t>(nd);
    std::vector<double> pos, mass, acc(3 * n), pot(n);
    make_particles(dist, n, 42, pos, mass);
    for (g::Backend backend : backends) {
      g::GravityOptions o;
      o.method = g::Method::direct;
      o.backend = backend;
      o.G = 1.0;
      if (backend == g::Backend::cuda) g::compute_field(o, pos, mass, acc, pot);  // warm-up: CUDA context
      // The GPU does not use the host's threads: one row.
      const std::vector<double> thread_counts = backend == g::Backend::cuda ? std::vector<double>{1} : threads;
      for (double t : thread_counts) {
        omp_set_num_threads(static_cast<int>(t));
        double best = 1e300, best_cpu = 1e300;
        for (int r = 0; r < reps; ++r) {
          const double t0 = now(), c0 = cpu_now();
          g::compute_field(o, pos, mass, acc, pot);
          best = std::min(best, now() - t0);
          best_cpu = std::min(best_cpu, cpu_now() - c0);
        }
        const double pairs = static_cast<double>(n) * static_cast<double>(n - 1);
        const std::string of_bound =
            backend == g::Backend::cpu && pair_bound > 0.0
                ? std::to_string(static_cast<int>(std::lround(100.0 * pairs / best_cpu / pair_bound))) + " %"
                : "-";
        std::printf("| %zu | %s | %d | %.4g | %.4g | %.3g | %.3g | %.3g | %s |\n", n, g::to_string(backend).c_str(),
                    static_cast<int>(t), best, best_cpu, pairs / best, pairs / best / t, pairs / best_cpu,
                    of_bound.c_str());
        std::fflush(stdout);
      }
    }
  }
}

/// One tree row: the best of reps evaluations of options o, with errors against aref.
void run_tree_row(const Arguments& args, const g::GravityOptions& o, int threads, const std::vector<double>& pos,
                  const std::vector<double>& mass, const std::vector<std::size_t>& targets,
                  const std::vector<double>& aref, std::ofstream& csv) {
  const std::size_t n = mass.size();
  std::vector<double> acc(3 * n), pot(n);
  omp_set_num_threads(threads);
  if (o.backend == g::Backend::cuda) g::compute_field(o, pos, mass, acc, pot);  // warm-up: CUDA context
  double best = 1e300, bb = 0, bw = 0, bt = 0, best_cpu = 1e300;
  // One workspace for the reps, as a run keeps one from step to step: the first rep faults in the
  // tree's memory, the others reuse it (the best of reps is a warm one when reps >= 2).
  g::FieldWorkspace workspace;
  for (int r = 0; r < args.reps; ++r) {
    if (args.fresh_workspace) workspace = g::FieldWorkspace{};
    const double t0 = now(), c0 = cpu_now();
    const g::FieldTimings ft = g::compute_field(o, pos, mass, acc, pot, workspace);
    const double dt = now() - t0;
    best_cpu = std::min(best_cpu, cpu_now() - c0);
    if (dt < best) best = dt, bb = ft.build_seconds, bw = ft.walk_seconds, bt = ft.transfer_seconds;
  }
  std::vector<double> err = relative_errors(acc, aref, targets);
  const double med = percentile(err, 0.5), p99 = percentile(err, 0.99), mx = *std::max_element(err.begin(), err.end());
  const std::string precision = g::to_string(o.precision), backend = g::to_string(o.backend);
  std::printf("| %s | %zu | %.2g | %d | %s | %s | %d | %.4g | %.4g | %.3g | %.3g | %.3g | %.2e | %.2e | %.2e |\n",
              args.dist.c_str(), n, o.theta, o.order, precision.c_str(), backend.c_str(), threads, best, best_cpu, bb,
              bw, bt, med, p99, mx);
  std::fflush(stdout);
  if (csv.is_open())
    csv << args.dist << ',' << n << ',' << o.theta << ',' << o.order << ',' << threads << ',' << best << ',' << best_cpu
        << ',' << bb << ',' << bw << ',' << med << ',' << p99 << ',' << mx << ',' << precision << ',' << backend << ','
        << bt << '\n';
}

int main(int argc, char** argv) {
  const Arguments args = parse_arguments(argc, argv);
  std::ofstream csv;
  if (!args.csv_path.empty()) {
    csv.open(args.csv_path);
    csv << "dist,n,theta,order,threads,seconds,cpu_seconds,build_seconds,walk_seconds,median,p99,max,precision,"
           "backend,transfer_seconds\n";
  }
  const int max_threads = static_cast<int>(*std::max_element(args.threads.begin(), args.threads.end()));

  if (args.direct_rate) {
    run_direct_rate(args);
    return 0;
  }

  std::printf(
      "| dist | N | θ | order | precision | backend | threads | s/eval (best of %d) | CPU s/eval | build s | walk s | "
      "copies s | median | p99 | max |\n",
      args.reps);
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (double nd : args.ns) {
    const auto n = static_cast<std::size_t>(nd);
    std::vector<double> pos, mass;
    make_particles(args.dist, n, 42, pos, mass);
    // Exact reference on all targets, or on a random subset for large N.
    std::vector<std::size_t> targets(n);
    std::iota(targets.begin(), targets.end(), std::size_t{0});
    if (n > 100000) {
      std::mt19937_64 rng(7);
      std::shuffle(targets.begin(), targets.end(), rng);
      targets.resize(std::min(args.subset, n));
    }
    g::GravityOptions ref;
    ref.method = g::Method::direct;
    ref.G = 1.0;
    std::vector<double> aref(3 * targets.size());
    omp_set_num_threads(max_threads);
    g::direct_sum_targets(ref, pos, mass, targets, aref, {});
    if (!args.reference_dir.empty()) {
      write_reference(args.reference_dir + "/" + args.dist + "-" + std::to_string(n) + ".bin", pos, mass, targets,
                      aref);
    }
    for (double order : args.orders)
      for (double theta : args.thetas)
        for (g::KernelPrecision precision : args.precisions)
          for (g::Backend backend : args.backends) {
            g::GravityOptions o;
            o.precision = precision;
            o.backend = backend;
            o.method = g::Method::tree;
            o.G = 1.0;
            o.theta = theta;
            o.order = static_cast<int>(order);
            o.leaf_size = args.leaf_size;
            o.group_size = args.group_size;
            if (const std::string why = g::backend_unavailable_reason(o); !why.empty()) {
              std::fprintf(stderr, "skipped: backend %s, precision %s: %s\n", g::to_string(backend).c_str(),
                           g::to_string(precision).c_str(), why.c_str());
              continue;
            }
            for (double t : args.threads) run_tree_row(args, o, static_cast<int>(t), pos, mass, targets, aref, csv);
          }
  }
  return 0;
}
