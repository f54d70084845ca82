// The key tables of the body sections: [[materials]], [[walls]], [[bodies]], [[generators]] and
// [[initial_conditions]] (scene_keys.hpp). Most of their keys depend on another key (a wall's
// type, a body's shape, a generator's type and shape): one table per kind. Keys read by hand are
// those whose value is not one member: the material (a name looked up among the materials), the
// prescribed motion (velocity, angular_velocity, motion: parse_motion), a polyhedron's mesh, and
// every generator key (they configure a packing, scene_generators.cpp).
#include "simulation/scene_keys.hpp"

namespace rubble::scene_detail {

const std::vector<SectionKey<MaterialEntry>>& material_keys() {
  using O = MaterialEntry;
  static const std::vector<SectionKey<O>> keys = {
      {.name = "name",
       .option = [](O& o) -> OptionRef { return &o.material.name; },
       .required = true,
       .check =
           [](const TableReader& table, const O& o) {
             const std::string& name = o.material.name;
             if (name.empty()) table.fail_key("name", "expected a nonempty material name");
             if (o.defined && o.defined->count(name)) {
               table.fail_key("name", "material \"" + name + "\" is defined twice (expected unique names)");
             }
           },
       .doc = "how grains, walls and contact laws refer to it"},
      {.name = "density",
       .option = [](O& o) -> OptionRef { return &o.material.density; },
       .range = positive(),
       .required = true,
       .doc = "kg/m^3, turns a grain's volume into its mass"},
  };
  return keys;
}

namespace {

/// `material`: a name among the [[materials]] (material_of), read by the section's parser.
template <class Options>
SectionKey<Options> material_row() {
  return {.name = "material", .type = "material name", .doc = "the name of a [[materials]] entry"};
}

/// The prescribed motion's keys, read by parse_motion (a constant velocity or a table of rows,
/// not both) and written by the writer's motion_keys (with `driven`).
template <class Options>
std::vector<SectionKey<Options>> motion_rows() {
  return {{.name = "velocity", .type = "vector", .doc = "m/s, velocity of the reference point"},
          {.name = "angular_velocity", .type = "vector", .doc = "rad/s, world frame, about the reference point"},
          {.name = "motion", .type = "array of rows", .doc = "a prescribed motion by a table of rows"}};
}

/// The `type` of a wall, or the `shape` of a body: read by the section's parser (it picks the table).
template <class Options>
SectionKey<Options> kind_row(std::string_view name, std::string_view word, std::string (*write)(const Options&)) {
  return {.name = name, .required = true, .choices = {word}, .write = write, .doc = "decides the other keys"};
}

bool turned(const Quat& q) { return q.coeffs() != Quat::Identity().coeffs(); }

}  // namespace

const std::vector<SectionKey<WallSpec>>& wall_keys(std::string_view type) {
  using O = WallSpec;
  static const std::vector<SectionKey<O>> plane =
      joined<O>({kind_row<O>("type", "plane", [](const O&) { return std::string("\"plane\""); }),
                 {.name = "point",
                  .option = [](O& o) -> OptionRef { return &o.position; },
                  .range = coordinate(),
                  .required = true,
                  .doc = "m, a point of the plane"},
                 // Read by hand: any nonzero vector, normalised (without overflow).
                 {.name = "normal",
                  .required = true,
                  .type = "vector",
                  .read =
                      [](const TableReader& table, O& o) {
                        const Vec3 normal = table.vec3("normal");
                        const double norm = normal.stableNorm();  // the plain norm of [1e200, 0, 0] overflows
                        if (!(norm > 1e-12) || !std::isfinite(norm)) {
                          table.fail_key("normal", "expected a nonzero vector (the side grains live on), got " +
                                                       show_vec3(normal));
                        }
                        o.normal = normal / norm;
                      },
                  .write = [](const O& o) { return format_vec3(o.normal); },
                  .doc = "points towards the grains; normalised"},
                 material_row<O>()},
                motion_rows<O>());
  static const std::vector<SectionKey<O>> box =
      joined<O>({kind_row<O>("type", "box", [](const O&) { return std::string("\"box\""); }),
                 {.name = "center",
                  .option = [](O& o) -> OptionRef { return &o.position; },
                  .range = coordinate(),
                  .required = true,
                  .doc = "m, centre of the box"},
                 {.name = "half_extents",
                  .option = [](O& o) -> OptionRef { return &o.half_extents; },
                  .range = length(),
                  .required = true,
                  .doc = "m, half side lengths along the box's axes"},
                 {.name = "orientation",
                  .option = [](O& o) -> OptionRef { return &o.orientation; },
                  .written = [](const O& o) { return turned(o.orientation); },
                  .doc = "box axes to world"},
                 material_row<O>()},
                motion_rows<O>());
  return type == "plane" ? plane : box;
}

namespace {

/// `driven`: read by parse_bodies with `motion` (a body with a motion table is driven).
template <class Options>
SectionKey<Options> driven_row() {
  return {.name = "driven", .type = "boolean", .doc = "true: the velocities are prescribed for the whole run"};
}

/// The keys of a body besides its shape's, after `position` and `orientation` (read by hand,
/// after the shape: the velocities with `driven` and `motion`).
std::vector<SectionKey<GrainSpec>> body_motion_rows() {
  std::vector<SectionKey<GrainSpec>> rows = motion_rows<GrainSpec>();
  rows.insert(rows.begin() + 2, {material_row<GrainSpec>(), driven_row<GrainSpec>()});
  return rows;
}

SectionKey<GrainSpec> position_row() {
  return {.name = "position",
          .option = [](GrainSpec& o) -> OptionRef { return &o.position; },
          .range = coordinate(),
          .required = true,
          .doc = "m, where the body's frame is placed"};
}

}  // namespace

const std::vector<SectionKey<GrainSpec>>& sphere_body_keys() {
  using O = GrainSpec;
  static const std::vector<SectionKey<O>> keys =
      joined<O>({kind_row<O>("shape", "sphere", [](const O&) { return std::string("\"sphere\""); }),
                 {.name = "radius",
                  .option = [](O& o) -> OptionRef { return &o.radius; },
                  .range = positive(),
                  .required = true,
                  .doc = "m"},
                 position_row(),
                 {.name = "orientation",
                  .option = [](O& o) -> OptionRef { return &o.orientation; },
                  .written = [](const O& o) { return turned(o.orientation); },
                  .doc = "body to world"}},
                body_motion_rows());
  return keys;
}

const std::vector<std::string_view>& polyhedron_ways() {
  static const std::vector<std::string_view> ways = {"file", "vertices", "diameter"};
  return ways;
}

const std::vector<SectionKey<GrainSpec>>& polyhedron_body_keys(std::string_view way) {
  using O = GrainSpec;
  // position and orientation place the frame the shape is given in (parse_polyhedron_body);
  // the way's keys make the shape, not a member of the grain: read by hand.
  static const std::vector<SectionKey<O>> placement =
      joined<O>({kind_row<O>("shape", "polyhedron", [](const O&) { return std::string("\"polyhedron\""); }),
                 position_row(),
                 {.name = "orientation",
                  .option = [](O& o) -> OptionRef { return &o.orientation; },
                  .doc = "the shape's frame to world"}},
                body_motion_rows());
  static const std::vector<SectionKey<O>> file =
      joined<O>(placement, {{.name = "file", .required = true, .type = "string", .doc = "path to a .off or .obj mesh"},
                            {.name = "scale", .type = "number", .doc = "factor on the file's coordinates"}});
  static const std::vector<SectionKey<O>> vertices = joined<O>(
      placement, {{.name = "vertices", .required = true, .type = "array of points", .doc = "m, >= 4 points"},
                  {.name = "faces", .required = true, .type = "array of faces", .doc = "0-based vertex indices"},
                  {.name = "convexity_tolerance",
                   .type = "number",
                   .doc = "allowed bend of a face, as a fraction of the diameter"}});
  static const std::vector<SectionKey<O>> random = joined<O>(
      placement, joined<O>({{.name = "diameter", .required = true, .type = "number", .doc = "m, circumscribed"},
                            {.name = "shape_seed", .type = "integer", .doc = "default: from the scene's seed"}},
                           keys_read_by_hand<O>(random_polyhedron_keys())));
  if (way == "file") return file;
  if (way == "vertices") return vertices;
  return random;
}

const std::vector<SectionKey<RandomPolyhedronOptions>>& random_polyhedron_keys() {
  using O = RandomPolyhedronOptions;
  static const std::vector<SectionKey<O>> keys = {
      {.name = "min_vertices",
       .option = [](O& o) -> OptionRef { return &o.min_vertices; },
       .low = 4,
       .high = 100'000,
       .doc = "fewest points drawn on the sphere"},
      {.name = "max_vertices",
       .option = [](O& o) -> OptionRef { return &o.max_vertices; },
       .low = 4,
       .high = 100'000,
       .check =
           [](const TableReader& table, const O& o) {
             if (o.max_vertices < o.min_vertices) {
               table.fail_key("max_vertices", "expected max_vertices >= min_vertices (" +
                                                  std::to_string(o.min_vertices) + "), got " +
                                                  std::to_string(o.max_vertices));
             }
           },
       .doc = "most points drawn on the sphere"},
      {.name = "min_elongation",
       .option = [](O& o) -> OptionRef { return &o.min_elongation; },
       .range = Range{0.0, 1.0, false, true},
       .doc = "elongation drawn in [min_elongation, 1]"},
      {.name = "min_platyness",
       .option = [](O& o) -> OptionRef { return &o.min_platyness; },
       .range = Range{0.0, 1.0, false, true},
       .doc = "platyness drawn in [min_platyness, 1]"},
  };
  return keys;
}

const std::vector<SectionKey<ByHand>>& generator_common_keys() {
  static const std::vector<SectionKey<ByHand>> keys = {
      {.name = "type",
       .required = true,
       .choices = {"box_deposit", "cubic_grid", "sphere_cloud"},
       .doc = "the placement; decides the other keys"},
      {.name = "shape", .choices = {"sphere", "polyhedron", "mix"}, .doc = "grain shape"},
      {.name = "distribution",
       .choices = {"uniform_radius", "uniform_volume_fraction", "monodisperse", "bins"},
       .doc = "law of the size"},
      {.name = "radius_min", .required = true, .type = "number", .doc = "m"},
      {.name = "radius_max", .required = true, .type = "number", .doc = "m, >= radius_min"},
      {.name = "radius", .required = true, .type = "number", .doc = "m, monodisperse"},
      {.name = "bins", .required = true, .type = "array of [diameter, fraction]", .doc = "size classes"},
      {.name = "bin_fractions", .choices = {"volume", "number"}, .doc = "what the bin fractions are shares of"},
      material_row<ByHand>(),
      {.name = "velocity", .type = "vector", .doc = "m/s, initial velocity of every grain"},
  };
  return keys;
}

const std::vector<SectionKey<ByHand>>& generator_shape_keys(std::string_view shape) {
  static const std::vector<SectionKey<ByHand>> sphere = {};
  static const std::vector<SectionKey<ByHand>> polyhedron = keys_read_by_hand<ByHand>(random_polyhedron_keys());
  static const std::vector<SectionKey<ByHand>> mix =
      joined<ByHand>(polyhedron, {{.name = "polyhedron_fraction",
                                   .required = true,
                                   .type = "number",
                                   .doc = "probability that a grain is a polyhedron"}});
  if (shape == "sphere") return sphere;
  return shape == "mix" ? mix : polyhedron;
}

const std::vector<SectionKey<ByHand>>& generator_type_keys(std::string_view type) {
  using O = ByHand;
  const SectionKey<O> count = {.name = "count", .required = true, .type = "integer", .doc = "grains"};
  const SectionKey<O> cell_size = {.name = "cell_size", .type = "number", .doc = "m, grid cell edge; 0: automatic"};
  const SectionKey<O> center = {.name = "center", .type = "vector", .doc = "m"};
  static const std::vector<SectionKey<O>> box_deposit = {
      count,
      {.name = "region_min", .required = true, .type = "vector", .doc = "m"},
      {.name = "region_max", .required = true, .type = "vector", .doc = "m"},
      cell_size};
  static const std::vector<SectionKey<O>> cubic_grid = {
      {.name = "cells_per_side", .required = true, .type = "integer", .doc = "n: n^3 grains"}, cell_size, center};
  static const std::vector<SectionKey<O>> sphere_cloud = {
      count,
      center,
      {.name = "cloud_radius", .type = "number", .doc = "m, radius of the ball"},
      {.name = "volume_fraction", .type = "number", .doc = "grain volume / ball volume"}};
  if (type == "box_deposit") return box_deposit;
  return type == "cubic_grid" ? cubic_grid : sphere_cloud;
}

const std::vector<SectionKey<InitialCondition>>& initial_condition_keys() {
  using O = InitialCondition;
  static const std::vector<SectionKey<O>> keys = {
      {.name = "velocity", .option = [](O& o) -> OptionRef { return &o.velocity; }, .doc = "V, m/s"},
      {.name = "angular_velocity",
       .option = [](O& o) -> OptionRef { return &o.angular_velocity; },
       .doc = "omega, rad/s, world frame"},
      // Read by hand (parse_initial_conditions): optional points (unset: the selection's centre
      // of mass, everywhere) and a material name.
      {.name = "center", .type = "vector", .doc = "m, a point of the rotation axis"},
      material_row<O>(),
      {.name = "region_min", .type = "vector", .doc = "m, with region_max"},
      {.name = "region_max", .type = "vector", .doc = "m, with region_min"},
  };
  return keys;
}

const std::vector<SectionKey<ByHand>>& inflow_keys() {
  static const std::vector<SectionKey<ByHand>> keys = [] {
    // The grains' keys are a generator's (shape, size law, material, velocity) without `type`:
    // read by the same code (scene_generators.cpp); then the inflow's own.
    std::vector<SectionKey<ByHand>> grain_keys;
    for (const SectionKey<ByHand>& key : generator_common_keys()) {
      if (key.name != "type") grain_keys.push_back(key);
    }
    return joined<ByHand>(
        grain_keys,
        {{.name = "count", .required = true, .type = "integer", .doc = "grains inserted in all"},
         {.name = "rate", .type = "number", .doc = "grains per second (or mass_rate)"},
         {.name = "mass_rate", .type = "number", .doc = "kg/s, instead of rate"},
         {.name = "start_time", .type = "number", .doc = "s, when the first grain is due"},
         {.name = "region_min", .required = true, .type = "vector", .doc = "m, where the grains' centres appear"},
         {.name = "region_max", .required = true, .type = "vector", .doc = "m, > region_min on every axis"},
         {.name = "attempts", .type = "integer", .doc = "positions tried per grain and step before it waits"}});
  }();
  return keys;
}

}  // namespace rubble::scene_detail
