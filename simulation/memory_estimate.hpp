#pragma once
// How much memory a scene will need, estimated from its grain counts before anything is
// allocated, and how much this process may use: a scene that cannot fit is refused as bad input
// with the estimate (exit code 2) instead of growing for minutes and dying with std::bad_alloc.
#include <cstdint>
#include <string>

namespace rubble {

/// Peak resident memory a sphere grain takes in a run, bytes: 2.44 kB measured at 10^5 spheres
/// (bench/RESULTS.md, "The sweeps keep W⁻¹ beside W"; 1.84 kB in "Memory per grain", no longer
/// true), rounded up.
inline constexpr double bytes_per_sphere = 2560.0;
/// The same for a random convex polyhedron grain (10-70 vertices): 5.50 kB measured, rounded up.
inline constexpr double bytes_per_polyhedron = 6144.0;

/// Estimated peak memory of a run of `spheres` sphere grains and `polyhedra` polyhedral grains,
/// bytes (the per-grain figures above; a lower bound for meshes of many vertices).
double scene_memory_estimate(std::uint64_t spheres, std::uint64_t polyhedra);

/// Memory this process may use, bytes: the smallest of the machine's physical memory
/// (sysconf), the cgroup's limit (memory.max, or memory.limit_in_bytes for cgroup v1) and the
/// address-space and data-segment limits (ulimit -v, -d); 0 if none could be read.
double available_memory();

/// When the estimate exceeds available_memory(), what to say: "this scene needs about X GB
/// (...), more than the Y GB this machine/process has"; empty when it fits (or the memory is unknown).
std::string memory_shortfall(std::uint64_t spheres, std::uint64_t polyhedra);

}  // namespace rubble
