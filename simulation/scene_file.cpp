// Scene files: parse_scene reads the sections in a fixed order (the order decides which problem of
// a file with several is reported), checks what needs only the grains' materials and kinds, makes
// the generated polyhedra, checks the geometry, then makes the bodies. The pieces
// live in files of their own (simulation/README.md): reading TOML (scene_reader), the sections
// (scene_sections, scene_materials, scene_bodies, scene_generators), the checks (scene_checks),
// the writer (scene_writer) and the built-in scenes (scene_defaults).
#include "simulation/scene_file.hpp"

#include "core/input_file.hpp"
#include "simulation/scene_keys.hpp"
#include "simulation/scene_parser.hpp"

namespace rubble {

namespace {

/// "FILE:LINE: KEY: message". Appended piece by piece: `":" + std::to_string(line)` trips GCC 12's
/// -Wrestrict false positive when inlined here.
std::string scene_error_text(const std::string& file, int line, const std::string& key, const std::string& message) {
  std::string text = file;
  if (line > 0) text.append(":").append(std::to_string(line));
  text.append(": ");
  if (!key.empty()) text.append(key).append(": ");
  return text.append(message);
}

}  // namespace

SceneError::SceneError(std::string file_, int line_, std::string key_, std::string message_)
    : InputError(scene_error_text(file_, line_, key_, message_)),
      file(std::move(file_)),
      line(line_),
      key(std::move(key_)),
      message(std::move(message_)) {}

namespace scene_detail {
namespace {

/// The inflow grains, after the walls (never selected by [[initial_conditions]]: not in play),
/// waiting at rest at their region's centre until the run inserts them.
void add_inflow_grains(SceneDraft& draft) {
  Model& model = draft.scene.model;
  State& state = draft.scene.state;
  InflowPlan& plan = draft.scene.inflow;
  plan.first_body = model.body_count();
  for (GrainSpec& g : draft.inflow_grains) {
    if (g.polyhedron) {
      add_polyhedron_grain(model, *g.polyhedron, g.material);
      g.polyhedron.reset();
    } else {
      add_sphere(model, g.radius, g.material);
    }
  }
  state.position.reserve(model.body_count());
  for (const InflowGrain& grain : plan.grains) {
    const Inflow& inflow = plan.inflows[static_cast<std::size_t>(grain.inflow)];
    state.position.push_back(0.5 * (inflow.region_min + inflow.region_max));
    state.orientation.push_back(Quat::Identity());
    state.velocity.push_back(Vec3::Zero());
    state.angular_velocity.push_back(Vec3::Zero());
  }
}

/// Grains first (bodies then generators, in file order), then walls, then the inflow grains.
void build(SceneDraft& draft) {
  Model& model = draft.scene.model;
  State& state = draft.scene.state;
  for (GrainSpec& g : draft.grains) {
    if (g.polyhedron) {
      add_polyhedron_grain(model, *g.polyhedron, g.material);
      // The model holds its own copy: drop the parser's at once, so that the next copy reuses
      // its memory and a scene never holds every shape twice (bench/RESULTS.md, memory per grain).
      g.polyhedron.reset();
    } else {
      add_sphere(model, g.radius, g.material);
    }
  }
  for (const WallSpec& w : draft.walls) {
    if (w.is_plane) {
      add_plane_wall(model, w.normal, w.material);
    } else {
      add_box_wall(model, w.half_extents, w.material);
    }
  }
  const std::size_t grains = draft.grains.size();
  state.resize(model.body_count());
  for (std::size_t i = 0; i < grains; ++i) {
    state.position[i] = draft.grains[i].position;
    state.orientation[i] = draft.grains[i].orientation;
    state.velocity[i] = draft.grains[i].velocity;
    state.angular_velocity[i] = draft.grains[i].angular_velocity;
  }
  for (std::size_t k = 0; k < draft.walls.size(); ++k) {
    state.position[grains + k] = draft.walls[k].position;
    state.orientation[grains + k] = draft.walls[k].orientation;
  }
  for (std::size_t i = 0; i < grains; ++i) {
    const int motion = draft.grains[i].motion;
    if (motion >= 0) drive_body(model, static_cast<int>(i), draft.grain_motions[static_cast<std::size_t>(motion)]);
  }
  for (std::size_t k = 0; k < draft.walls.size(); ++k) {
    if (draft.walls[k].motion) drive_body(model, static_cast<int>(grains + k), *draft.walls[k].motion);
  }
  set_prescribed_velocities(model, state);
  if (const auto k = apply_initial_conditions(model, draft.scene.initial_conditions, state)) {
    draft.root.fail(draft.condition_nodes[*k], "initial_conditions[" + std::to_string(*k) + "]",
                    "selects no grain (no free grain of its material has its centre in its region)");
  }
  add_inflow_grains(draft);
}

Scene parse(const std::string& file, const toml::table& root, const std::string& default_name) {
  SceneDraft draft(file, root);
  draft.root.allow_only(key_names(top_level_keys()), "at the top level");
  draft.scene.name = default_name;
  read_section_keys(draft.root, top_level_keys(), draft.scene);
  parse_time(draft);
  parse_solver(draft);
  parse_detection(draft);
  parse_gravity(draft);
  parse_output(draft);
  parse_materials(draft);
  parse_contact_laws(draft);
  parse_walls(draft);
  parse_bodies(draft);
  parse_generators(draft);
  parse_initial_conditions(draft);
  parse_inflows(draft);
  if (draft.grains.empty() && draft.inflow_grains.empty()) {
    draft.root.fail(nullptr, "",
                    "the scene has no grains: expected at least one [[bodies]], [[generators]] or [[inflow]] entry");
  }
  check_contact_law_coverage(draft);
  check_rotation_resistance_shapes(draft);
  check_walls_have_an_inside(draft);
  make_polyhedra(draft);
  finish_inflows(draft);
  check_grains_inside_walls(draft);
  check_grains_do_not_overlap(draft);
  build(draft);
  finish_time(draft);
  return std::move(draft.scene);
}

}  // namespace
}  // namespace scene_detail

Scene parse_scene(std::string_view toml_text, const std::string& source_name) {
  toml::table root;
  try {
    root = toml::parse(toml_text, source_name);
  } catch (const toml::parse_error& error) {
    throw SceneError(source_name, static_cast<int>(error.source().begin.line), "",
                     "TOML syntax error: " + std::string(error.description()));
  }
  std::string stem = std::filesystem::path(source_name).stem().string();
  if (stem.empty()) stem = "scene";
  return scene_detail::parse(source_name, root, stem);
}

Scene load_scene_file(const std::filesystem::path& path) {
  const std::string name = path.string();
  std::string text;
  try {
    // Regular files of at most 256 MiB (core/input_file.hpp): /dev/zero or a FIFO is refused.
    text = read_input_file(path, max_scene_file_bytes, "scene file");
  } catch (const InputFileError& e) {
    throw SceneError(name, 0, "", e.reason);
  }
  return parse_scene(text, name);
}

}  // namespace rubble
