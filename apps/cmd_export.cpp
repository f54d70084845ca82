// `rubble export RUN.h5 [--snapshot K] -o SCENE.toml`: a saved state of a run written as a scene
// file with every grain explicit (position, orientation, velocity, angular velocity), which anyone
// can edit and run (docs/checkpoints.md, "Branching"). Materials, contact laws, solver, gravity and
// output come from the run's scene; dt and the rest thresholds are the values the run used
// ("auto" resolved), so that the exported scene goes on as the run would.
#include <cmath>
#include <filesystem>
#include <fmt/format.h>
#include <iostream>

#include "apps/commands.hpp"
#include "core/input_error.hpp"
#include "postprocessing/run_reader.hpp"
#include "simulation/branch.hpp"
#include "simulation/scene_file.hpp"

namespace rubble::apps {
namespace {

struct ExportArguments {
  std::string run_file;        ///< RUN.h5 (or a run folder)
  std::int64_t snapshot = -1;  ///< which snapshot (negative: from the end)
  std::string output;          ///< SCENE.toml, or "-" for stdout
};

int bad_input(const std::string& message) {
  std::cerr << "rubble export: error: " << message << "\n";
  return exit_bad_input;
}

int export_command(const ExportArguments& args) {
  std::string text;
  try {
    BranchSource source;
    source.path = args.run_file;
    if (std::filesystem::is_directory(source.path)) source.path /= "run.h5";
    source.kind = BranchSource::Kind::snapshot;
    source.snapshot = args.snapshot;
    SavedState saved = load_saved_state(source);
    // The run options as the run parsed them (its scene text), the bodies as the run file holds them.
    Scene scene = parse_scene(saved.scene_text, source.path.string() + ":/scene");
    if (const auto mismatch = body_mismatch(scene.model, saved.model)) {
      return bad_input(
          fmt::format("{}: the run's scene text does not rebuild its bodies: {}", source.path.string(), *mismatch));
    }
    const RunReader reader = RunReader::open(source.path);
    // The bodies as the run file holds them; the prescribed motions of driven bodies (not in the
    // run file) from the run's scene, on the exported scene's clock, which starts again at 0.
    saved.model.motion_of_body = scene.model.motion_of_body;
    saved.model.prescribed_motions = scene.model.prescribed_motions;
    saved.model.driven_bodies = scene.model.driven_bodies;
    for (PrescribedMotion& motion : saved.model.prescribed_motions) {
      for (double& t : motion.time) t -= saved.state.time;
    }
    scene.model = saved.model;
    const double time = saved.state.time;
    const std::int64_t step = saved.state.step;
    scene.state = std::move(saved.state);
    // A scene starts at t = 0, step 0: the state keeps its positions and velocities, not its clock.
    scene.state.time = 0.0;
    scene.state.step = 0;
    // "auto" values resolved as the run used them: recomputed from the settled state they would
    // change (a compact aggregate has a larger free-fall velocity, hence a smaller dt).
    const double h = reader.time_step();
    if (scene.run.automatic_time_step && h > 0.0) scene.run.step.integrator.time_step = h;
    scene.run.automatic_time_step = false;
    scene.run.automatic_rest_speed = false;
    scene.run.automatic_rest_coordination_change = false;
    scene.run.automatic_rest_duration = false;
    if (args.output != "-") {
      scene.run.output.directory = std::filesystem::path(args.output).stem().string() + "-output";
    }
    text = fmt::format(
        "# exported by rubble export: {}; every grain with its state at t = {:.17g} s, step {} of that run.\n"
        "# The scene starts again at t = 0; dt and the rest thresholds are the values that run used.\n",
        saved.description, time, step);
    if (scene.inflow.active()) {
      // An inflow run: the bodies in play (the state's bodies before the first one not inserted,
      // NaN in a snapshot), as grains of their own; the grains the inflow had still to insert are left out.
      std::size_t in_play = scene.state.body_count();
      while (in_play > scene.inflow.first_body && !scene.state.position[in_play - 1].allFinite()) --in_play;
      text += fmt::format(
          "# The run's [[inflow]] had inserted {} of its {} grains: they are [[bodies]] here "
          "(numbered before the walls now); the inflow is left out.\n",
          in_play - scene.inflow.first_body, scene.inflow.grains.size());
      scene.model = model_prefix(scene.model, in_play);
      scene.state = state_prefix(scene.state, in_play);
      scene.inflow = InflowPlan{};
    }
    text += scene_to_toml(scene);
    // The file must read back: parse it once before writing it.
    parse_scene(text, args.output == "-" ? "<rubble export>" : args.output);
  } catch (const SceneError& e) {
    return bad_input(std::string("the run's scene: ") + e.what());
  } catch (const InputError& e) {  // BranchError, InputFileError, ...
    return bad_input(e.what());
  } catch (const std::runtime_error& e) {
    return bad_input(e.what());
  }
  return write_scene_text("export", args.output, text);
}

}  // namespace

void register_export_command(CLI::App& app) {
  auto args = std::make_shared<ExportArguments>();
  CLI::App* command = app.add_subcommand(
      "export", "Write a saved state of a run (a snapshot of RUN.h5) as a scene file with every grain explicit");
  command->add_option("run", args->run_file, "Run file RUN.h5 (or its run folder)")->required();
  command
      ->add_option("--snapshot", args->snapshot,
                   "Snapshot index, 0-based; negative counts from the end (default -1: the last)")
      ->type_name("K");
  command->add_option("-o,--output", args->output, "Scene file to write (- for stdout)")->required();
  command->callback([args] {
    const int code = export_command(*args);
    if (code != exit_ok) throw CLI::RuntimeError(code);
  });
}

}  // namespace rubble::apps
