// scene_to_toml: a scene written back as scene-file text, every grain and wall explicit
// (docs/scene-file.md). Numbers are written as the shortest text that reads back to the same
// double, so that parse_scene(scene_to_toml(s)) gives back s bit for bit (tests/scene/).
#include <cstdio>
#include <sstream>
#include <stdexcept>

#include "simulation/scene_file.hpp"
#include "simulation/scene_keys.hpp"

namespace rubble {

namespace {

using scene_detail::format_number;
using scene_detail::format_vec3;
using scene_detail::GrainSpec;
using scene_detail::toml_string;
using scene_detail::WallSpec;

/// The keys of a driven body's prescribed motion (a constant one as velocity and
/// angular_velocity, a table as motion = [[t, vx, vy, vz, wx, wy, wz], ...]), or of a free
/// grain's velocities; each line ends with a newline.
std::string motion_keys(const Model& model, const State& state, std::size_t body) {
  std::string out;
  if (model.is_driven(body) && model.is_grain(body)) out += "driven = true\n";
  if (!model.is_driven(body) ||
      model.prescribed_motions[static_cast<std::size_t>(model.motion_of_body[body])].time.size() == 1) {
    const RigidVelocity v = model.is_driven(body) ? model.driven_velocity(body, state.time)
                                                  : RigidVelocity{state.velocity[body], state.angular_velocity[body]};
    if (!model.is_grain(body) && v.linear == Vec3::Zero() && v.angular == Vec3::Zero()) return out;
    return out + "velocity = " + format_vec3(v.linear) + "\nangular_velocity = " + format_vec3(v.angular) + "\n";
  }
  const PrescribedMotion& motion = model.prescribed_motions[static_cast<std::size_t>(model.motion_of_body[body])];
  out += "motion = [";
  for (std::size_t k = 0; k < motion.time.size(); ++k) {
    const Vec3& v = motion.velocity[k];
    const Vec3& w = motion.angular_velocity[k];
    out += (k ? ",\n  [" : "\n  [") + format_number(motion.time[k]);
    for (int i = 0; i < 3; ++i) out += ", " + format_number(v[i]);
    for (int i = 0; i < 3; ++i) out += ", " + format_number(w[i]);
    out += "]";
  }
  return out + "\n]\n";
}

/// The [gravity] type whose keys `gravity` has.
std::string_view gravity_type(const GravitySettings& gravity) {
  switch (gravity.kind) {
    case GravitySettings::Kind::none:
      return "none";
    case GravitySettings::Kind::uniform:
      return "uniform";
    case GravitySettings::Kind::self:
      return gravity.self_gravity.method == gravity::Method::tree ? "tree" : "direct";
    case GravitySettings::Kind::central:
      break;
  }
  return "central";
}

void write_materials_and_laws(std::ostream& out, const Model& model) {
  for (const Material& material : model.materials) {
    out << "\n[[materials]]\n";
    scene_detail::write_section_keys(out, scene_detail::material_keys(), scene_detail::MaterialEntry{material});
  }
  const auto material_name = [&](int id) { return toml_string(model.materials[static_cast<std::size_t>(id)].name); };
  const int n = model.contact_laws.material_count;
  for (int a = 0; a < n; ++a) {
    for (int b = a; b < n; ++b) {
      const ContactLaw& law = model.contact_laws.get(a, b);
      out << "\n[[contact_laws]]\nmaterials = [" << material_name(a) << ", " << material_name(b) << "]\n";
      scene_detail::write_section_keys(out, scene_detail::contact_law_keys(), law);
    }
  }
}

/// Body-frame vertices and faces (the shape's principal frame, centroid at the origin), so
/// position and orientation are the state's. Merged faces may be bent by up to the generator's
/// merge angle, hence the convexity tolerance.
void write_polyhedron(std::ostream& out, const Model& model, const State& state, std::size_t body) {
  const ConvexPolyhedron& shape = model.polyhedra[static_cast<std::size_t>(model.shape_index[body])];
  GrainSpec grain;
  grain.position = state.position[body];
  grain.orientation = state.orientation[body];
  out << "\n[[bodies]]\n";
  scene_detail::write_section_keys(out, scene_detail::polyhedron_body_keys("vertices"), grain);
  out << motion_keys(model, state, body) << "convexity_tolerance = 0.05\nvertices = [";
  for (std::size_t v = 0; v < shape.vertices.size(); ++v) out << (v ? ", " : "") << format_vec3(shape.vertices[v]);
  out << "]\nfaces = [";
  for (std::size_t f = 0; f < shape.faces.size(); ++f) {
    out << (f ? ", [" : "[");
    for (std::size_t k = 0; k < shape.faces[f].size(); ++k) out << (k ? ", " : "") << shape.faces[f][k];
    out << "]";
  }
  out << "]\n";
}

void write_body(std::ostream& out, const Model& model, const State& state, std::size_t body) {
  const auto index = static_cast<std::size_t>(model.shape_index[body]);
  WallSpec wall;
  wall.position = state.position[body];
  wall.orientation = state.orientation[body];
  switch (model.shape_kind[body]) {
    case ShapeKind::plane:
      wall.normal = state.orientation[body] * model.planes[index].normal;
      out << "\n[[walls]]\n";
      scene_detail::write_section_keys(out, scene_detail::wall_keys("plane"), wall);
      out << motion_keys(model, state, body);
      break;
    case ShapeKind::box:
      wall.half_extents = model.boxes[index].half_extents;
      out << "\n[[walls]]\n";
      scene_detail::write_section_keys(out, scene_detail::wall_keys("box"), wall);
      out << motion_keys(model, state, body);
      break;
    case ShapeKind::sphere: {
      GrainSpec grain;
      grain.radius = model.spheres[index].radius;
      grain.position = state.position[body];
      grain.orientation = state.orientation[body];
      out << "\n[[bodies]]\n";
      scene_detail::write_section_keys(out, scene_detail::sphere_body_keys(), grain);
      out << motion_keys(model, state, body);
      break;
    }
    case ShapeKind::polyhedron:
      write_polyhedron(out, model, state, body);
      break;
  }
  out << "material = " << toml_string(model.materials[static_cast<std::size_t>(model.material[body])].name) << "\n";
}

}  // namespace

std::string scene_to_toml(const Scene& scene) {
  if (scene.inflow.active()) {
    throw std::invalid_argument(
        "a scene with [[inflow]] entries cannot be written back with every grain explicit "
        "(its inflow grains are not placed yet): keep its file");
  }
  const Model& model = scene.model;
  const RunOptions& run = scene.run;
  std::ostringstream out;
  out << "# rubble scene file (written by rubble). Reference: docs/scene-file.md\n";
  scene_detail::write_section_keys(out, scene_detail::top_level_keys(), scene);
  out << "\n[time]\n";
  scene_detail::write_section_keys(out, scene_detail::time_keys(), run);
  out << "\n[solver]\n";
  scene_detail::write_section_keys(out, scene_detail::solver_keys(), run.step.solver);
  out << "\n[detection]\n";
  scene_detail::write_section_keys(out, scene_detail::detection_keys(), run.step.detection);
  out << "\n[gravity]\n";
  scene_detail::write_section_keys(out, scene_detail::gravity_keys(gravity_type(run.step.gravity)), run.step.gravity);
  out << "\n[output]\n";
  scene_detail::write_section_keys(out, scene_detail::output_keys(), run.output);
  write_materials_and_laws(out, model);
  for (std::size_t body = 0; body < model.body_count(); ++body) write_body(out, model, scene.state, body);
  return out.str();
}

}  // namespace rubble
