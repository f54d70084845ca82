// `rubble run`: runs a scene file (or the built-in default) and writes DIR/run.h5.
#include <fstream>
#include <iostream>
#include <sstream>

#include "apps/commands.hpp"
#include "simulation/run.hpp"
#include "simulation/scene_file.hpp"

namespace rubble::apps {
namespace {

struct RunArguments {
  std::string scene_path;
  std::string output_directory;
  double end_time = 0.0;
  bool print_default = false;
  bool quiet = false;
};

int run_command(const RunArguments& args) {
  Scene scene;
  std::string scene_text;
  try {
    if (args.scene_path.empty()) {
      scene_text = default_scene_toml();
      scene = parse_scene(scene_text, "<built-in default scene>");
    } else {
      std::ifstream in(args.scene_path);
      if (!in) {
        std::cerr << "rubble run: error: " << args.scene_path << ": cannot open the scene file\n";
        return exit_bad_input;
      }
      std::stringstream buffer;
      buffer << in.rdbuf();
      scene_text = buffer.str();
      scene = load_scene_file(args.scene_path);
    }
  } catch (const SceneError& e) {
    std::cerr << "rubble run: error: " << e.what() << "\n";
    return exit_bad_input;
  }
  if (!args.output_directory.empty()) scene.run.output.directory = args.output_directory;
  if (args.end_time > 0.0) scene.run.end_time = args.end_time;

  std::ostream* progress = args.quiet ? nullptr : &std::cout;
  if (progress) {
    *progress << "rubble run: " << scene.name << ": " << scene.model.body_count() << " bodies, dt = "
              << scene.run.step.integrator.time_step << " s, until t = " << scene.run.end_time << " s\n";
  }
  try {
    const RunSummary summary = run_scene(scene, RunControl{progress, scene_text});
    std::cout << "rubble run: done: " << summary.steps << " steps, t = " << summary.simulated_time << " s in "
              << summary.wall_seconds << " s wall (" << summary.steps / std::max(summary.wall_seconds, 1e-9)
              << " steps/s), mean NLGS iterations " << summary.mean_iterations << ", max residual "
              << summary.max_residual << ", " << summary.unconverged_steps << " steps at the iteration cap\n"
              << "  output: " << summary.run_file.string() << " (" << summary.snapshots
              << " snapshots; layout in docs/output-format.md)\n"
              << "  look at it: rubble post " << summary.run_file.string()
              << " --vtk, then open the .pvd in ParaView, or h5py.File('" << summary.run_file.string() << "')\n";
  } catch (const NumericalFailure& e) {
    std::cerr << "rubble run: numerical failure: " << e.what() << "\n";
    return exit_numerical_failure;
  }
  return exit_ok;
}

}  // namespace

void register_run_command(CLI::App& app) {
  auto args = std::make_shared<RunArguments>();
  CLI::App* run = app.add_subcommand("run", "Run a scene file (without SCENE: the built-in default scene)");
  run->add_option("scene", args->scene_path, "Scene file (TOML, see docs/scene-file.md)");
  run->add_option("-o,--out", args->output_directory, "Output directory (overrides the scene's output.directory)");
  run->add_option("--end-time", args->end_time, "Override the scene's end time (s)")->check(CLI::PositiveNumber);
  run->add_flag("--print-default-scene", args->print_default, "Print the built-in default scene as TOML and exit");
  run->add_flag("-q,--quiet", args->quiet, "No progress lines");
  run->callback([args] {
    if (args->print_default) {
      std::cout << default_scene_toml();
      return;
    }
    const int code = run_command(*args);
    if (code != exit_ok) throw CLI::RuntimeError(code);
  });
}

}  // namespace rubble::apps
