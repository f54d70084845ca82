#pragma once
// A test-context helper: small scenes in a line, e.g.
//   TestScene s; s.uniform_gravity(); int floor = s.plane({0,0,0}, {0,0,1}); int ball = s.sphere(0.1, {0,0,0.1});
//   s.run(1.0);   // steps until t = 1 s
#include <cmath>

#include "core/model.hpp"
#include "core/state.hpp"
#include "simulation/step.hpp"
#include "support/rotation.hpp"

namespace rubble::testing {

/// A model, a state and step options built up body by body, then stepped.
struct TestScene {
  Model model;
  State state;
  StepOptions options;
  StepWorkspace workspace;
  StepReport last_report;

  /// One material "grain" (density in kg/m^3) and one contact law for every pair.
  explicit TestScene(double density = 2500.0, double friction = 0.0, double restitution = 0.0) {
    model.materials.push_back(Material{"grain", density});
    model.contact_laws.reset(1, ContactLaw{friction, restitution});
    options.integrator.time_step = 1e-4;
    options.solver.tolerance = 1e-10;
    options.solver.max_iterations = 2000;
  }
  /// Sets the contact law of every pair.
  void law(double friction, double restitution) { model.contact_laws.reset(1, ContactLaw{friction, restitution}); }
  /// Uniform gravity g along -z (m/s^2).
  void uniform_gravity(double g = 9.81) {
    options.gravity.kind = GravitySettings::Kind::uniform;
    options.gravity.acceleration = Vec3(0, 0, -g);
  }
  /// Uniform gravity of the given vector.
  void uniform_gravity(const Vec3& acceleration) {
    options.gravity.kind = GravitySettings::Kind::uniform;
    options.gravity.acceleration = acceleration;
  }
  /// A sphere grain at `position` with `velocity`; returns its body id.
  int sphere(double radius, const Vec3& position, const Vec3& velocity = Vec3::Zero()) {
    const int id = add_sphere(model, radius, 0);
    place(id, position, Quat::Identity(), velocity);
    return id;
  }
  /// A fixed plane wall through `point` with outward normal `normal`; returns its body id.
  int plane(const Vec3& point, const Vec3& normal) {
    const int id = add_plane_wall(model, Vec3::UnitZ(), 0);
    place(id, point, rotation_between(Vec3::UnitZ(), normal), Vec3::Zero());
    return id;
  }
  /// A fixed box wall centred at `centre` with `half_extents` and `orientation`; returns its id.
  int box_wall(const Vec3& centre, const Vec3& half_extents, const Quat& orientation = Quat::Identity()) {
    const int id = add_box_wall(model, half_extents, 0);
    place(id, centre, orientation, Vec3::Zero());
    return id;
  }
  /// Makes body `id` a driven body with a constant velocity and angular velocity (infinite mass).
  void drive(int id, const Vec3& velocity, const Vec3& angular_velocity = Vec3::Zero()) {
    drive(id, PrescribedMotion{{state.time}, {velocity}, {angular_velocity}});
  }
  /// Makes body `id` a driven body moving with `motion`.
  void drive(int id, PrescribedMotion motion) {
    drive_body(model, id, std::move(motion));
    set_prescribed_velocities(model, state);
  }
  /// Sets the pose and velocity of a body already in the model.
  void place(int id, const Vec3& position, const Quat& orientation, const Vec3& velocity,
             const Vec3& angular_velocity = Vec3::Zero()) {
    const auto b = static_cast<std::size_t>(id);
    if (state.body_count() < model.body_count()) {
      State grown = state;
      grown.resize(model.body_count());
      for (std::size_t i = 0; i < state.body_count(); ++i) {
        grown.position[i] = state.position[i];
        grown.orientation[i] = state.orientation[i];
        grown.velocity[i] = state.velocity[i];
        grown.angular_velocity[i] = state.angular_velocity[i];
      }
      grown.time = state.time;
      grown.step = state.step;
      state = std::move(grown);
    }
    state.position[b] = position;
    state.orientation[b] = orientation;
    state.velocity[b] = velocity;
    state.angular_velocity[b] = angular_velocity;
  }
  /// One step.
  const StepReport& advance() {
    last_report = rubble::step(model, state, workspace, options);
    return last_report;
  }
  /// Steps until t >= end_time (within half a step).
  void run(double end_time) {
    while (state.time < end_time - 0.5 * options.integrator.time_step) advance();
  }
  /// Steps `count` times.
  void steps(long count) {
    for (long k = 0; k < count; ++k) advance();
  }
};

}  // namespace rubble::testing
