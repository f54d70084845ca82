#pragma once
// Initial packings of grains: where the grains of a scene start and how big they are.
//
// Both packings place one grain per cell of a regular cubic grid, at a uniformly random position
// inside its cell, shrunk by the grain's radius so that the grain lies entirely in its cell.
// Cells do not overlap, so grains never overlap, with no neighbour search (the accretion study's
// initial state: "grains placed at random in the cells of a cubic grid of mesh d_max").
//
// Reproducibility: every packing draws from a std::mt19937_64 built locally from the seed, and
// turns its raw 64-bit output into numbers with our own formulas (not std::uniform_real_distribution,
// whose algorithm differs between standard libraries), so the same seed gives bit-identical grains
// on every platform and thread count.
#include <cstdint>
#include <random>
#include <stdexcept>
#include <vector>

#include "core/input_error.hpp"
#include "core/math.hpp"

namespace rubble {

/// Thrown when packing options are invalid or the region cannot hold the requested grains. An
/// InputError: the options are what a user gave (core/input_error.hpp).
class PackingError : public InputError {
 public:
  using InputError::InputError;
};

/// How grain radii are distributed between radius_min and radius_max.
enum class SizeDistribution {
  /// Every grain has radius_max (radius_min is not used).
  monodisperse,
  /// Radius uniform in [radius_min, radius_max].
  uniform_radius,
  /// Uniform by volume fraction: every radius class [r, r + dr] holds the same total grain
  /// volume, so the number density is n(r) ∝ r^-3 (Voivret et al. 2007, Phys. Rev. E 76; the
  /// accretion study's distribution). Sampled by inverting F(r) = (rmin^-2 - r^-2) / (rmin^-2 - rmax^-2).
  uniform_volume_fraction,
  /// Discrete sizes: SizeRange::bins lists (diameter, fraction) pairs, the fraction being a
  /// share of the grain volume (SizeRange::bin_fractions_by_volume, the usual sieve-curve
  /// convention) or of the number of grains. A grain falls in bin i with probability
  /// p_i = f_i / d_i^3 / sum_j f_j / d_j^3 (by volume) or f_i / sum_j f_j (by number).
  bins,
};

/// One size class of SizeDistribution::bins.
struct SizeBin {
  double diameter = 0.0;  ///< m, > 0
  double fraction = 0.0;  ///< >= 0, share of the volume (or number) of the grains; normalised
};

/// A range of grain radii and how they are drawn.
struct SizeRange {
  double radius_min = 0.0;  ///< m, > 0 (for bins: half the smallest diameter, see size_bins())
  double radius_max = 0.0;  ///< m, >= radius_min (for bins: half the largest diameter)
  SizeDistribution distribution = SizeDistribution::uniform_radius;  ///< law of the radius
  std::vector<SizeBin> bins;                                         ///< SizeDistribution::bins only
  bool bin_fractions_by_volume = true;  ///< bins: fractions of the volume (true) or of the number
};

/// A SizeRange of discrete bins, radius_min/radius_max set from the bins. Throws PackingError
/// for an empty list, a diameter <= 0, a fraction < 0 or fractions summing to 0.
SizeRange size_bins(std::vector<SizeBin> bins, bool fractions_by_volume = true);

/// Probability that a drawn grain falls in each bin (SizeDistribution::bins): the number shares.
std::vector<double> bin_number_probabilities(const SizeRange& sizes);

/// One placed grain: centre and (bounding) radius.
struct PackedGrain {
  Vec3 position = Vec3::Zero();  ///< m, centre
  double radius = 0.0;           ///< m
};

/// A given number of grains in an axis-aligned box region (a deposit before it falls).
struct BoxDepositOptions {
  std::uint64_t count = 0;         ///< number of grains, <= max_packed_grains
  SizeRange sizes{};               ///< radii
  Vec3 region_min = Vec3::Zero();  ///< m, lower corner of the region every grain lies inside
  Vec3 region_max = Vec3::Zero();  ///< m, upper corner
  /// m, edge of the grid cells; 0 picks 2.2 radius_max (a loose grid: grains start apart).
  /// Must be >= 2 radius_max.
  double cell_size = 0.0;
};

/// The accretion study's cloud: n^3 grains, one per cell of a cubic grid.
struct CubicGridOptions {
  std::uint64_t cells_per_side = 0;  ///< n, the grid has n^3 cells and grains
  double cell_size = 0.0;            ///< m, mesh of the grid; 0 picks 2 radius_max (d_max); >= 2 radius_max
  Vec3 center = Vec3::Zero();        ///< m, centre of the grid
  SizeRange sizes{};                 ///< radii
};

/// A loose random cloud: `count` grains at uniformly random positions inside a ball, no two
/// overlapping (random sequential addition: each grain, largest first, is tried at random
/// positions until it overlaps none of those placed before).
struct SphereCloudOptions {
  std::uint64_t count = 0;     ///< number of grains
  SizeRange sizes{};           ///< radii
  Vec3 center = Vec3::Zero();  ///< m, centre of the ball
  double radius = 0.0;         ///< m, radius of the ball every grain lies inside, >= radius_max
  /// Tries per grain before giving up with a PackingError (the cloud is too dense: random
  /// sequential addition jams near a volume fraction of 0.38 for equal spheres).
  int max_attempts = 10000;
};

/// Largest number of grains a packing will produce (memory guard).
inline constexpr std::uint64_t max_packed_grains = 100'000'000;

/// A uniform double in [0, 1) from the top 53 bits of one draw (portable, unlike
/// std::uniform_real_distribution).
inline double uniform_01(std::mt19937_64& rng) { return static_cast<double>(rng() >> 11) * 0x1.0p-53; }

/// An independent seed for random stream `stream` of a scene seeded with `seed` (SplitMix64 of the
/// pair, Steele, Lea & Flood 2014), so that e.g. each generator of a scene draws its own numbers and
/// adding a generator does not change the grains of the others.
inline std::uint64_t derive_seed(std::uint64_t seed, std::uint64_t stream) {
  std::uint64_t z = seed + 0x9E3779B97F4A7C15ULL * (stream + 1);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

/// Draws one radius from the range (one call to the generator).
double draw_radius(const SizeRange& sizes, std::mt19937_64& rng);

/// Cell edge a box deposit uses (options.cell_size, or 2.2 radius_max when it is 0).
double box_deposit_cell_size(const BoxDepositOptions& options);

/// How many grains the box deposit's grid holds: the product over the three axes of
/// floor(region extent / cell size). Throws PackingError on invalid options.
std::uint64_t box_deposit_capacity(const BoxDepositOptions& options);

/// Places `count` grains in the region, filling grid layers from region_min.z upwards (x fastest,
/// then y, then z), the grid centred in the region. Each grain lies inside the region and inside its
/// own cell, so none overlap. Throws PackingError if the options are invalid or count exceeds the capacity.
std::vector<PackedGrain> box_deposit(const BoxDepositOptions& options, std::uint64_t seed);

/// Places one grain in each cell of the n^3 grid centred on options.center (x fastest, then y, then z).
/// Throws PackingError if the options are invalid.
std::vector<PackedGrain> cubic_grid_packing(const CubicGridOptions& options, std::uint64_t seed);

/// The ball radius that gives a cloud of `count` grains of the given sizes the volume fraction
/// `volume_fraction` (grain volume / ball volume), from the mean grain volume of the law.
double sphere_cloud_radius(std::uint64_t count, const SizeRange& sizes, double volume_fraction);

/// A random loose cloud in a ball (SphereCloudOptions). Grains come out in placement order
/// (largest first). Throws PackingError if the options are invalid or a grain finds no room.
std::vector<PackedGrain> sphere_cloud(const SphereCloudOptions& options, std::uint64_t seed);

}  // namespace rubble
