#include "core/model.hpp"

#include <algorithm>
#include <limits>
#include <numbers>
#include <stdexcept>

namespace rubble {
namespace {

int push_body(Model& model, ShapeKind kind, int shape_index, int material, double mass, const Vec3& inertia,
              double bounding_radius, double volume) {
  model.shape_kind.push_back(kind);
  model.shape_index.push_back(shape_index);
  model.material.push_back(material);
  model.mass.push_back(mass);
  model.inverse_mass.push_back(mass > 0.0 ? 1.0 / mass : 0.0);
  model.principal_inertia.push_back(inertia);
  model.inverse_inertia.push_back(mass > 0.0 ? Vec3(inertia.cwiseInverse()) : Vec3::Zero());
  model.bounding_radius.push_back(bounding_radius);
  model.volume.push_back(volume);
  model.motion_of_body.push_back(-1);
  return static_cast<int>(model.shape_kind.size()) - 1;
}

double density_of(const Model& model, int material) {
  if (material < 0 || material >= static_cast<int>(model.materials.size())) {
    throw std::invalid_argument("material id out of range");
  }
  return model.materials[static_cast<std::size_t>(material)].density;
}

}  // namespace

int add_sphere(Model& model, double radius, int material) {
  const double volume = 4.0 / 3.0 * std::numbers::pi * radius * radius * radius;
  const double mass = density_of(model, material) * volume;
  const double inertia = 0.4 * mass * radius * radius;  // solid ball: I = 2/5 m r^2
  model.spheres.push_back(Sphere{radius});
  return push_body(model, ShapeKind::sphere, static_cast<int>(model.spheres.size()) - 1, material, mass,
                   Vec3::Constant(inertia), radius, volume);
}

int add_plane_wall(Model& model, const Vec3& normal, int material) {
  model.planes.push_back(Plane{normal.normalized()});
  return push_body(model, ShapeKind::plane, static_cast<int>(model.planes.size()) - 1, material, 0.0, Vec3::Zero(),
                   std::numeric_limits<double>::infinity(), 0.0);
}

int add_box_wall(Model& model, const Vec3& half_extents, int material) {
  model.boxes.push_back(Box{half_extents});
  return push_body(model, ShapeKind::box, static_cast<int>(model.boxes.size()) - 1, material, 0.0, Vec3::Zero(),
                   half_extents.norm(), 0.0);
}

int add_polyhedron(Model& model, ConvexPolyhedron shape, double volume, const Vec3& principal_inertia_per_density,
                   int material) {
  const double density = density_of(model, material);
  double bounding_radius = 0.0;
  for (const Vec3& v : shape.vertices) bounding_radius = std::max(bounding_radius, v.norm());
  model.polyhedra.push_back(std::move(shape));
  return push_body(model, ShapeKind::polyhedron, static_cast<int>(model.polyhedra.size()) - 1, material,
                   density * volume, density * principal_inertia_per_density, bounding_radius, volume);
}

RigidVelocity prescribed_velocity(const PrescribedMotion& motion, double time) {
  const std::vector<double>& t = motion.time;
  if (t.size() == 1 || time <= t.front()) return {motion.velocity.front(), motion.angular_velocity.front()};
  if (time >= t.back()) return {motion.velocity.back(), motion.angular_velocity.back()};
  // The knot interval holding `time`: t[k - 1] <= time < t[k].
  const auto k = static_cast<std::size_t>(std::upper_bound(t.begin(), t.end(), time) - t.begin());
  const double s = (time - t[k - 1]) / (t[k] - t[k - 1]);
  return {(1.0 - s) * motion.velocity[k - 1] + s * motion.velocity[k],
          (1.0 - s) * motion.angular_velocity[k - 1] + s * motion.angular_velocity[k]};
}

void drive_body(Model& model, int body, PrescribedMotion motion) {
  if (body < 0 || static_cast<std::size_t>(body) >= model.body_count())
    throw std::invalid_argument("body id out of range");
  const std::size_t knots = motion.time.size();
  if (knots == 0 || motion.velocity.size() != knots || motion.angular_velocity.size() != knots) {
    throw std::invalid_argument("a prescribed motion needs one velocity and one angular velocity per knot");
  }
  for (std::size_t k = 1; k < knots; ++k) {
    if (!(motion.time[k] > motion.time[k - 1])) throw std::invalid_argument("the knots' times must increase");
  }
  const auto b = static_cast<std::size_t>(body);
  if (model.is_driven(b)) throw std::invalid_argument("body already driven");
  model.mass[b] = 0.0;
  model.inverse_mass[b] = 0.0;
  model.principal_inertia[b] = Vec3::Zero();
  model.inverse_inertia[b] = Vec3::Zero();
  model.motion_of_body[b] = static_cast<int>(model.prescribed_motions.size());
  model.prescribed_motions.push_back(std::move(motion));
  model.driven_bodies.insert(std::upper_bound(model.driven_bodies.begin(), model.driven_bodies.end(), b), b);
}

void set_prescribed_velocities(const Model& model, State& state) {
  for (const std::size_t b : model.driven_bodies) {
    const RigidVelocity v = model.driven_velocity(b, state.time);
    state.velocity[b] = v.linear;
    state.angular_velocity[b] = v.angular;
  }
}

namespace {

template <class T>
std::vector<T> first(const std::vector<T>& values, std::size_t n) {
  return std::vector<T>(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(std::min(n, values.size())));
}

}  // namespace

Model model_prefix(const Model& model, std::size_t bodies) {
  Model prefix = model;
  prefix.shape_kind = first(model.shape_kind, bodies);
  prefix.shape_index = first(model.shape_index, bodies);
  prefix.material = first(model.material, bodies);
  prefix.mass = first(model.mass, bodies);
  prefix.inverse_mass = first(model.inverse_mass, bodies);
  prefix.principal_inertia = first(model.principal_inertia, bodies);
  prefix.inverse_inertia = first(model.inverse_inertia, bodies);
  prefix.bounding_radius = first(model.bounding_radius, bodies);
  prefix.volume = first(model.volume, bodies);
  prefix.motion_of_body = first(model.motion_of_body, bodies);
  prefix.driven_bodies.clear();
  for (const std::size_t b : model.driven_bodies) {
    if (b < bodies) prefix.driven_bodies.push_back(b);
  }
  return prefix;
}

State state_prefix(const State& state, std::size_t bodies) {
  State prefix;
  prefix.time = state.time;
  prefix.step = state.step;
  prefix.position = first(state.position, bodies);
  prefix.orientation = first(state.orientation, bodies);
  prefix.velocity = first(state.velocity, bodies);
  prefix.angular_velocity = first(state.angular_velocity, bodies);
  return prefix;
}

}  // namespace rubble
