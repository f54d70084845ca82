// The scene file's [[walls]], [[bodies]] (spheres and polyhedra, driven ones with their prescribed
// motion) and [[initial_conditions]] (docs/scene-file.md).
#include <filesystem>
#include <limits>

#include "preprocessing/packing.hpp"
#include "preprocessing/polyhedron_file.hpp"
#include "simulation/scene_parser.hpp"

namespace rubble::scene_detail {

std::string grain_label(const GrainOrigin& origin) {
  if (origin.body_entry >= 0) return "the grain";
  return "grain " + std::to_string(origin.ordinal);
}

std::string grain_name(const GrainOrigin& origin) {
  if (origin.body_entry >= 0) return "bodies[" + std::to_string(origin.body_entry) + "]";
  return "generators[" + std::to_string(origin.generator) + "] (grain " + std::to_string(origin.ordinal) + ")";
}

std::string grain_key(const GrainOrigin& origin) {
  if (origin.body_entry >= 0) return "bodies[" + std::to_string(origin.body_entry) + "]";
  return "generators[" + std::to_string(origin.generator) + "]";
}

namespace {

/// The prescribed motion of a driven wall or body: `motion`, a table of rows
/// [t, vx, vy, vz] or [t, vx, vy, vz, wx, wy, wz] (s, m/s, rad/s; times increasing; linear in
/// between, held outside), or else the constant `velocity` and `angular_velocity`.
PrescribedMotion parse_motion(const TableReader& entry) {
  PrescribedMotion motion;
  const toml::node* node = entry.get("motion");
  if (!node) {
    motion.time = {0.0};
    motion.velocity = {entry.vec3_or("velocity", Vec3::Zero())};
    motion.angular_velocity = {entry.vec3_or("angular_velocity", Vec3::Zero())};
    return motion;
  }
  for (const std::string_view key : {"velocity", "angular_velocity"}) {
    if (entry.has(key)) {
      entry.fail_key(key,
                     "give either a motion table or a constant velocity and angular_velocity, not both (the "
                     "table's rows hold the velocities)");
    }
  }
  const auto* rows = node->as_array();
  if (!rows || rows->empty()) {
    entry.fail(node, entry.key_path("motion"),
               "expected an array of rows [t, vx, vy, vz] or [t, vx, vy, vz, wx, wy, wz], got " + describe_node(*node));
  }
  for (std::size_t i = 0; i < rows->size(); ++i) {
    const std::string path = entry.key_path("motion") + "[" + std::to_string(i) + "]";
    const auto* row = rows->get(i)->as_array();
    if (!row || (row->size() != 4 && row->size() != 7)) {
      entry.fail(rows->get(i), path,
                 "expected a row [t, vx, vy, vz] or [t, vx, vy, vz, wx, wy, wz] (s, m/s, rad/s), got " +
                     describe_node(*rows->get(i)));
    }
    double values[7] = {0, 0, 0, 0, 0, 0, 0};
    for (std::size_t k = 0; k < row->size(); ++k) values[k] = entry.number_of(*row->get(k), path, any_number());
    if (!motion.time.empty() && !(values[0] > motion.time.back())) {
      entry.fail(rows->get(i), path,
                 "expected times increasing row by row, got t = " + show(values[0]) + " s after " +
                     show(motion.time.back()) + " s");
    }
    motion.time.push_back(values[0]);
    motion.velocity.emplace_back(values[1], values[2], values[3]);
    motion.angular_velocity.emplace_back(values[4], values[5], values[6]);
  }
  return motion;
}

/// An array of [x, y, z] arrays.
std::vector<Vec3> vector_list(const TableReader& entry, std::string_view key) {
  const toml::node* node = entry.get(key);
  const auto* array = node ? node->as_array() : nullptr;
  if (!array || array->size() < 4) {
    entry.fail(
        node ? node : entry.anchor(), entry.key_path(key),
        "expected an array of >= 4 points [[x, y, z], ...]" + (node ? ", got " + describe_node(*node) : std::string()));
  }
  std::vector<Vec3> points;
  for (std::size_t i = 0; i < array->size(); ++i) {
    const std::string path = entry.key_path(key) + "[" + std::to_string(i) + "]";
    const auto* point = array->get(i)->as_array();
    if (!point || point->size() != 3) entry.fail(array->get(i), path, "expected [x, y, z]");
    Vec3 p;
    for (int axis = 0; axis < 3; ++axis) {
      p[axis] = entry.number_of(*point->get(static_cast<std::size_t>(axis)), path, any_number());
    }
    points.push_back(p);
  }
  return points;
}

/// The `faces` key: arrays of >= 3 indices into `vertex_count` vertices.
std::vector<std::vector<int>> face_list(const TableReader& entry, std::size_t vertex_count) {
  const toml::node* faces_node = entry.get("faces");
  if (!faces_node)
    entry.missing("faces", "an array of faces, each an array of vertex indices (0-based, CCW from outside)");
  std::vector<std::vector<int>> faces;
  const auto* faces_array = faces_node->as_array();
  if (!faces_array) entry.fail(faces_node, entry.key_path("faces"), "expected an array of arrays of vertex indices");
  for (std::size_t f = 0; f < faces_array->size(); ++f) {
    const auto* face = faces_array->get(f)->as_array();
    const std::string key = entry.key_path("faces") + "[" + std::to_string(f) + "]";
    if (!face || face->size() < 3) entry.fail(faces_array->get(f), key, "expected an array of >= 3 vertex indices");
    std::vector<int> indices;
    for (std::size_t k = 0; k < face->size(); ++k) {
      const auto* index = face->get(k)->as_integer();
      if (!index || index->get() < 0 || index->get() >= static_cast<std::int64_t>(vertex_count)) {
        entry.fail(face->get(k), key,
                   "expected vertex indices in [0, " + std::to_string(vertex_count - 1) + "], got " +
                       describe_node(*face->get(k)));
      }
      indices.push_back(static_cast<int>(index->get()));
    }
    faces.push_back(std::move(indices));
  }
  return faces;
}

/// A polyhedron body read from a mesh file (relative paths from the scene file's folder).
ConvexPolyhedron polyhedron_from_file(const SceneDraft& draft, const TableReader& entry, PolyhedronPose& pose) {
  PolyhedronFileOptions options;
  options.scale = entry.number_or("scale", 1.0, positive());
  std::filesystem::path path = entry.string("file");
  if (path.is_relative()) path = std::filesystem::path(draft.file).parent_path() / path;
  try {
    return load_polyhedron_file(path.string(), options, &pose);
  } catch (const std::exception& error) {
    entry.fail_key("file", std::string("cannot use the polyhedron file: ") + error.what());
  }
}

/// A polyhedron body given by its vertices and faces.
ConvexPolyhedron polyhedron_from_vertices(const TableReader& entry, PolyhedronPose& pose) {
  const std::vector<Vec3> vertices = vector_list(entry, "vertices");
  std::vector<std::vector<int>> faces = face_list(entry, vertices.size());
  PolyhedronBuildOptions options;
  options.convexity_tolerance =
      entry.number_or("convexity_tolerance", options.convexity_tolerance, Range{0.0, 0.5, false, true});
  try {
    return make_convex_polyhedron(vertices, std::move(faces), options, &pose);
  } catch (const PolyhedronError& error) {
    entry.fail_key(error.face >= 0 ? "faces" : "vertices", error.what());
  }
}

/// A random polyhedron body (centroid and principal frame at position and orientation).
ConvexPolyhedron random_polyhedron_body(const SceneDraft& draft, const TableReader& entry) {
  RandomPolyhedronOptions options = parse_random_polyhedron_options(entry);
  options.diameter = entry.number("diameter", positive());
  const auto shape_seed = static_cast<std::uint64_t>(
      entry.integer_or("shape_seed", static_cast<std::int64_t>(derive_seed(draft.scene.run.seed, 1ULL << 40) >> 1), 0,
                       std::numeric_limits<std::int64_t>::max()));
  try {
    return generate_random_polyhedron(options, shape_seed);
  } catch (const std::exception& error) {
    entry.fail_table(std::string("cannot make the random polyhedron: ") + error.what());
  }
}

/// A [[bodies]] entry of shape = "polyhedron": from a mesh file, from listed vertices and
/// faces, or random. position/orientation place the file's (or the listed vertices') frame;
/// for a random polyhedron, they are the centroid and the principal frame.
void parse_polyhedron_body(const SceneDraft& draft, const TableReader& entry, GrainSpec& grain) {
  const std::vector<std::string_view> placement = {
      "shape", "position", "orientation", "velocity", "angular_velocity", "material", "driven", "motion"};
  const auto with = [&](std::initializer_list<std::string_view> more) {
    std::vector<std::string_view> keys = placement;
    keys.insert(keys.end(), more);
    return keys;
  };
  const int sources = (entry.has("file") ? 1 : 0) + (entry.has("vertices") ? 1 : 0) + (entry.has("diameter") ? 1 : 0);
  if (sources != 1) {
    entry.fail_table(sources == 0 ? "a polyhedron needs its shape: expected one of file = \"rock.obj\", vertices = "
                                    "[[x, y, z], ...] with faces, or diameter = D for a random one"
                                  : "expected only one of file, vertices and diameter");
  }
  const Vec3 position = entry.vec3("position", coordinate());
  const Quat orientation = entry.orientation_or_identity("orientation");
  PolyhedronPose pose;  // the body frame in the frame the shape was given in
  ConvexPolyhedron shape;
  if (entry.has("file")) {
    entry.allow_only(with({"file", "scale"}), "for a polyhedron read from a file");
    shape = polyhedron_from_file(draft, entry, pose);
  } else if (entry.has("vertices")) {
    entry.allow_only(with({"vertices", "faces", "convexity_tolerance"}), "for a polyhedron given by its vertices");
    shape = polyhedron_from_vertices(entry, pose);
  } else {
    entry.allow_only(
        with({"diameter", "shape_seed", "min_vertices", "max_vertices", "min_elongation", "min_platyness"}),
        "for a random polyhedron");
    shape = random_polyhedron_body(draft, entry);
  }
  grain.position = position + orientation * pose.centroid;
  grain.orientation = (orientation * pose.orientation).normalized();
  grain.radius = shape.bounding_radius;
  grain.polyhedron = std::make_shared<const ConvexPolyhedron>(std::move(shape));
}

}  // namespace

RandomPolyhedronOptions parse_random_polyhedron_options(const TableReader& entry) {
  RandomPolyhedronOptions options;
  options.min_vertices = static_cast<int>(entry.integer_or("min_vertices", options.min_vertices, 4, 100'000));
  options.max_vertices = static_cast<int>(entry.integer_or("max_vertices", options.max_vertices, 4, 100'000));
  if (options.max_vertices < options.min_vertices) {
    entry.fail_key("max_vertices", "expected max_vertices >= min_vertices (" + std::to_string(options.min_vertices) +
                                       "), got " + std::to_string(options.max_vertices));
  }
  options.min_elongation = entry.number_or("min_elongation", options.min_elongation, Range{0.0, 1.0, false, true});
  options.min_platyness = entry.number_or("min_platyness", options.min_platyness, Range{0.0, 1.0, false, true});
  return options;
}

void add_grain(SceneDraft& draft, const GrainSpec& grain) {
  if (draft.grains.size() >= max_packed_grains) {
    draft.root.fail(grain.origin.node, grain_key(grain.origin),
                    "too many grains: expected at most " + std::to_string(max_packed_grains) + " in a scene");
  }
  draft.grains.push_back(grain);
}

void parse_walls(SceneDraft& draft) {
  for (const TableReader& entry : draft.root.tables("walls")) {
    WallSpec wall;
    wall.path = entry.path();
    wall.node = entry.anchor();
    const std::string type = entry.choice("type", {"plane", "box"});
    if (type == "plane") {
      entry.allow_only({"type", "point", "normal", "material", "velocity", "angular_velocity", "motion"},
                       "for a wall of type = \"plane\"");
      wall.is_plane = true;
      wall.position = entry.vec3("point", coordinate());
      const Vec3 normal = entry.vec3("normal");
      const double norm = normal.stableNorm();  // the plain norm of [1e200, 0, 0] overflows
      if (!(norm > 1e-12) || !std::isfinite(norm)) {
        entry.fail_key("normal", "expected a nonzero vector (the side grains live on), got " + show_vec3(normal));
      }
      wall.normal = normal / norm;
    } else {
      entry.allow_only(
          {"type", "center", "half_extents", "orientation", "material", "velocity", "angular_velocity", "motion"},
          "for a wall of type = \"box\"");
      wall.is_plane = false;
      wall.position = entry.vec3("center", coordinate());
      wall.half_extents = entry.vec3("half_extents", length());
      wall.orientation = entry.orientation_or_identity("orientation");
    }
    wall.material = material_of(draft, entry);
    // A wall moves when given a velocity, an angular velocity or a motion table.
    if (entry.has("motion") || entry.has("velocity") || entry.has("angular_velocity"))
      wall.motion = parse_motion(entry);
    draft.walls.push_back(wall);
  }
}

void parse_bodies(SceneDraft& draft) {
  const auto entries = draft.root.tables("bodies");
  for (std::size_t i = 0; i < entries.size(); ++i) {
    const TableReader& entry = entries[i];
    const std::string shape = entry.choice("shape", {"sphere", "polyhedron"});
    GrainSpec grain;
    if (shape == "polyhedron") {
      parse_polyhedron_body(draft, entry, grain);
    } else {
      entry.allow_only({"shape", "radius", "position", "orientation", "velocity", "angular_velocity", "material",
                        "driven", "motion"},
                       "for a body of shape = \"sphere\"");
      grain.radius = entry.number("radius", positive());
      grain.position = entry.vec3("position", coordinate());
      grain.orientation = entry.orientation_or_identity("orientation");
    }
    grain.velocity = entry.vec3_or("velocity", Vec3::Zero());
    grain.angular_velocity = entry.vec3_or("angular_velocity", Vec3::Zero());
    grain.material = material_of(draft, entry);
    const bool driven = entry.boolean_or("driven", entry.has("motion"));
    if (entry.has("motion") && !driven) entry.fail_key("driven", "a body with a motion table is driven: expected true");
    if (driven) {
      grain.motion = static_cast<int>(draft.grain_motions.size());
      draft.grain_motions.push_back(parse_motion(entry));
    }
    grain.origin.body_entry = static_cast<int>(i);
    grain.origin.node = entry.anchor();
    add_grain(draft, grain);
  }
}

void parse_initial_conditions(SceneDraft& draft) {
  for (const TableReader& entry : draft.root.tables("initial_conditions")) {
    entry.allow_only({"velocity", "angular_velocity", "center", "material", "region_min", "region_max"},
                     "in [[initial_conditions]]");
    if (!entry.has("velocity") && !entry.has("angular_velocity")) {
      entry.fail_table("expected velocity = [vx, vy, vz] (m/s) and/or angular_velocity = [wx, wy, wz] (rad/s)");
    }
    InitialCondition condition;
    condition.velocity = entry.vec3_or("velocity", Vec3::Zero());
    condition.angular_velocity = entry.vec3_or("angular_velocity", Vec3::Zero());
    condition.centre = entry.optional_vector<3>("center", coordinate());
    if (entry.has("material")) condition.material = material_of(draft, entry);
    if (entry.has("region_min") != entry.has("region_max")) {
      entry.fail_key(entry.has("region_min") ? "region_min" : "region_max",
                     "expected both region_min and region_max (the corners of the box the grains' centres lie in)");
    }
    if (entry.has("region_min")) {
      condition.region_min = entry.vec3("region_min", coordinate());
      condition.region_max = entry.vec3("region_max", coordinate());
      if ((condition.region_max->array() < condition.region_min->array()).any()) {
        entry.fail_key("region_max", "expected region_max >= region_min on every axis, got " +
                                         show_vec3(*condition.region_max) + " vs " + show_vec3(*condition.region_min));
      }
    }
    draft.scene.initial_conditions.push_back(condition);
    draft.condition_nodes.push_back(entry.anchor());
  }
}

}  // namespace rubble::scene_detail
