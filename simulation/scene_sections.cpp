// The scene file's settings sections: [time], [solver], [detection], [gravity] and [output]
// (docs/scene-file.md), read from their key tables (scene_keys.hpp); here, what spans several
// keys: dt against end_time, and what depends on the grains (dt = "auto", the rest criterion).
#include <stdexcept>

#include "simulation/run_control.hpp"
#include "simulation/scene_keys.hpp"
#include "simulation/scene_parser.hpp"

namespace rubble::scene_detail {

namespace {

/// dt against end_time: not longer, and not absurdly many steps.
void check_step_count(const SceneDraft& draft, const TableReader& time) {
  const auto& integrator = draft.scene.run.step.integrator;
  const std::string origin = draft.scene.run.automatic_time_step ? " (the automatic dt)" : "";
  // A guard against typos in the exponent (dt = 1e-40): more steps than any run can take
  // (the same bound holds --end-time, run_control.hpp).
  constexpr double max_steps = max_run_steps;
  if (draft.scene.run.end_time / integrator.time_step > max_steps) {
    time.fail_key("dt", "expected at most 10^12 steps (dt >= end_time / 1e12 = " +
                            show_short(draft.scene.run.end_time / max_steps) +
                            " s), got dt = " + show(integrator.time_step) + origin);
  }
  if (integrator.time_step > draft.scene.run.end_time) {
    time.fail_key("dt", "expected dt <= end_time (" + show(draft.scene.run.end_time) + " s), got " +
                            show(integrator.time_step) + origin);
  }
}

}  // namespace

void parse_time(SceneDraft& draft) {
  const auto time = draft.root.optional_table("time");
  if (!time) draft.root.fail(nullptr, "time", "missing required table [time] (expected dt and end_time, in s)");
  if (time->has("rest_kinetic_energy")) {
    // Scenes written before issue 18: the mean kinetic energy per grain declared rest while a few
    // grains still moved fast; the criterion is now on the grains' speeds, Z and contacts.
    time->fail_key("rest_kinetic_energy",
                   "replaced by rest_speed (m/s or \"auto\"): rest is now judged on the grains' speeds, the "
                   "coordination number and the contacts (docs/scene-file.md, \"Stopping at rest\")");
  }
  time->allow_only(key_names(time_keys()), "in [time]");
  RunOptions& run = draft.scene.run;
  read_section_keys(*time, time_keys(), run);
  if (!run.automatic_time_step) check_step_count(draft, *time);
}

void finish_time(SceneDraft& draft) {
  const auto time = draft.root.optional_table("time");
  RunOptions& run = draft.scene.run;
  if (run.automatic_time_step) {
    try {
      run.step.integrator.time_step =
          automatic_time_step(draft.scene.model, draft.scene.state, run.step.gravity).time_step;
    } catch (const std::invalid_argument& error) {
      time->fail_key("dt", error.what());
    }
    check_step_count(draft, *time);
  }
  if (run.until_rest) {
    const SceneScales scales = scene_scales(draft.scene.model, draft.scene.state, run.step.gravity);
    try {
      const RestCriterion given = run.rest;
      run.rest = automatic_rest_criterion(scales, run.automatic_rest_speed ? 0.0 : given.speed,
                                          run.automatic_rest_duration ? 0.0 : given.duration);
      run.rest.quantile = given.quantile;
      if (!run.automatic_rest_coordination_change) run.rest.coordination_change = given.coordination_change;
      run.rest.contact_change = given.contact_change;
      if (!run.automatic_rest_duration) run.rest.duration = given.duration;  // 0 is a valid duration
    } catch (const std::invalid_argument& error) {
      time->fail_key(run.automatic_rest_speed ? "rest_speed" : "rest_duration", error.what());
    }
  }
}

void parse_solver(SceneDraft& draft) {
  const auto solver = draft.root.optional_table("solver");
  if (!solver) return;
  solver->allow_only(key_names(solver_keys()), "in [solver]");
  read_section_keys(*solver, solver_keys(), draft.scene.run.step.solver);
}

void parse_detection(SceneDraft& draft) {
  const auto detection = draft.root.optional_table("detection");
  if (!detection) return;
  detection->allow_only(key_names(detection_keys()), "in [detection]");
  read_section_keys(*detection, detection_keys(), draft.scene.run.step.detection);
}

void parse_gravity(SceneDraft& draft) {
  auto& gravity = draft.scene.run.step.gravity;
  const auto table = draft.root.optional_table("gravity");
  if (!table) {
    gravity.kind = GravitySettings::Kind::none;
    return;
  }
  const std::string type = table->choice("type", {"none", "uniform", "direct", "tree", "central"});
  const auto& keys = gravity_keys(type);
  table->allow_only(key_names(keys), "for [gravity] type = \"" + type + "\"");
  if (type == "none") {
    gravity.kind = GravitySettings::Kind::none;
  } else if (type == "uniform") {
    gravity.kind = GravitySettings::Kind::uniform;
  } else if (type == "central") {
    gravity.kind = GravitySettings::Kind::central;
  } else {
    gravity.kind = GravitySettings::Kind::self;
    gravity.self_gravity.method = type == "tree" ? gravity::Method::tree : gravity::Method::direct;
  }
  read_section_keys(*table, keys, gravity);
}

void parse_output(SceneDraft& draft) {
  const auto output = draft.root.optional_table("output");
  if (!output) return;
  output->allow_only(key_names(output_keys()), "in [output]");
  read_section_keys(*output, output_keys(), draft.scene.run.output);
}

}  // namespace rubble::scene_detail
