#include "simulation/inflow.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <random>

#include "preprocessing/packing.hpp"

namespace rubble {
namespace {

/// A body's bounding ball, for the overlap test of a candidate position.
struct Ball {
  Vec3 centre = Vec3::Zero();
  double radius = 0.0;
};

/// What a candidate must not overlap: the bounding balls of the grains in play near the region
/// and every wall in play.
struct Obstacles {
  std::vector<Ball> grains;
  std::vector<std::size_t> walls;
};

/// Distance from `x` to the region box (0 inside).
double distance_to_box(const Vec3& x, const Vec3& low, const Vec3& high) {
  return (x.cwiseMax(low).cwiseMin(high) - x).norm();
}

Obstacles obstacles_near(const Model& in_play, const State& state, const Inflow& inflow, double reach) {
  Obstacles obstacles;
  for (std::size_t b = 0; b < in_play.body_count(); ++b) {
    if (!in_play.is_grain(b)) {
      obstacles.walls.push_back(b);
    } else if (distance_to_box(state.position[b], inflow.region_min, inflow.region_max) <
               in_play.bounding_radius[b] + reach) {
      obstacles.grains.push_back({state.position[b], in_play.bounding_radius[b]});
    }
  }
  return obstacles;
}

/// Whether a ball of `radius` at `x` stays clear of wall `b`: outside a plane's solid half-space
/// (behind the plane) and outside a solid box.
bool clear_of_wall(const Model& model, const State& state, std::size_t b, const Vec3& x, double radius) {
  const Vec3 local = state.orientation[b].conjugate() * (x - state.position[b]);
  const int shape = model.shape_index[b];
  if (model.shape_kind[b] == ShapeKind::plane) {
    return model.planes[static_cast<std::size_t>(shape)].normal.dot(local) >= radius;
  }
  const Vec3 half = model.boxes[static_cast<std::size_t>(shape)].half_extents;
  return distance_to_box(local, -half, half) >= radius;
}

bool clear(const Model& model, const State& state, const Obstacles& obstacles, const Vec3& x, double radius) {
  for (const Ball& ball : obstacles.grains) {
    if ((ball.centre - x).squaredNorm() < (ball.radius + radius) * (ball.radius + radius)) return false;
  }
  for (const std::size_t wall : obstacles.walls) {
    if (!clear_of_wall(model, state, wall, x, radius)) return false;
  }
  return true;
}

/// A uniformly distributed rotation (Shoemake 1992, "Uniform random rotations").
Quat uniform_orientation(std::mt19937_64& rng) {
  const double u1 = uniform_01(rng), u2 = uniform_01(rng), u3 = uniform_01(rng);
  const double a = std::sqrt(1.0 - u1), b = std::sqrt(u1);
  const double tau = 2.0 * std::numbers::pi;
  return Quat(b * std::cos(tau * u3), a * std::sin(tau * u2), a * std::cos(tau * u2), b * std::sin(tau * u3));
}

/// Appends body `b` of `model` to its prefix `in_play`.
void append_body(const Model& model, std::size_t b, Model& in_play) {
  in_play.shape_kind.push_back(model.shape_kind[b]);
  in_play.shape_index.push_back(model.shape_index[b]);
  in_play.material.push_back(model.material[b]);
  in_play.mass.push_back(model.mass[b]);
  in_play.inverse_mass.push_back(model.inverse_mass[b]);
  in_play.principal_inertia.push_back(model.principal_inertia[b]);
  in_play.inverse_inertia.push_back(model.inverse_inertia[b]);
  in_play.bounding_radius.push_back(model.bounding_radius[b]);
  in_play.volume.push_back(model.volume[b]);
  in_play.motion_of_body.push_back(b < model.motion_of_body.size() ? model.motion_of_body[b] : -1);
}

}  // namespace

std::size_t InflowPlan::due_count(double time) const {
  const auto after = std::upper_bound(grains.begin(), grains.end(), time,
                                      [](double t, const InflowGrain& grain) { return t < grain.due_time; });
  return static_cast<std::size_t>(after - grains.begin());
}

State state_with_waiting_bodies(const State& in_play, std::size_t body_count) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const Vec3 unknown(nan, nan, nan);
  State whole = in_play;
  whole.position.resize(body_count, unknown);
  whole.orientation.resize(body_count, Quat(nan, nan, nan, nan));
  whole.velocity.resize(body_count, unknown);
  whole.angular_velocity.resize(body_count, unknown);
  return whole;
}

InflowInsertion insert_due_grains(const InflowPlan& plan, const Model& model, Model& in_play, State& state) {
  InflowInsertion result;
  const std::size_t due = plan.due_count(state.time);
  if (in_play.body_count() >= plan.first_body + due) return result;
  // Obstacles are gathered once per inflow and pass (O(N)); grains placed in the pass join them.
  std::vector<std::optional<Obstacles>> obstacles(plan.inflows.size());
  double reach = 0.0;  // the largest bounding radius of an inflow grain
  for (std::size_t b = plan.first_body; b < model.body_count(); ++b) reach = std::max(reach, model.bounding_radius[b]);
  while (in_play.body_count() < plan.first_body + due) {
    const std::size_t body = in_play.body_count();
    const InflowGrain& grain = plan.grains[body - plan.first_body];
    const Inflow& inflow = plan.inflows[static_cast<std::size_t>(grain.inflow)];
    std::optional<Obstacles>& near = obstacles[static_cast<std::size_t>(grain.inflow)];
    if (!near) near = obstacles_near(in_play, state, inflow, reach);
    std::mt19937_64 rng(derive_seed(derive_seed(inflow.seed, grain.ordinal), static_cast<std::uint64_t>(state.step)));
    const double radius = model.bounding_radius[body];
    bool placed = false;
    Vec3 x = Vec3::Zero();
    for (int attempt = 0; attempt < inflow.attempts && !placed; ++attempt) {
      for (int axis = 0; axis < 3; ++axis) {
        x[axis] = inflow.region_min[axis] + uniform_01(rng) * (inflow.region_max[axis] - inflow.region_min[axis]);
      }
      placed = clear(model, state, *near, x, radius);
    }
    if (!placed) {
      result.waiting = plan.first_body + due - body;
      result.blocked_body = body;
      return result;
    }
    append_body(model, body, in_play);
    state.position.push_back(x);
    state.orientation.push_back(model.shape_kind[body] == ShapeKind::polyhedron ? uniform_orientation(rng)
                                                                                : Quat::Identity());
    state.velocity.push_back(inflow.velocity);
    state.angular_velocity.push_back(Vec3::Zero());
    near->grains.push_back({x, radius});
    // The other inflows' regions may overlap this one: their obstacles get the grain too.
    for (std::size_t i = 0; i < obstacles.size(); ++i) {
      if (static_cast<int>(i) != grain.inflow && obstacles[i]) obstacles[i]->grains.push_back({x, radius});
    }
    ++result.placed;
  }
  return result;
}

}  // namespace rubble
