#include "preprocessing/packing.hpp"

#include <algorithm>
#include <array>
#include <functional>
#include <limits>
#include <cmath>
#include <numbers>
#include <numeric>
#include <sstream>
#include <unordered_map>

namespace rubble {
namespace {

/// Default cell of a box deposit, in units of the largest diameter: 10% of free space around each
/// grain so the deposit starts loose and no two grains start in contact.
constexpr double loose_cell_factor = 1.1;

bool finite(const Vec3& v) { return v.allFinite(); }

void validate_bins(const std::vector<SizeBin>& bins) {
  if (bins.empty()) throw PackingError("bins: expected at least one (diameter, fraction) bin");
  double total = 0.0;
  for (std::size_t i = 0; i < bins.size(); ++i) {
    if (!std::isfinite(bins[i].diameter) || !(bins[i].diameter > 0.0)) {
      std::ostringstream out;
      out << "bins[" << i << "]: diameter must be a finite number > 0, got " << bins[i].diameter;
      throw PackingError(out.str());
    }
    if (!std::isfinite(bins[i].fraction) || !(bins[i].fraction >= 0.0)) {
      std::ostringstream out;
      out << "bins[" << i << "]: fraction must be a finite number >= 0, got " << bins[i].fraction;
      throw PackingError(out.str());
    }
    total += bins[i].fraction;
  }
  if (!(total > 0.0)) throw PackingError("bins: expected fractions summing to more than 0");
}

void validate_sizes(const SizeRange& sizes) {
  if (sizes.distribution == SizeDistribution::bins) validate_bins(sizes.bins);
  if (!std::isfinite(sizes.radius_min) || !(sizes.radius_min > 0.0)) {
    std::ostringstream out;
    out << "radius_min must be a finite number > 0, got " << sizes.radius_min;
    throw PackingError(out.str());
  }
  if (!std::isfinite(sizes.radius_max) || !(sizes.radius_max >= sizes.radius_min)) {
    std::ostringstream out;
    out << "radius_max must be a finite number >= radius_min (" << sizes.radius_min << "), got " << sizes.radius_max;
    throw PackingError(out.str());
  }
}

void validate_cell(double cell_size, double radius_max) {
  if (!std::isfinite(cell_size) || !(cell_size >= 2.0 * radius_max)) {
    std::ostringstream out;
    out << "cell_size must be a finite number >= 2 radius_max (" << 2.0 * radius_max << " m), got " << cell_size;
    throw PackingError(out.str());
  }
}

/// One grain per cell for the first `count` cells of an nx * ny * nz grid whose cell (0,0,0) has
/// its lower corner at `origin`; x fastest, then y, then z. Per grain: one draw for the radius,
/// then one per axis for the position, so the sequence is fixed by the seed.
std::vector<PackedGrain> fill_grid(const Vec3& origin, const std::uint64_t n[3], double cell, std::uint64_t count,
                                   const SizeRange& sizes, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<PackedGrain> grains;
  grains.reserve(static_cast<std::size_t>(count));
  for (std::uint64_t index = 0; index < count; ++index) {
    const std::uint64_t i = index % n[0];
    const std::uint64_t j = (index / n[0]) % n[1];
    const std::uint64_t k = index / (n[0] * n[1]);
    const Vec3 corner = origin + cell * Vec3(static_cast<double>(i), static_cast<double>(j), static_cast<double>(k));
    PackedGrain grain;
    grain.radius = draw_radius(sizes, rng);
    // Centre uniform in the cell shrunk by the radius: the ball stays inside its cell.
    const double free_length = cell - 2.0 * grain.radius;
    for (int axis = 0; axis < 3; ++axis) {
      grain.position[axis] = corner[axis] + grain.radius + uniform_01(rng) * free_length;
    }
    grains.push_back(grain);
  }
  return grains;
}

}  // namespace

SizeRange size_bins(std::vector<SizeBin> bins, bool fractions_by_volume) {
  validate_bins(bins);
  SizeRange sizes;
  sizes.distribution = SizeDistribution::bins;
  sizes.bin_fractions_by_volume = fractions_by_volume;
  sizes.radius_min = std::numeric_limits<double>::infinity();
  for (const SizeBin& bin : bins) {
    sizes.radius_min = std::min(sizes.radius_min, 0.5 * bin.diameter);
    sizes.radius_max = std::max(sizes.radius_max, 0.5 * bin.diameter);
  }
  sizes.bins = std::move(bins);
  return sizes;
}

std::vector<double> bin_number_probabilities(const SizeRange& sizes) {
  std::vector<double> p(sizes.bins.size());
  for (std::size_t i = 0; i < p.size(); ++i) {
    const double d = sizes.bins[i].diameter;
    // A volume share f_i is f_i / d_i^3 grains (up to a constant factor pi/6).
    p[i] = sizes.bin_fractions_by_volume ? sizes.bins[i].fraction / (d * d * d) : sizes.bins[i].fraction;
  }
  const double total = std::accumulate(p.begin(), p.end(), 0.0);
  for (double& x : p) x /= total;
  return p;
}

double draw_radius(const SizeRange& sizes, std::mt19937_64& rng) {
  const double u = uniform_01(rng);
  switch (sizes.distribution) {
    case SizeDistribution::monodisperse:
      return sizes.radius_max;
    case SizeDistribution::bins: {
      // Inverse CDF over the bins; the last bin takes any round-off remainder.
      const std::vector<double> p = bin_number_probabilities(sizes);
      double cumulative = 0.0;
      for (std::size_t i = 0; i + 1 < p.size(); ++i) {
        cumulative += p[i];
        if (u < cumulative) return 0.5 * sizes.bins[i].diameter;
      }
      return 0.5 * sizes.bins.back().diameter;
    }
    case SizeDistribution::uniform_radius:
      return sizes.radius_min + u * (sizes.radius_max - sizes.radius_min);
    case SizeDistribution::uniform_volume_fraction: {
      // Number density n(r) ∝ r^-3 on [rmin, rmax]; CDF F(r) = (rmin^-2 - r^-2) / (rmin^-2 - rmax^-2),
      // inverted: r = (rmin^-2 - u (rmin^-2 - rmax^-2))^(-1/2).
      const double a = 1.0 / (sizes.radius_min * sizes.radius_min);
      const double b = 1.0 / (sizes.radius_max * sizes.radius_max);
      const double r = 1.0 / std::sqrt(a - u * (a - b));
      return std::clamp(r, sizes.radius_min, sizes.radius_max);
    }
  }
  return sizes.radius_min;
}

double box_deposit_cell_size(const BoxDepositOptions& options) {
  return options.cell_size > 0.0 ? options.cell_size : 2.0 * loose_cell_factor * options.sizes.radius_max;
}

std::uint64_t box_deposit_capacity(const BoxDepositOptions& options) {
  validate_sizes(options.sizes);
  if (!finite(options.region_min) || !finite(options.region_max)) {
    throw PackingError("region_min and region_max must be finite");
  }
  const double cell = box_deposit_cell_size(options);
  validate_cell(cell, options.sizes.radius_max);
  double capacity = 1.0;
  for (int axis = 0; axis < 3; ++axis) {
    const double extent = options.region_max[axis] - options.region_min[axis];
    if (!(extent > 0.0)) {
      std::ostringstream out;
      out << "region_max must exceed region_min on every axis, got extent " << extent << " m on axis "
          << "xyz"[axis];
      throw PackingError(out.str());
    }
    // The relative 1e-9 keeps an extent meant as an exact multiple of the cell from losing a layer
    // to round-off.
    capacity *= std::floor(extent / cell * (1.0 + 1e-9));
  }
  return capacity >= 1.8e19 ? UINT64_MAX : static_cast<std::uint64_t>(capacity);
}

std::vector<PackedGrain> box_deposit(const BoxDepositOptions& options, std::uint64_t seed) {
  const std::uint64_t capacity = box_deposit_capacity(options);
  if (options.count > max_packed_grains) {
    std::ostringstream out;
    out << "count must be <= " << max_packed_grains << ", got " << options.count;
    throw PackingError(out.str());
  }
  const double cell = box_deposit_cell_size(options);
  if (options.count > capacity) {
    std::ostringstream out;
    out << "the region holds at most " << capacity << " grains on a grid of cell " << cell << " m, asked for "
        << options.count;
    throw PackingError(out.str());
  }
  std::uint64_t n[3];
  Vec3 origin;
  for (int axis = 0; axis < 3; ++axis) {
    const double extent = options.region_max[axis] - options.region_min[axis];
    // Capped before the cast: an absurdly long axis (extent / cell > 2^64, found by fuzzing) would
    // overflow it, and no axis ever needs more cells than the largest grain count.
    n[axis] = static_cast<std::uint64_t>(
        std::min(std::floor(extent / cell * (1.0 + 1e-9)), static_cast<double>(max_packed_grains)));
    // Centre the grid in x and y; along z start at the bottom so the deposit is a compact column.
    origin[axis] = axis == 2 ? options.region_min[axis]
                             : options.region_min[axis] + 0.5 * (extent - static_cast<double>(n[axis]) * cell);
  }
  return fill_grid(origin, n, cell, options.count, options.sizes, seed);
}

std::vector<PackedGrain> cubic_grid_packing(const CubicGridOptions& options, std::uint64_t seed) {
  validate_sizes(options.sizes);
  if (!finite(options.center)) throw PackingError("center must be finite");
  const double cell = options.cell_size > 0.0 ? options.cell_size : 2.0 * options.sizes.radius_max;
  validate_cell(cell, options.sizes.radius_max);
  const std::uint64_t k = options.cells_per_side;
  if (k == 0 || k > 464) {  // 465^3 > 10^8
    std::ostringstream out;
    out << "cells_per_side must be in [1, 464] (at most " << max_packed_grains << " grains), got " << k;
    throw PackingError(out.str());
  }
  const std::uint64_t n[3] = {k, k, k};
  const Vec3 origin = options.center - Vec3::Constant(0.5 * static_cast<double>(k) * cell);
  return fill_grid(origin, n, cell, k * k * k, options.sizes, seed);
}

double sphere_cloud_radius(std::uint64_t count, const SizeRange& sizes, double volume_fraction) {
  validate_sizes(sizes);
  if (!std::isfinite(volume_fraction) || !(volume_fraction > 0.0) || !(volume_fraction < 1.0)) {
    std::ostringstream out;
    out << "volume_fraction must be in (0, 1), got " << volume_fraction;
    throw PackingError(out.str());
  }
  // Mean of r^3 under the law, so that the expected grain volume is count 4/3 pi <r^3>.
  const double a = sizes.radius_min;
  const double b = sizes.radius_max;
  double mean_r3 = b * b * b;
  switch (sizes.distribution) {
    case SizeDistribution::monodisperse:
      break;
    case SizeDistribution::uniform_radius:
      if (b > a) mean_r3 = (b * b * b * b - a * a * a * a) / (4.0 * (b - a));
      break;
    case SizeDistribution::uniform_volume_fraction:
      // pdf 2 r^-3 / (a^-2 - b^-2): <r^3> = 2 (b - a) / (a^-2 - b^-2).
      if (b > a) mean_r3 = 2.0 * (b - a) / (1.0 / (a * a) - 1.0 / (b * b));
      break;
    case SizeDistribution::bins: {
      const std::vector<double> p = bin_number_probabilities(sizes);
      mean_r3 = 0.0;
      for (std::size_t i = 0; i < p.size(); ++i) mean_r3 += p[i] * std::pow(0.5 * sizes.bins[i].diameter, 3);
      break;
    }
  }
  return std::cbrt(static_cast<double>(count) * mean_r3 / volume_fraction);
}

std::vector<PackedGrain> sphere_cloud(const SphereCloudOptions& options, std::uint64_t seed) {
  validate_sizes(options.sizes);
  if (!finite(options.center)) throw PackingError("center must be finite");
  if (options.count == 0 || options.count > max_packed_grains) {
    std::ostringstream out;
    out << "count must be in [1, " << max_packed_grains << "], got " << options.count;
    throw PackingError(out.str());
  }
  if (!std::isfinite(options.radius) || !(options.radius >= options.sizes.radius_max)) {
    std::ostringstream out;
    out << "the cloud radius must be a finite number >= radius_max (" << options.sizes.radius_max << " m), got "
        << options.radius;
    throw PackingError(out.str());
  }
  if (options.max_attempts < 1) throw PackingError("max_attempts must be >= 1");
  std::mt19937_64 rng(seed);
  std::vector<double> radii(static_cast<std::size_t>(options.count));
  for (double& r : radii) r = draw_radius(options.sizes, rng);
  // Largest first: small grains fill the gaps that large ones leave, so the cloud jams later.
  std::sort(radii.begin(), radii.end(), std::greater<>());

  // Hash grid of cell 2 radius_max: a grain's overlapping neighbours are in the 27 cells around it.
  const double cell = 2.0 * options.sizes.radius_max;
  const auto key_of = [&](const Vec3& x) {
    std::array<std::int64_t, 3> k{};
    for (int axis = 0; axis < 3; ++axis)
      k[static_cast<std::size_t>(axis)] =
          static_cast<std::int64_t>(std::floor((x[axis] - options.center[axis]) / cell));
    return k;
  };
  const auto hash = [](const std::array<std::int64_t, 3>& k) {
    return static_cast<std::uint64_t>(k[0]) * 73856093ULL ^ static_cast<std::uint64_t>(k[1]) * 19349663ULL ^
           static_cast<std::uint64_t>(k[2]) * 83492791ULL;
  };
  std::unordered_map<std::uint64_t, std::vector<std::uint32_t>> grid;
  std::vector<PackedGrain> grains;
  grains.reserve(radii.size());
  for (const double r : radii) {
    const double reach = options.radius - r;
    bool placed = false;
    for (int attempt = 0; attempt < options.max_attempts && !placed; ++attempt) {
      // Uniform in the ball of radius `reach` by rejection from its cube.
      Vec3 offset;
      do {
        for (int axis = 0; axis < 3; ++axis) offset[axis] = (2.0 * uniform_01(rng) - 1.0) * reach;
      } while (offset.squaredNorm() > reach * reach);
      const Vec3 x = options.center + offset;
      const auto k = key_of(x);
      bool free = true;
      for (std::int64_t dx = -1; dx <= 1 && free; ++dx) {
        for (std::int64_t dy = -1; dy <= 1 && free; ++dy) {
          for (std::int64_t dz = -1; dz <= 1 && free; ++dz) {
            const auto it = grid.find(hash({k[0] + dx, k[1] + dy, k[2] + dz}));
            if (it == grid.end()) continue;
            for (const std::uint32_t other : it->second) {
              const double touch = r + grains[other].radius;
              if ((grains[other].position - x).squaredNorm() < touch * touch) {
                free = false;
                break;
              }
            }
          }
        }
      }
      if (!free) continue;
      grid[hash(k)].push_back(static_cast<std::uint32_t>(grains.size()));
      grains.push_back(PackedGrain{x, r});
      placed = true;
    }
    if (!placed) {
      double volume = 0.0;
      for (const double x : radii) volume += x * x * x;
      std::ostringstream out;
      out << "no room for grain " << grains.size() << " of " << options.count << " (radius " << r << " m) after "
          << options.max_attempts << " random tries: the cloud is too dense (grain volume fraction "
          << volume / std::pow(options.radius, 3) << "; random loose clouds jam near 0.3): enlarge the cloud radius";
      throw PackingError(out.str());
    }
  }
  return grains;
}

}  // namespace rubble
