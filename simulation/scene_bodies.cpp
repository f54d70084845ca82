// The scene file's [[walls]], [[bodies]] (spheres and polyhedra, driven ones with their prescribed
// motion) and [[initial_conditions]] (docs/scene-file.md). Their keys are the tables of
// scene_body_keys.cpp, which read the keys that set one member; here, those read by hand: the
// material, the prescribed motion, a polyhedron's shape, an initial condition's selection.
#include <filesystem>
#include <limits>

#include "preprocessing/packing.hpp"
#include "preprocessing/polyhedron_file.hpp"
#include "simulation/scene_keys.hpp"
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
  const int sources = (entry.has("file") ? 1 : 0) + (entry.has("vertices") ? 1 : 0) + (entry.has("diameter") ? 1 : 0);
  if (sources != 1) {
    entry.fail_table(sources == 0 ? "a polyhedron needs its shape: expected one of file = \"rock.obj\", vertices = "
                                    "[[x, y, z], ...] with faces, or diameter = D for a random one"
                                  : "expected only one of file, vertices and diameter");
  }
  const std::string_view way = entry.has("file") ? "file" : entry.has("vertices") ? "vertices" : "diameter";
  const auto& keys = polyhedron_body_keys(way);
  read_section_keys(entry, keys, grain);  // position and orientation of the shape's frame
  PolyhedronPose pose;                    // the body frame in the frame the shape was given in
  ConvexPolyhedron shape;
  if (way == "file") {
    entry.allow_only(key_names(keys), "for a polyhedron read from a file");
    shape = polyhedron_from_file(draft, entry, pose);
  } else if (way == "vertices") {
    entry.allow_only(key_names(keys), "for a polyhedron given by its vertices");
    shape = polyhedron_from_vertices(entry, pose);
  } else {
    entry.allow_only(key_names(keys), "for a random polyhedron");
    shape = random_polyhedron_body(draft, entry);
  }
  grain.position = grain.position + grain.orientation * pose.centroid;
  grain.orientation = (grain.orientation * pose.orientation).normalized();
  grain.radius = shape.bounding_radius;
  grain.polyhedron = std::make_shared<const ConvexPolyhedron>(std::move(shape));
}

}  // namespace

RandomPolyhedronOptions parse_random_polyhedron_options(const TableReader& entry) {
  RandomPolyhedronOptions options;
  read_section_keys(entry, random_polyhedron_keys(), options);
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
    const auto& keys = wall_keys(type);
    entry.allow_only(key_names(keys), "for a wall of type = \"" + type + "\"");
    wall.is_plane = type == "plane";
    read_section_keys(entry, keys, wall);
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
      entry.allow_only(key_names(sphere_body_keys()), "for a body of shape = \"sphere\"");
      read_section_keys(entry, sphere_body_keys(), grain);
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
    entry.allow_only(key_names(initial_condition_keys()), "in [[initial_conditions]]");
    if (!entry.has("velocity") && !entry.has("angular_velocity")) {
      entry.fail_table("expected velocity = [vx, vy, vz] (m/s) and/or angular_velocity = [wx, wy, wz] (rad/s)");
    }
    InitialCondition condition;
    read_section_keys(entry, initial_condition_keys(), condition);
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
