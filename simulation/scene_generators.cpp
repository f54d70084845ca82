// The scene file's [[generators]]: grains packed by preprocessing/packing.hpp (a box deposit, a
// cubic grid or a spherical cloud), spheres, random polyhedra or a mix (docs/scene-file.md). The
// keys a generator of each type and shape takes are the tables of scene_body_keys.cpp; they are
// read here, by hand (they configure a packing, and check each other: sizes, regions, counts).
#include <algorithm>
#include <numbers>
#include <random>
#include <span>
#include <tuple>

#include "preprocessing/grain_shapes.hpp"
#include "preprocessing/packing.hpp"
#include "simulation/memory_estimate.hpp"
#include "simulation/scene_keys.hpp"
#include "simulation/scene_parser.hpp"

namespace rubble::scene_detail {

namespace {

/// The bins of distribution = "bins": [[diameter, fraction], ...].
SizeRange parse_size_bins(const TableReader& entry) {
  const toml::node* node = entry.get("bins");
  if (!node) entry.missing("bins", "an array of [diameter, fraction] pairs, e.g. [[0.01, 0.5], [0.02, 0.5]]");
  const auto* array = node->as_array();
  if (!array || array->empty())
    entry.fail(node, entry.key_path("bins"), "expected a nonempty array of [diameter, fraction] pairs");
  std::vector<SizeBin> bins;
  double total = 0.0;
  for (std::size_t i = 0; i < array->size(); ++i) {
    const std::string path = entry.key_path("bins") + "[" + std::to_string(i) + "]";
    const auto* pair = array->get(i)->as_array();
    if (!pair || pair->size() != 2) entry.fail(array->get(i), path, "expected [diameter, fraction]");
    SizeBin bin;
    bin.diameter = entry.number_of(*pair->get(0), path + "[0]", positive());
    bin.fraction = entry.number_of(*pair->get(1), path + "[1]", non_negative());
    total += bin.fraction;
    bins.push_back(bin);
  }
  if (!(total > 0.0)) entry.fail(node, entry.key_path("bins"), "expected fractions summing to more than 0");
  const bool by_volume = entry.optional_choice("bin_fractions", {"volume", "number"}).value_or("volume") == "volume";
  return size_bins(std::move(bins), by_volume);
}

/// Size keys of a generator: radius_min/radius_max, or radius (monodisperse), or bins.
SizeRange parse_sizes(const TableReader& entry) {
  const std::string law =
      entry.optional_choice("distribution", {"uniform_radius", "uniform_volume_fraction", "monodisperse", "bins"})
          .value_or("uniform_radius");
  const auto refuse = [&](std::initializer_list<std::string_view> keys, const std::string& why) {
    for (const std::string_view key : keys) {
      if (entry.has(key)) entry.fail_key(key, "not used with distribution = \"" + law + "\" (" + why + ")");
    }
  };
  if (law == "monodisperse") {
    refuse({"radius_min", "radius_max", "bins", "bin_fractions"}, "give radius");
    SizeRange sizes;
    sizes.distribution = SizeDistribution::monodisperse;
    sizes.radius_min = sizes.radius_max = entry.number("radius", positive());
    return sizes;
  }
  if (law == "bins") {
    refuse({"radius_min", "radius_max", "radius"}, "give bins = [[diameter, fraction], ...]");
    return parse_size_bins(entry);
  }
  refuse({"radius", "bins", "bin_fractions"}, "give radius_min and radius_max");
  SizeRange sizes;
  sizes.radius_min = entry.number("radius_min", positive());
  sizes.radius_max = entry.number("radius_max", positive());
  if (sizes.radius_max < sizes.radius_min) {
    entry.fail_key("radius_max",
                   "expected radius_max >= radius_min (" + show(sizes.radius_min) + "), got " + show(sizes.radius_max));
  }
  sizes.distribution =
      law == "uniform_radius" ? SizeDistribution::uniform_radius : SizeDistribution::uniform_volume_fraction;
  return sizes;
}

/// Refuses (on `entry`'s `key`) a generator whose `count` grains, with the scene's grains so
/// far, would not fit in this process's memory (simulation/memory_estimate.hpp): checked
/// before the grains are made, so a scene of 10^8 grains fails at once with the estimate.
void check_memory(const SceneDraft& draft, const TableReader& entry, std::string_view key, std::uint64_t count,
                  bool polyhedra) {
  std::uint64_t spheres = 0, polyhedron_grains = 0;
  for (const GrainSpec& grain : draft.grains) ++(grain.is_polyhedron() ? polyhedron_grains : spheres);
  (polyhedra ? polyhedron_grains : spheres) += count;
  const std::string shortfall = memory_shortfall(spheres, polyhedron_grains);
  if (!shortfall.empty()) entry.fail_key(key, shortfall);
}

/// The keys a generator of this type and shape takes (scene_keys.hpp), for the unknown-key check.
std::vector<std::string_view> generator_keys(const std::string& type, const std::string& shape) {
  std::vector<std::string_view> allowed = key_names(generator_common_keys());
  for (const auto* more : {&generator_shape_keys(shape), &generator_type_keys(type)}) {
    for (const std::string_view name : key_names(*more)) allowed.push_back(name);
  }
  return allowed;
}

/// Everything a packing function needs to know about its generator entry.
struct GeneratorEntry {
  const SceneDraft& draft;
  const TableReader& entry;
  bool polyhedra = false;  ///< shape is "polyhedron" or "mix" (for the memory estimate)
  std::uint64_t seed = 0;
};

std::vector<PackedGrain> pack_box_deposit(const GeneratorEntry& g) {
  const TableReader& entry = g.entry;
  BoxDepositOptions options;
  options.count = static_cast<std::uint64_t>(entry.integer("count", 1, static_cast<std::int64_t>(max_packed_grains)));
  check_memory(g.draft, entry, "count", options.count, g.polyhedra);
  options.sizes = parse_sizes(entry);
  options.region_min = entry.vec3("region_min", coordinate());
  options.region_max = entry.vec3("region_max", coordinate());
  for (int axis = 0; axis < 3; ++axis) {
    if (!(options.region_max[axis] > options.region_min[axis])) {
      entry.fail_key("region_max", "expected region_max > region_min on every axis, got " +
                                       show_vec3(options.region_max) + " vs " + show_vec3(options.region_min));
    }
  }
  options.cell_size = entry.number_or("cell_size", 0.0, length_or_zero());
  const double cell = box_deposit_cell_size(options);
  if (cell < 2.0 * options.sizes.radius_max) {
    entry.fail_key("cell_size", "expected 0 (automatic) or a cell >= 2 radius_max (" +
                                    show(2.0 * options.sizes.radius_max) + " m), got " + show(cell));
  }
  const std::uint64_t capacity = box_deposit_capacity(options);
  if (options.count > capacity) {
    entry.fail_key("count", "the region is too small: it holds at most " + std::to_string(capacity) +
                                " grains on a grid of cell " + show(cell) + " m (expected count <= " +
                                std::to_string(capacity) + ", got " + std::to_string(options.count) +
                                "); enlarge region_min/region_max or reduce radius_max or cell_size");
  }
  return box_deposit(options, g.seed);
}

std::vector<PackedGrain> pack_cubic_grid(const GeneratorEntry& g) {
  const TableReader& entry = g.entry;
  CubicGridOptions options;
  options.cells_per_side = static_cast<std::uint64_t>(entry.integer("cells_per_side", 1, 464));
  check_memory(g.draft, entry, "cells_per_side",
               options.cells_per_side * options.cells_per_side * options.cells_per_side, g.polyhedra);
  options.sizes = parse_sizes(entry);
  options.cell_size = entry.number_or("cell_size", 0.0, length_or_zero());
  if (options.cell_size > 0.0 && options.cell_size < 2.0 * options.sizes.radius_max) {
    entry.fail_key("cell_size", "expected 0 (automatic: 2 radius_max) or a cell >= 2 radius_max (" +
                                    show(2.0 * options.sizes.radius_max) + " m), got " + show(options.cell_size));
  }
  options.center = entry.optional_vector<3>("center", coordinate()).value_or(Vec3::Zero());
  return cubic_grid_packing(options, g.seed);
}

std::vector<PackedGrain> pack_sphere_cloud(const GeneratorEntry& g) {
  const TableReader& entry = g.entry;
  SphereCloudOptions options;
  options.count = static_cast<std::uint64_t>(entry.integer("count", 1, static_cast<std::int64_t>(max_packed_grains)));
  check_memory(g.draft, entry, "count", options.count, g.polyhedra);
  options.sizes = parse_sizes(entry);
  options.center = entry.optional_vector<3>("center", coordinate()).value_or(Vec3::Zero());
  if (entry.has("cloud_radius") == entry.has("volume_fraction")) {
    entry.fail_table("expected exactly one of cloud_radius (m) and volume_fraction (grain volume / ball volume)");
  }
  if (entry.has("cloud_radius")) {
    options.radius = entry.number("cloud_radius", length());
    if (options.radius < options.sizes.radius_max) {
      entry.fail_key("cloud_radius", "expected a cloud radius >= the largest grain radius (" +
                                         show(options.sizes.radius_max) + " m), got " + show(options.radius));
    }
  } else {
    options.radius = sphere_cloud_radius(options.count, options.sizes, entry.number("volume_fraction", open(0.0, 1.0)));
    options.radius = std::max(options.radius, options.sizes.radius_max);
  }
  return sphere_cloud(options, g.seed);
}

/// What a generator's grains get besides their packed ball.
struct GrainRecipe {
  int material = 0;
  Vec3 velocity = Vec3::Zero();
  int polyhedron_recipe = -1;        ///< index into SceneDraft::polyhedron_recipes (shape "polyhedron" or "mix")
  double polyhedron_fraction = 0.0;  ///< probability that a grain is a polyhedron
};

/// The grains of generator `index` from its packing: spheres, or (with probability
/// `recipe.polyhedron_fraction`) polyhedra to inscribe in the packed balls, made later
/// (make_polyhedra).
std::vector<GrainSpec> generator_grains(const TableReader& entry, std::size_t index,
                                        const std::vector<PackedGrain>& packed, const GrainRecipe& recipe,
                                        std::uint64_t seed) {
  // Per grain, its own seed: whether it is a polyhedron, its shape and its orientation do not
  // depend on the other grains, so grains can be made in parallel and in any order.
  const std::uint64_t shape_stream = derive_seed(seed, 0x5348415045ULL);
  std::vector<GrainSpec> made(packed.size());
  for (std::size_t k = 0; k < packed.size(); ++k) {
    GrainSpec& grain = made[k];
    grain.radius = packed[k].radius;
    grain.position = packed[k].position;
    grain.velocity = recipe.velocity;
    grain.material = recipe.material;
    grain.origin.generator = static_cast<int>(index);
    grain.origin.ordinal = k;
    grain.origin.node = entry.anchor();
    if (recipe.polyhedron_fraction <= 0.0) continue;
    std::mt19937_64 rng(derive_seed(shape_stream, k));
    if (uniform_01(rng) >= recipe.polyhedron_fraction) continue;
    grain.pending_recipe = recipe.polyhedron_recipe;
    grain.shape_seed = rng();
  }
  return made;
}

/// The recipe of a generator or inflow entry of this shape: material, velocity, the share of
/// polyhedra and, for those, the shape options (registered in draft.polyhedron_recipes).
GrainRecipe parse_grain_recipe(SceneDraft& draft, const TableReader& entry, const std::string& shape,
                               const Vec3& velocity) {
  GrainRecipe recipe;
  recipe.material = material_of(draft, entry);
  recipe.velocity = velocity;
  recipe.polyhedron_fraction = shape == "polyhedron" ? 1.0 : 0.0;
  if (shape != "sphere") {
    recipe.polyhedron_recipe = static_cast<int>(draft.polyhedron_recipes.size());
    draft.polyhedron_recipes.push_back({entry, parse_random_polyhedron_options(entry)});
  }
  if (shape == "mix") recipe.polyhedron_fraction = entry.number("polyhedron_fraction", closed(0.0, 1.0));
  return recipe;
}

/// The box of an entry's region_min/region_max (centres), region_max > region_min on every axis.
std::pair<Vec3, Vec3> parse_region(const TableReader& entry) {
  const Vec3 low = entry.vec3("region_min", coordinate());
  const Vec3 high = entry.vec3("region_max", coordinate());
  for (int axis = 0; axis < 3; ++axis) {
    if (!(high[axis] > low[axis])) {
      entry.fail_key("region_max", "expected region_max > region_min on every axis, got " + show_vec3(high) + " vs " +
                                       show_vec3(low));
    }
  }
  return {low, high};
}

/// The grains of one inflow: sizes from the law, shapes as a generator's (each from its own
/// seed), placed nowhere yet (insert_due_grains places them during the run).
std::vector<GrainSpec> inflow_grains(const TableReader& entry, std::size_t index, std::uint64_t count,
                                     const SizeRange& sizes, const GrainRecipe& recipe, std::uint64_t seed) {
  std::mt19937_64 size_rng(derive_seed(seed, 0x53495A45ULL));
  std::vector<PackedGrain> balls(count);
  for (PackedGrain& ball : balls) ball.radius = draw_radius(sizes, size_rng);
  return generator_grains(entry, index, balls, recipe, seed);
}

/// Grains per second: `rate`, or `mass_rate` (kg/s) over the mean mass of the inflow's own grains
/// (density x volume), so that the grains' mass enters at mass_rate on average.
double inflow_rate(const SceneDraft& draft, double mass_rate, std::span<const GrainSpec> grains) {
  double mass = 0.0;
  for (const GrainSpec& grain : grains) {
    const double density = draft.scene.model.materials[static_cast<std::size_t>(grain.material)].density;
    mass += density * (grain.polyhedron ? grain.polyhedron->volume
                                        : 4.0 / 3.0 * std::numbers::pi * grain.radius * grain.radius * grain.radius);
  }
  return mass_rate * static_cast<double>(grains.size()) / mass;
}

}  // namespace

void parse_inflows(SceneDraft& draft) {
  const auto entries = draft.root.tables("inflow");
  // A stream of its own, so that adding an inflow changes no generator's grains.
  const std::uint64_t inflow_seed = derive_seed(draft.scene.run.seed, 0x494E464C4F57ULL);
  for (std::size_t index = 0; index < entries.size(); ++index) {
    const TableReader& entry = entries[index];
    const std::string shape = entry.optional_choice("shape", {"sphere", "polyhedron", "mix"}).value_or("sphere");
    std::vector<std::string_view> allowed = key_names(inflow_keys());
    for (const std::string_view name : key_names(generator_shape_keys(shape))) allowed.push_back(name);
    entry.allow_only(allowed, "for an inflow of shape = \"" + shape + "\"");
    Inflow inflow;
    inflow.count = static_cast<std::uint64_t>(entry.integer("count", 1, static_cast<std::int64_t>(max_packed_grains)));
    check_memory(draft, entry, "count", inflow.count, shape != "sphere");
    inflow.start_time = entry.number_or("start_time", 0.0, non_negative());
    std::tie(inflow.region_min, inflow.region_max) = parse_region(entry);
    inflow.attempts = static_cast<int>(entry.integer_or("attempts", 100, 1, 1000000));
    inflow.velocity = entry.vec3_or("velocity", Vec3::Zero());
    inflow.seed = derive_seed(inflow_seed, index);
    const SizeRange sizes = parse_sizes(entry);
    const GrainRecipe recipe = parse_grain_recipe(draft, entry, shape, inflow.velocity);
    if (entry.has("rate") == entry.has("mass_rate")) {
      entry.fail_table("expected exactly one of rate (grains per second) and mass_rate (kg/s)");
    }
    inflow.rate = entry.has("rate") ? entry.number("rate", positive()) : 0.0;  // mass_rate: finish_inflows
    draft.inflow_mass_rates.push_back(entry.has("mass_rate") ? entry.number("mass_rate", positive()) : 0.0);
    draft.inflow_first_grain.push_back(draft.inflow_grains.size());
    for (GrainSpec& grain : inflow_grains(entry, index, inflow.count, sizes, recipe, inflow.seed)) {
      draft.inflow_grains.push_back(std::move(grain));
    }
    draft.scene.inflow.inflows.push_back(inflow);
  }
}

void finish_inflows(SceneDraft& draft) {
  std::vector<Inflow>& inflows = draft.scene.inflow.inflows;
  std::vector<InflowGrain>& order = draft.scene.inflow.grains;
  for (std::size_t index = 0; index < inflows.size(); ++index) {
    Inflow& inflow = inflows[index];
    if (draft.inflow_mass_rates[index] > 0.0) {
      const std::span<const GrainSpec> grains(draft.inflow_grains.data() + draft.inflow_first_grain[index],
                                              inflow.count);
      inflow.rate = inflow_rate(draft, draft.inflow_mass_rates[index], grains);
    }
    for (std::uint64_t k = 0; k < inflow.count; ++k) {
      order.push_back({static_cast<int>(index), k, inflow.start_time + static_cast<double>(k) / inflow.rate});
    }
  }
  // Bodies in order of due time (ties: file order, then number), so that those in play are a prefix.
  std::stable_sort(order.begin(), order.end(),
                   [](const InflowGrain& a, const InflowGrain& b) { return a.due_time < b.due_time; });
  std::vector<GrainSpec> sorted;
  sorted.reserve(order.size());
  for (const InflowGrain& grain : order) {
    sorted.push_back(std::move(
        draft.inflow_grains[draft.inflow_first_grain[static_cast<std::size_t>(grain.inflow)] + grain.ordinal]));
  }
  draft.inflow_grains = std::move(sorted);
}

void make_polyhedra(SceneDraft& draft) {
  std::vector<GrainSpec*> pending;
  for (auto* grains : {&draft.grains, &draft.inflow_grains}) {
    for (GrainSpec& grain : *grains) {
      if (grain.pending_recipe >= 0) pending.push_back(&grain);
    }
  }
  std::vector<std::string> failure(pending.size());
  const auto count = static_cast<std::ptrdiff_t>(pending.size());
#pragma omp parallel for schedule(dynamic, 64) if (count > 256)
  for (std::ptrdiff_t k = 0; k < count; ++k) {
    GrainSpec& grain = *pending[static_cast<std::size_t>(k)];
    const RandomPolyhedronOptions& options =
        draft.polyhedron_recipes[static_cast<std::size_t>(grain.pending_recipe)].options;
    try {
      PlacedPolyhedron placed = random_polyhedron_in_ball({grain.position, grain.radius}, options, grain.shape_seed);
      grain.position = placed.position;
      grain.orientation = placed.orientation;
      grain.radius = placed.shape.bounding_radius;
      grain.polyhedron = std::make_shared<const ConvexPolyhedron>(std::move(placed.shape));
    } catch (const std::exception& error) {
      failure[static_cast<std::size_t>(k)] = error.what();
    }
  }
  for (std::size_t k = 0; k < pending.size(); ++k) {
    const GrainSpec& grain = *pending[k];
    if (!failure[k].empty()) {
      draft.polyhedron_recipes[static_cast<std::size_t>(grain.pending_recipe)].entry.fail_table(
          "grain " + std::to_string(grain.origin.ordinal) + ": cannot make its polyhedron: " + failure[k]);
    }
  }
  for (GrainSpec* grain : pending) grain->pending_recipe = -1;
}

void parse_generators(SceneDraft& draft) {
  const auto entries = draft.root.tables("generators");
  for (std::size_t index = 0; index < entries.size(); ++index) {
    const TableReader& entry = entries[index];
    const std::string type = entry.choice("type", {"box_deposit", "cubic_grid", "sphere_cloud"});
    const std::string shape = entry.optional_choice("shape", {"sphere", "polyhedron", "mix"}).value_or("sphere");
    entry.allow_only(generator_keys(type, shape),
                     "for a generator of type = \"" + type + "\" and shape = \"" + shape + "\"");
    const GeneratorEntry generator{draft, entry, shape != "sphere", derive_seed(draft.scene.run.seed, index)};
    std::vector<PackedGrain> packed;
    try {
      if (type == "box_deposit") {
        packed = pack_box_deposit(generator);
      } else if (type == "cubic_grid") {
        packed = pack_cubic_grid(generator);
      } else {
        packed = pack_sphere_cloud(generator);
      }
    } catch (const PackingError& error) {
      // Options are checked above; anything left is still reported against the generator.
      entry.fail_table(error.what());
    }
    const GrainRecipe recipe = parse_grain_recipe(draft, entry, shape, entry.vec3_or("velocity", Vec3::Zero()));
    const std::vector<GrainSpec> made = generator_grains(entry, index, packed, recipe, generator.seed);
    for (const GrainSpec& grain : made) add_grain(draft, grain);
  }
}

}  // namespace rubble::scene_detail
