// The scene file's settings sections: [time], [solver], [detection], [gravity] and [output]
// (docs/scene-file.md). [solver], [detection] and [output] are read from their key tables
// (scene_keys.hpp).
#include <limits>
#include <stdexcept>

#include "core/units.hpp"
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

/// The thresholds of the at-rest watcher (run_control.hpp); each "auto" or absent one is set by
/// finish_time once the grains are known.
void parse_rest_criterion(const TableReader& time, RunOptions& run) {
  for (const std::string_view key :
       {"rest_speed", "rest_quantile", "rest_coordination_change", "rest_contact_change", "rest_duration"}) {
    if (time.has(key) && !run.until_rest) {
      time.fail_key(key, "only used with until = \"rest\" (expected that key too, or no " + std::string(key) + ")");
    }
  }
  run.automatic_rest_speed = is_auto(time, "rest_speed") || !time.has("rest_speed");
  if (!run.automatic_rest_speed) run.rest.speed = time.number("rest_speed", positive());
  run.rest.quantile = time.number_or("rest_quantile", auto_rest_quantile, Range{0.0, 1.0, false, true});
  run.automatic_rest_coordination_change =
      is_auto(time, "rest_coordination_change") || !time.has("rest_coordination_change");
  if (!run.automatic_rest_coordination_change) {
    run.rest.coordination_change = time.number("rest_coordination_change", non_negative());
  }
  run.rest.contact_change = time.number_or("rest_contact_change", auto_rest_contact_change, closed(0.0, 1.0));
  run.automatic_rest_duration = is_auto(time, "rest_duration") || !time.has("rest_duration");
  if (!run.automatic_rest_duration) run.rest.duration = time.number("rest_duration", non_negative());
}

/// [gravity] type = "direct" or "tree": self-gravity (gravity/), held for evaluate_every steps.
void parse_self_gravity(const TableReader& table, bool tree, GravitySettings& gravity) {
  if (tree) {
    table.allow_only(
        {"type", "G", "softening", "theta", "order", "leaf_size", "group_size", "evaluate_every", "backend"},
        "for [gravity] type = \"tree\"");
  } else {
    table.allow_only({"type", "G", "softening", "evaluate_every", "backend"}, "for [gravity] type = \"direct\"");
  }
  // Held field between evaluations (external_forces.cpp); capped so a typo cannot freeze gravity for a run.
  gravity.evaluate_every = static_cast<int>(table.integer_or("evaluate_every", 1, 1, 1'000'000));
  gravity.kind = GravitySettings::Kind::self;
  auto& self = gravity.self_gravity;
  self.method = tree ? gravity::Method::tree : gravity::Method::direct;
  self.G = table.number_or("G", units::gravitational_constant, positive());
  const double softening = table.number_or("softening", 0.0, non_negative());
  self.softening.kind = softening > 0.0 ? gravity::Softening::Kind::plummer : gravity::Softening::Kind::none;
  self.softening.length = softening;
  if (tree) {
    self.theta = table.number_or("theta", self.theta, Range{0.0, 2.0, false, true});
    self.order = static_cast<int>(table.integer_or("order", self.order, 1, 2));
    self.leaf_size = static_cast<int>(table.integer_or("leaf_size", self.leaf_size, 1, 1'000'000));
    self.group_size = static_cast<int>(table.integer_or("group_size", self.group_size, 1, 1'000'000));
  }
  // A GPU backend that cannot run here is refused now, at its line, not at the first step.
  if (table.optional_choice("backend", {"cpu", "cuda"}).value_or("cpu") == "cuda") {
    self.backend = gravity::Backend::cuda;
    const std::string reason = gravity::backend_unavailable_reason(self);
    if (!reason.empty()) table.fail_key("backend", "\"cuda\" cannot run here: " + reason);
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
  time->allow_only({"dt", "theta", "end_time", "until", "rest_speed", "rest_quantile", "rest_coordination_change",
                    "rest_contact_change", "rest_duration"},
                   "in [time]");
  auto& integrator = draft.scene.run.step.integrator;
  RunOptions& run = draft.scene.run;
  run.automatic_time_step = is_auto(*time, "dt");
  if (!run.automatic_time_step) integrator.time_step = time->number("dt", positive());
  integrator.theta = time->number_or("theta", 0.5, closed(0.5, 1.0));
  run.end_time = time->number("end_time", positive());
  run.until_rest = time->optional_choice("until", {"end_time", "rest"}).value_or("end_time") == "rest";
  parse_rest_criterion(*time, run);
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
  if (type == "none") {
    table->allow_only({"type"}, "for [gravity] type = \"none\"");
    gravity.kind = GravitySettings::Kind::none;
  } else if (type == "uniform") {
    table->allow_only({"type", "acceleration"}, "for [gravity] type = \"uniform\"");
    gravity.kind = GravitySettings::Kind::uniform;
    gravity.acceleration = table->vec3("acceleration");
  } else if (type == "central") {
    // A fixed point mass (step.hpp, CentralField): Plummer-softened Kepler field.
    table->allow_only({"type", "centre", "mass", "G", "softening"}, "for [gravity] type = \"central\"");
    gravity.kind = GravitySettings::Kind::central;
    auto& central = gravity.central;
    central.centre = table->vec3("centre", coordinate());
    central.mass = table->number("mass", positive());
    central.G = table->number_or("G", units::gravitational_constant, positive());
    central.softening = table->number_or("softening", 0.0, non_negative());
  } else {
    parse_self_gravity(*table, type == "tree", gravity);
  }
}

void parse_output(SceneDraft& draft) {
  const auto output = draft.root.optional_table("output");
  if (!output) return;
  output->allow_only(key_names(output_keys()), "in [output]");
  read_section_keys(*output, output_keys(), draft.scene.run.output);
}

}  // namespace rubble::scene_detail
