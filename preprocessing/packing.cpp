#include "preprocessing/packing.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace rubble {
namespace {

/// Default cell of a box deposit, in units of the largest diameter: 10% of free space around each
/// grain so the deposit starts loose and no two grains start in contact.
constexpr double loose_cell_factor = 1.1;

bool finite(const Vec3& v) { return v.allFinite(); }

void validate_sizes(const SizeRange& sizes) {
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

double draw_radius(const SizeRange& sizes, std::mt19937_64& rng) {
  const double u = uniform_01(rng);
  switch (sizes.distribution) {
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
      out << "region_max must exceed region_min on every axis, got extent " << extent << " m on axis " << "xyz"[axis];
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
    n[axis] = static_cast<std::uint64_t>(std::floor(extent / cell * (1.0 + 1e-9)));
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

}  // namespace rubble
