#pragma once
// A scene: the model, the initial state and how to run it. What a scene file describes.
#include <cstdint>
#include <string>

#include "core/model.hpp"
#include "core/state.hpp"
#include "simulation/inflow.hpp"
#include "simulation/initial_conditions.hpp"
#include "simulation/run_control.hpp"
#include "simulation/step.hpp"

namespace rubble {

/// Where and how often the run writes its results.
struct OutputOptions {
  std::string directory = "rubble-output";  ///< output folder (created if missing)
  std::int64_t snapshot_every_steps = 0;    ///< write a state snapshot every N steps (0: use snapshot_interval)
  double snapshot_interval = 0.0;           ///< s of simulated time between snapshots (0: 100 snapshots per run)
  double progress_interval = 2.0;           ///< s of wall time between progress lines
  bool write_vtk = false;                   ///< also write a ParaView series
  /// Checkpoint retention: besides the newest two, keep the first checkpoint of every interval of
  /// this many steps (steps [0, N), [N, 2N), ...), so that a run can be restarted from an earlier
  /// step (`rubble run --resume DIR --from-step K`); 0: only the newest two.
  std::int64_t keep_checkpoint_every = 0;
};

/// How long to run and what to write, besides the step's own options.
struct RunOptions {
  StepOptions step{};     ///< integrator, detection, solver, gravity
  double end_time = 1.0;  ///< s of simulated time (with until_rest: the latest end)
  /// The scene asked for dt = "auto": step.integrator.time_step was set by automatic_time_step().
  bool automatic_time_step = false;
  /// [time] until = "rest": also stop as soon as the grains are at rest (RestDetector).
  bool until_rest = false;
  /// Thresholds and duration of "at rest" (set from the scene even when chosen automatically).
  RestCriterion rest{};
  bool automatic_rest_speed = true;                ///< rest.speed was chosen automatically
  bool automatic_rest_coordination_change = true;  ///< rest.coordination_change was chosen automatically
  bool automatic_rest_duration = true;             ///< rest.duration was chosen automatically
  OutputOptions output{};                          ///< output folder and cadence
  std::uint64_t seed = 1;                          ///< seed of every random generator the scene uses
};

/// A complete scene: immutable model, initial state, run options.
struct Scene {
  std::string name = "scene";  ///< from the file name or the scene's `name` key
  Model model;                 ///< shapes, masses, materials, contact laws
  State state;                 ///< initial positions and velocities
  RunOptions run;              ///< time stepping, solver, output
  /// The scene's [[initial_conditions]], already applied to `state`; kept to be applied again to
  /// the state a branch starts from (`rubble run SCENE --from RUN`).
  std::vector<InitialCondition> initial_conditions;
  /// The scene's [[inflow]] sources and their grains, the model's last bodies (after the walls),
  /// not in play until inserted during the run (simulation/inflow.hpp). In `state` they wait at
  /// their region's centre at rest; `rubble run` steps only the bodies in play.
  InflowPlan inflow;
};

}  // namespace rubble
