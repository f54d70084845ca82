// gravity/cuda.hpp on top of the raw CUDA entry points (built only with the CUDA backend).
#include <memory>
#include <stdexcept>
#include <vector>

#include "gravity/cuda.hpp"
#include "gravity/cuda/direct_sum.cuh"
#include "gravity/cuda/tree_walk.cuh"
#include "gravity/tree.hpp"

namespace rubble::gravity::cuda {
namespace {

/// Below this many items the host loops run on one thread (a parallel region costs more).
constexpr std::ptrdiff_t kParallelMin = std::ptrdiff_t{1} << 16;

double softening_length(const GravityOptions& options) {
  return options.softening.kind == Softening::Kind::plummer ? options.softening.length : 0.0;
}

void require_device() {
  std::string reason;
  if (detail::device_count(&reason) == 0) throw BackendUnavailable("CUDA backend: " + reason);
}

/// The tree's nodes as the GPU walk reads them, with this evaluation's opening radii.
std::vector<detail::WalkNode> walk_nodes(const Tree& tree, double theta) {
  const auto& nodes = tree.nodes();
  const auto& moments = tree.second_moments();
  std::vector<detail::WalkNode> out(nodes.size());
  const double inv_theta = 1.0 / theta;
  const auto count = static_cast<std::ptrdiff_t>(nodes.size());
#pragma omp parallel for schedule(static) if (count >= kParallelMin)
  for (std::ptrdiff_t si = 0; si < count; ++si) {
    const auto i = static_cast<std::size_t>(si);
    const Tree::Node& nd = nodes[i];
    detail::WalkNode& w = out[i];
    w.cx = nd.cx, w.cy = nd.cy, w.cz = nd.cz;
    w.mass = nd.mass;
    w.r_open2 = Tree::opening_radius2(nd, inv_theta);
    for (int k = 0; k < 6; ++k) w.q[k] = moments[i][static_cast<std::size_t>(k)];
    w.begin = nd.begin, w.count = nd.count;
    w.first_child = nd.first_child, w.num_children = nd.num_children;
  }
  return out;
}

std::vector<detail::WalkGroup> walk_groups(const Tree& tree) {
  std::vector<detail::WalkGroup> out;
  out.reserve(tree.groups().size());
  for (const Tree::Group& g : tree.groups())
    out.push_back({{g.lo[0], g.lo[1], g.lo[2]}, {g.hi[0], g.hi[1], g.hi[2]}, g.begin, g.count});
  return out;
}

}  // namespace

bool compiled() { return true; }

int device_count() { return detail::device_count(nullptr); }

bool available() { return device_count() > 0; }

std::string unavailable_reason() {
  std::string reason;
  return detail::device_count(&reason) > 0 ? std::string() : reason;
}

void direct_sum(const GravityOptions& options, std::span<const double> positions, std::span<const double> masses,
                std::span<double> accelerations, std::span<double> potential) {
  GravityOptions o = options;
  o.method = Method::direct;
  validate(o, positions, masses, accelerations, potential);
  require_device();
  const double eps = softening_length(options);
  try {
    detail::direct_sum(positions.data(), masses.data(), masses.size(), eps * eps, options.G, accelerations.data(),
                       potential.empty() ? nullptr : potential.data());
  } catch (const std::runtime_error& e) {
    throw GravityError(e.what());
  }
}

FieldTimings tree_field(const GravityOptions& options, std::span<const double> positions,
                        std::span<const double> masses, std::span<double> accelerations, std::span<double> potential) {
  GravityOptions o = options;
  o.method = Method::tree;
  validate(o, positions, masses, accelerations, potential);
  if (options.precision != KernelPrecision::double_precision)
    throw BackendUnavailable(
        "CUDA backend: the GPU tree computes in double precision only (precision single is a "
        "CPU option)");
  require_device();
  FieldTimings timings;
  Tree tree(options.leaf_size, options.group_size);
  timings.build_seconds = tree.build(positions, masses);
  const std::size_t n = masses.size();
  if (n == 0) return timings;
  const std::vector<detail::WalkNode> nodes = walk_nodes(tree, options.theta);
  const std::vector<detail::WalkGroup> groups = walk_groups(tree);
  const Tree::SortedParticles p = tree.sorted_particles();
  const double eps = softening_length(options);
  detail::TreeWalkInput input;
  input.num_particles = n;
  input.x = p.x.data(), input.y = p.y.data(), input.z = p.z.data(), input.m = p.m.data();
  input.num_nodes = nodes.size(), input.nodes = nodes.data();
  input.num_groups = groups.size(), input.groups = groups.data();
  input.quadrupole = options.order == 2;
  input.eps2 = eps * eps;
  input.G = options.G;
  // Not value-initialised: every entry is written by the GPU (10^7 particles: 0.3 s of zeroing).
  const std::unique_ptr<double[]> acc_sorted(new double[3 * n]);
  const std::unique_ptr<double[]> pot_sorted(potential.empty() ? nullptr : new double[n]);
  detail::TreeWalkTimings walk;
  try {
    detail::tree_walk(input, acc_sorted.get(), pot_sorted.get(), &walk);
  } catch (const std::runtime_error& e) {
    throw GravityError(e.what());
  }
  // Back from Morton order to the caller's.
  const auto& order = tree.order();
  const auto sn = static_cast<std::ptrdiff_t>(n);
#pragma omp parallel for schedule(static) if (sn >= kParallelMin)
  for (std::ptrdiff_t sk = 0; sk < sn; ++sk) {
    const auto k = static_cast<std::size_t>(sk);
    const std::size_t i = order[k];
    for (std::size_t c = 0; c < 3; ++c) accelerations[3 * i + c] = acc_sorted[3 * k + c];
    if (!potential.empty()) potential[i] = pot_sorted[k];
  }
  timings.walk_seconds = walk.kernel_seconds;
  timings.transfer_seconds = walk.upload_seconds + walk.download_seconds;
  return timings;
}

}  // namespace rubble::gravity::cuda
