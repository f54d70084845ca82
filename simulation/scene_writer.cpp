// scene_to_toml: a scene written back as scene-file text, every grain and wall explicit
// (docs/scene-file.md). Numbers are written as the shortest text that reads back to the same
// double, so that parse_scene(scene_to_toml(s)) gives back s bit for bit (tests/scene/).
#include <cstdio>
#include <sstream>

#include "simulation/scene_file.hpp"
#include "simulation/scene_keys.hpp"
#include "simulation/scene_reader.hpp"

namespace rubble {

namespace {

using scene_detail::format_number;
using scene_detail::format_vec3;
using scene_detail::toml_string;

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

std::string toml_quaternion(const Quat& q) {
  // Appended piece by piece: `"[" + std::string` trips GCC 12's -Wrestrict false positive here.
  std::string text = "[";
  text.append(format_number(q.w())).append(", ").append(format_number(q.x())).append(", ");
  text.append(format_number(q.y())).append(", ").append(format_number(q.z())).append("]");
  return text;
}

/// A number, or "auto" when the scene asked for the automatic value.
std::string number_or_auto(bool automatic, double x) { return automatic ? std::string("\"auto\"") : format_number(x); }

void write_time(std::ostream& out, const RunOptions& run) {
  out << "[time]\n";
  out << "dt = " << number_or_auto(run.automatic_time_step, run.step.integrator.time_step) << "\n";
  out << "theta = " << format_number(run.step.integrator.theta) << "\n";
  out << "end_time = " << format_number(run.end_time) << "\n";
  if (run.until_rest) {
    out << "until = \"rest\"\n";
    out << "rest_speed = " << number_or_auto(run.automatic_rest_speed, run.rest.speed) << "\n";
    out << "rest_quantile = " << format_number(run.rest.quantile) << "\n";
    out << "rest_coordination_change = "
        << number_or_auto(run.automatic_rest_coordination_change, run.rest.coordination_change) << "\n";
    out << "rest_contact_change = " << format_number(run.rest.contact_change) << "\n";
    out << "rest_duration = " << number_or_auto(run.automatic_rest_duration, run.rest.duration) << "\n";
  }
  out << "\n";
}

void write_self_gravity(std::ostream& out, const GravitySettings& gravity) {
  const gravity::GravityOptions& self = gravity.self_gravity;
  const bool tree = self.method == gravity::Method::tree;
  out << "type = \"" << (tree ? "tree" : "direct") << "\"\n";
  out << "G = " << format_number(self.G) << "\n";
  out << "softening = "
      << format_number(self.softening.kind == gravity::Softening::Kind::plummer ? self.softening.length : 0.0) << "\n";
  if (tree) {
    out << "theta = " << format_number(self.theta) << "\n";
    out << "order = " << self.order << "\n";
    out << "leaf_size = " << self.leaf_size << "\n";
    out << "group_size = " << self.group_size << "\n";
  }
  if (self.backend != gravity::Backend::cpu) out << "backend = \"" << gravity::to_string(self.backend) << "\"\n";
  if (gravity.evaluate_every != 1) out << "evaluate_every = " << gravity.evaluate_every << "\n";
  out << "\n";
}

void write_gravity(std::ostream& out, const GravitySettings& gravity) {
  out << "[gravity]\n";
  switch (gravity.kind) {
    case GravitySettings::Kind::none:
      out << "type = \"none\"\n\n";
      break;
    case GravitySettings::Kind::uniform:
      out << "type = \"uniform\"\nacceleration = " << format_vec3(gravity.acceleration) << "\n\n";
      break;
    case GravitySettings::Kind::self:
      write_self_gravity(out, gravity);
      break;
    case GravitySettings::Kind::central: {
      const CentralField& central = gravity.central;
      out << "type = \"central\"\n";
      out << "centre = " << format_vec3(central.centre) << "\n";
      out << "mass = " << format_number(central.mass) << "\n";
      out << "G = " << format_number(central.G) << "\n";
      out << "softening = " << format_number(central.softening) << "\n\n";
      break;
    }
  }
}

void write_materials_and_laws(std::ostream& out, const Model& model) {
  for (const Material& material : model.materials) {
    out << "\n[[materials]]\nname = " << toml_string(material.name) << "\ndensity = " << format_number(material.density)
        << "\n";
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
  out << "\n[[bodies]]\nshape = \"polyhedron\"\nposition = " << format_vec3(state.position[body])
      << "\norientation = " << toml_quaternion(state.orientation[body]) << "\n"
      << motion_keys(model, state, body) << "convexity_tolerance = 0.05\nvertices = [";
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
  switch (model.shape_kind[body]) {
    case ShapeKind::plane:
      out << "\n[[walls]]\ntype = \"plane\"\npoint = " << format_vec3(state.position[body])
          << "\nnormal = " << format_vec3(state.orientation[body] * model.planes[index].normal) << "\n";
      out << motion_keys(model, state, body);
      break;
    case ShapeKind::box:
      out << "\n[[walls]]\ntype = \"box\"\ncenter = " << format_vec3(state.position[body])
          << "\nhalf_extents = " << format_vec3(model.boxes[index].half_extents) << "\n";
      if (state.orientation[body].coeffs() != Quat::Identity().coeffs()) {
        out << "orientation = " << toml_quaternion(state.orientation[body]) << "\n";
      }
      out << motion_keys(model, state, body);
      break;
    case ShapeKind::sphere:
      out << "\n[[bodies]]\nshape = \"sphere\"\nradius = " << format_number(model.spheres[index].radius)
          << "\nposition = " << format_vec3(state.position[body]);
      if (state.orientation[body].coeffs() != Quat::Identity().coeffs()) {
        out << "\norientation = " << toml_quaternion(state.orientation[body]);
      }
      out << "\n" << motion_keys(model, state, body);
      break;
    case ShapeKind::polyhedron:
      write_polyhedron(out, model, state, body);
      break;
  }
  out << "material = " << toml_string(model.materials[static_cast<std::size_t>(model.material[body])].name) << "\n";
}

}  // namespace

std::string scene_to_toml(const Scene& scene) {
  const Model& model = scene.model;
  const RunOptions& run = scene.run;
  std::ostringstream out;
  out << "# rubble scene file (written by rubble). Reference: docs/scene-file.md\n";
  out << "name = " << toml_string(scene.name) << "\n";
  out << "seed = " << static_cast<std::int64_t>(run.seed & 0x7FFFFFFFFFFFFFFFULL) << "\n\n";
  write_time(out, run);
  out << "[solver]\n";
  scene_detail::write_section_keys(out, scene_detail::solver_keys(), run.step.solver);
  out << "\n[detection]\n";
  scene_detail::write_section_keys(out, scene_detail::detection_keys(), run.step.detection);
  out << "\n";
  write_gravity(out, run.step.gravity);
  out << "[output]\n";
  scene_detail::write_section_keys(out, scene_detail::output_keys(), run.output);
  write_materials_and_laws(out, model);
  for (std::size_t body = 0; body < model.body_count(); ++body) write_body(out, model, scene.state, body);
  return out.str();
}

}  // namespace rubble
