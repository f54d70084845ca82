#pragma once
// Inflow sources ([[inflow]] in a scene file): grains that enter the scene during the run, at a
// rate, in a box region, without overlapping anything there (a pour, a hopper feeding a pile).
//
// Every grain an inflow will ever insert is made when the scene is read (its shape, size and
// material drawn from the scene's seed) and numbered after the walls, in the order the grains
// are due. The bodies in play are therefore always a prefix of the model's bodies: the grains and
// walls of the scene, then the inflow grains inserted so far. The run loop steps a model and a
// state cut to that prefix, and inserting a grain appends one body to both. So no stage of the
// step knows about inflows (contact detection, gravity and the solver see only bodies in play),
// the arrays of a step keep their meaning, and a checkpoint (whose state is the prefix) restarts
// a pour bit for bit: the number of grains inserted is the state's body count.
//
// Insertion is random sequential addition, as DEM codes insert a pour (LIGGGHTS' fix
// insert/rate/region): grain k of inflow i is due at
// t_k = start_time + k / rate. Before each step, every grain due by the state's time is placed
// in turn at a uniformly random position in the region (orientation uniform too), rejecting a
// position whose bounding sphere overlaps the bounding sphere of a grain in play or a wall; after
// `attempts` rejections it waits for the next step, and the grains due after it (of every inflow)
// wait behind it, so that the bodies in play stay a prefix. The random draws of grain k at step n
// come from SplitMix64(seed, k, n): the result depends on neither the thread count nor on what
// was drawn before, and needs no generator state in a checkpoint.
#include <cstdint>
#include <vector>

#include "core/model.hpp"
#include "core/state.hpp"

namespace rubble {

/// One [[inflow]] entry (docs/scene-file.md).
struct Inflow {
  Vec3 region_min = Vec3::Zero();  ///< m, corner of the box grains appear in (their centres)
  Vec3 region_max = Vec3::Zero();  ///< m, the opposite corner
  double rate = 0.0;               ///< grains per second
  double start_time = 0.0;         ///< s, when grain 0 is due
  std::uint64_t count = 0;         ///< grains it inserts in all
  Vec3 velocity = Vec3::Zero();    ///< m/s, velocity of an inserted grain
  int attempts = 100;              ///< random positions tried per grain and step before it waits
  std::uint64_t seed = 0;          ///< of the insertion positions (derived from the scene's seed)
};

/// One inflow grain: which inflow inserts it, its number there, and when it is due.
struct InflowGrain {
  int inflow = 0;             ///< index into the scene's inflows
  std::uint64_t ordinal = 0;  ///< k: the k-th grain of its inflow
  double due_time = 0.0;      ///< s, start_time + k / rate
};

/// The inflows of a scene and their grains, which are the model's last bodies, in order of due time.
struct InflowPlan {
  std::vector<Inflow> inflows;      ///< the [[inflow]] entries, file order
  std::vector<InflowGrain> grains;  ///< body first_body + j is grains[j], sorted by (due_time, inflow, ordinal)
  std::size_t first_body = 0;       ///< body id of the first inflow grain (= bodies of the scene without inflow)

  /// Whether the scene has any inflow grain.
  bool active() const { return !grains.empty(); }
  /// The inflow grains due by `time` (s): the number that should be in play then.
  std::size_t due_count(double time) const;
};

// The model and state the step sees while the later inflow grains are not in play:
// model_prefix and state_prefix (core/model.hpp).

/// The state of the whole model: `in_play` followed by the bodies not inserted yet, whose
/// positions, velocities and orientations are NaN (a run file's snapshot: docs/output-format.md).
State state_with_waiting_bodies(const State& in_play, std::size_t body_count);

/// What one insertion pass did.
struct InflowInsertion {
  std::size_t placed = 0;   ///< grains inserted by this pass
  std::size_t waiting = 0;  ///< grains due but not in play after it (no room found)
  /// Body id of the first grain that could not be placed (meaningful when waiting > 0).
  std::size_t blocked_body = 0;
};

/// Inserts the inflow grains due by state.time: appends each to `in_play` (a prefix of `model`,
/// model_prefix) and to `state` at a random non-overlapping position in its inflow's region, with
/// the inflow's velocity and no spin. Stops at the first grain that finds no room.
InflowInsertion insert_due_grains(const InflowPlan& plan, const Model& model, Model& in_play, State& state);

}  // namespace rubble
