#pragma once
// rubble::gravity — Newtonian self-gravity of N point masses (standalone library).
//
// Entry point: compute_field(). It depends on nothing else in rubble, so other codes (and a later
// Python module) can call it. Units: whatever G says; SI by default (G = 6.674e-11 m^3 kg^-1 s^-2).
//
//   a_i   = -G * sum_{j != i} m_j (x_i - x_j) / (|x_i - x_j|^2 + eps^2)^{3/2}
//   phi_i = -G * sum_{j != i} m_j / (|x_i - x_j|^2 + eps^2)^{1/2}
//
// eps = 0 unless Plummer softening is requested. See gravity/README.md for the tree algorithm.

#include <memory>
#include <span>
#include <stdexcept>
#include <string>

namespace rubble::gravity {

/// Which evaluator computes the field.
enum class Method {
  direct,  ///< exact O(N^2) pairwise sum
  tree     ///< Barnes-Hut octree with monopole or quadrupole moments, O(N log N)
};

/// Where the field is computed.
enum class Backend {
  cpu,  ///< this library's OpenMP code (always available)
  cuda  ///< an NVIDIA GPU through the CUDA backend (gravity/cuda/): only when the library was built
        ///< with it and a GPU is present; the direct sum, and the tree (built and walked on the
        ///< GPU, double precision only)
};

/// Arithmetic of the tree's interaction kernels.
enum class KernelPrecision {
  double_precision,  ///< double throughout (the default)
  single_precision   ///< the tree's particle and multipole kernels in float: sources and targets as
                     ///< offsets from their group's centre, scaled so that no value leaves float's
                     ///< range; each term within a relative ~1e-6 of the double one (far below the
                     ///< tree's own error, >= 1e-5 at theta >= 0.3), twice the SIMD lanes
};

/// Softening of the 1/r potential at short range.
struct Softening {
  /// none: exact Newtonian 1/r. plummer: 1/sqrt(r^2 + length^2) (Plummer 1911; Aarseth 1963).
  enum class Kind { none, plummer } kind = Kind::none;
  /// Plummer length eps [m]; ignored when kind == none. Must be >= 0.
  double length = 0.0;
};

/// Everything compute_field() needs besides the particles.
struct GravityOptions {
  /// Evaluator to use.
  Method method = Method::tree;
  /// Where to compute it. Backend::cuda throws BackendUnavailable where it cannot run (see
  /// backend_unavailable_reason()); there is no silent fallback to the CPU.
  Backend backend = Backend::cpu;
  /// Gravitational constant [m^3 kg^-1 s^-2]; any unit system is used through G.
  double G = 6.674e-11;
  /// Opening angle of the tree: a node is used as a multipole for a group of targets when the
  /// distance from its centre of mass to the group's bounding box exceeds max(l/theta + delta,
  /// b_max) (l: longest side of the node's box, delta: offset of the centre of mass from the box
  /// centre, b_max: farthest particle from the centre of mass). Must be > 0. Ignored by direct.
  double theta = 0.5;
  /// Multipole order of the tree: 1 = monopole, 2 = quadrupole. Ignored by Method::direct.
  int order = 2;
  /// Short-range softening (both methods).
  Softening softening{};
  /// Maximum number of particles in a tree leaf (>= 1). Ignored by Method::direct.
  int leaf_size = 16;
  /// Maximum number of targets that walk the tree together (share one interaction list); >= 1.
  int group_size = 64;
  /// Arithmetic of the tree's kernels. Ignored by Method::direct, which stays exact.
  KernelPrecision precision = KernelPrecision::double_precision;
};

/// Wall-clock seconds spent in the phases of an evaluation (direct sum: walk only).
struct FieldTimings {
  /// Tree construction: Morton keys, sort, nodes, moments (and groups).
  double build_seconds = 0;
  /// Field evaluation (tree walk + interaction kernels, or the direct sum).
  double walk_seconds = 0;
  /// Backend::cuda tree: the copies of the particles to the GPU and of the field back (not in the
  /// other two). 0 on the CPU.
  double transfer_seconds = 0;
};

/// Thrown for invalid arguments (sizes, theta <= 0, order not in {1, 2}, ...).
class GravityError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

/// Thrown when the requested backend cannot run here: the library was built without it, no GPU is
/// present, or the method has no implementation on that backend. what() says which.
class BackendUnavailable : public GravityError {
 public:
  using GravityError::GravityError;
};

/// Why options.backend cannot compute options.method here; empty when it can. Backend::cpu always
/// can. Cheap enough to call before a run (it asks the CUDA driver for its devices once per call).
std::string backend_unavailable_reason(const GravityOptions& options);

/// Throws BackendUnavailable("backend cuda: <reason>") when backend_unavailable_reason() is not empty.
void require_backend(const GravityOptions& options);

/// Checks options and array sizes; throws GravityError with a message naming the problem.
/// positions: 3N values, masses: N values, accelerations: 3N values, potential: N values or empty.
void validate(const GravityOptions& options, std::span<const double> positions, std::span<const double> masses,
              std::span<const double> accelerations, std::span<const double> potential);

/// Checks options and the particle arrays only (positions 3N finite, masses N finite and >= 0).
void validate_particles(const GravityOptions& options, std::span<const double> positions,
                        std::span<const double> masses);

/// Computes the gravitational acceleration (and optionally the potential) of every particle due to
/// all others. positions: N*3 contiguous (x0,y0,z0,x1,...), masses: N. Writes accelerations (N*3)
/// and potential (N; pass an empty span to skip it). Self-interaction is excluded. Results are
/// bit-identical for any number of OpenMP threads. Throws GravityError on invalid input and
/// BackendUnavailable (a GravityError) when options.backend cannot run here.
FieldTimings compute_field(const GravityOptions& options, std::span<const double> positions,
                           std::span<const double> masses, std::span<double> accelerations,
                           std::span<double> potential);

class Tree;

/// Memory that compute_field keeps from one call to the next: the tree, its arrays and the scratch
/// of its build and walk. A run that evaluates the field every step passes the same workspace to
/// every call, and no call after the first asks the system for fresh pages: each new page is
/// zeroed on first touch (~10 us in a virtual machine), about 2 000 of them (~85 bytes a particle)
/// per evaluation at N = 10^5 otherwise, i.e. 20-25 ms against a 55-95 ms evaluation
/// (bench/RESULTS.md, "Gravity: the tree's memory kept from call to call"). It changes no result.
/// Scratch, not state: a copy starts empty. One workspace serves one call at a time.
struct FieldWorkspace {
  FieldWorkspace();
  ~FieldWorkspace();
  FieldWorkspace(const FieldWorkspace&);
  FieldWorkspace(FieldWorkspace&&) noexcept;
  FieldWorkspace& operator=(const FieldWorkspace&);
  FieldWorkspace& operator=(FieldWorkspace&&) noexcept;
  /// The tree of the last Method::tree evaluation on the CPU (gravity/tree.hpp); null before.
  std::unique_ptr<Tree> tree;
};

/// compute_field, reusing `workspace`'s memory (see FieldWorkspace); the same results.
FieldTimings compute_field(const GravityOptions& options, std::span<const double> positions,
                           std::span<const double> masses, std::span<double> accelerations, std::span<double> potential,
                           FieldWorkspace& workspace);

/// The instruction set of the CPU kernels this process runs, chosen once from the CPU (function
/// multi-versioning, gravity/kernels.cpp): "avx512" (x86-64-v4, with the hand-vectorized kernels
/// and their VRSQRT14 estimates), "x86-64-v3" (AVX2 and FMA) or "baseline" (any other CPU or
/// compiler). The CPU field is bit-identical for any number of threads, but its last bits differ
/// between these sets (SIMD width of the reductions, fused multiply-adds, the 1/sqrt estimates),
/// so a run's final hash is reproducible on machines of the same set.
std::string kernel_instruction_set();

/// Human-readable name of a method ("direct", "tree").
std::string to_string(Method method);

/// Name of a backend ("cpu", "cuda"), as in the scene file and the command line.
std::string to_string(Backend backend);

/// Name of a kernel precision ("double", "single"), as in the scene file and the command line.
std::string to_string(KernelPrecision precision);

}  // namespace rubble::gravity
