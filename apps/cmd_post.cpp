// `rubble post RUN.h5 [-o DIR] [--vtk] [--every N] [--no-plots]`: metrics of every snapshot (CSV and
// HDF5), the per-step series as CSV, ParaView files on request, PNG plots.
// `rubble post --study DIR_OR_RUN... [-o DIR] [--stable-after S] [--include-unfinished]`: the
// study's comparison plots. Plots that cannot be drawn (no matplotlib) are a warning, not an error.
// Every file written is listed in docs/postprocessing.md.
#include <iostream>
#include <memory>

#include "apps/commands.hpp"
#include "postprocessing/post.hpp"
#include "postprocessing/run_reader.hpp"
#include "simulation/scene_file.hpp"

namespace rubble::apps {
namespace {

struct PostArguments {
  std::string run_file;
  std::vector<std::string> study;
  std::string output_directory;
  bool vtk = false;
  bool no_plots = false;
  bool include_unfinished = false;
  std::string python;
  std::string plots_script;
  bool quiet = false;
  int every = 1;
  int bins = 20;
  double stable_after = 7500.0;
};

/// The run's gravity and time step (and, given `solver`, its sweep cap and tolerance), from the
/// scene stored in the run file. A scene this rubble cannot parse leaves the potential energy at 0
/// (with a warning), h to the series and the solver's limits unknown.
void settings_from_scene(const RunReader& reader, PostOptions& options, std::ostream& warnings,
                         SolverLimits* solver = nullptr) {
  try {
    const Scene scene = parse_scene(reader.scene_text(), reader.path().string() + ":/scene");
    if (solver != nullptr) *solver = {scene.run.step.solver.max_iterations, scene.run.step.solver.tolerance};
    const GravitySettings& gravity = scene.run.step.gravity;
    switch (gravity.kind) {
      case GravitySettings::Kind::none:
        options.potential.kind = PotentialSettings::Kind::none;
        break;
      case GravitySettings::Kind::uniform:
        options.potential.kind = PotentialSettings::Kind::uniform;
        options.potential.acceleration = gravity.acceleration;
        break;
      case GravitySettings::Kind::central:
        // The metrics know no central-mass potential yet: left at 0, as for no gravity.
        options.potential.kind = PotentialSettings::Kind::none;
        break;
      case GravitySettings::Kind::self:
        options.potential.kind = PotentialSettings::Kind::self;
        options.potential.gravitational_constant = gravity.self_gravity.G;
        options.potential.softening = gravity.self_gravity.softening.kind == gravity::Softening::Kind::plummer
                                          ? gravity.self_gravity.softening.length
                                          : 0.0;
        break;
    }
    options.time_step = scene.run.step.integrator.time_step;
  } catch (const std::exception& e) {
    warnings << "rubble post: warning: the run's scene could not be read (" << e.what()
             << "); potential energy left at 0, time step estimated from the series\n";
  }
}

PlotOptions plot_options(const PostArguments& args) {
  PlotOptions plot;
  plot.python = args.python;
  plot.script = args.plots_script;
  return plot;
}

int post_command(const PostArguments& args) {
  std::ostream* log = args.quiet ? nullptr : &std::cout;
  try {
    if (!args.study.empty()) {
      StudyOptions options;
      options.output_directory = args.output_directory.empty() ? "rubble-study" : args.output_directory;
      options.stable_after = args.stable_after;
      options.plots = !args.no_plots;
      options.plot = plot_options(args);
      options.include_unfinished = args.include_unfinished;
      // Each run's own gravity (G, softening) for the escape test of its last snapshot, and its
      // solver's limits for the count of capped steps: one parse of its scene.
      options.settings_of = [](const RunReader& reader) {
        PostOptions post;
        StudyRunSettings settings;
        settings_from_scene(reader, post, std::cerr, &settings.solver);
        settings.potential = post.potential;
        return settings;
      };
      options.log = log;
      options.warnings = &std::cerr;
      std::vector<std::filesystem::path> inputs(args.study.begin(), args.study.end());
      const auto written = post_process_study(inputs, options);
      if (log != nullptr) {
        for (const auto& path : written) *log << "  " << path.string() << "\n";
      }
      return exit_ok;
    }
    const std::filesystem::path run(args.run_file);
    std::error_code error;
    if (std::filesystem::is_directory(run, error)) {
      std::cerr << "rubble post: error: " << run.string() << ": is a folder, expected a run file (DIR/run.h5)\n";
      return exit_bad_input;
    }
    PostOptions options;
    {
      const RunReader reader = RunReader::open(run);
      settings_from_scene(reader, options, std::cerr);
    }
    options.output_directory = args.output_directory.empty() ? run.parent_path() / (run.stem().string() + "-post")
                                                             : std::filesystem::path(args.output_directory);
    options.every = args.every;
    options.write_vtk = args.vtk;
    options.plots = !args.no_plots;
    options.plot = plot_options(args);
    options.histogram_bins = args.bins;
    options.log = log;
    options.warnings = &std::cerr;
    post_process_run(run, options);
  } catch (const PostOutputError& e) {
    std::cerr << "rubble post: output failure: " << e.what() << "\n";
    return exit_output_failure;
  } catch (const NonFiniteResult& e) {
    std::cerr << "rubble post: numerical failure: " << e.what() << "\n";
    return exit_numerical_failure;
  } catch (const std::exception& e) {
    std::cerr << "rubble post: error: " << e.what() << "\n";
    return exit_bad_input;
  }
  return exit_ok;
}

}  // namespace

void register_post_command(CLI::App& app) {
  auto args = std::make_shared<PostArguments>();
  CLI::App* post = app.add_subcommand("post", "Metrics, plots and ParaView files of a run (docs/postprocessing.md)");
  auto* run = post->add_option("run", args->run_file, "Run file (HDF5) written by `rubble run`");
  auto* study = post->add_option("--study", args->study,
                                 "Gather these run files, or folders searched for run files, into the study's plots");
  run->excludes(study);
  post->add_option("-o,--out", args->output_directory,
                   "Output folder (default: RUN-post beside the run file; rubble-study for --study)");
  post->add_flag("--vtk", args->vtk, "Also write the ParaView series (OUT/vtk/*.pvd)");
  post->add_option("--every", args->every, "Use every N-th snapshot (the last one always)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  post->add_option("--bins", args->bins, "Bins of the normal impulse distribution")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  post->add_option("--stable-after", args->stable_after,
                   "With --study: average over snapshots at t >= this (s; the paper's 125 min); never replaced: a run "
                   "short of it is flagged and left out")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  post->add_flag("--no-plots", args->no_plots, "Do not draw the PNGs");
  post->add_option("--python", args->python,
                   "Python interpreter with matplotlib that draws the PNGs (default: $RUBBLE_PYTHON, else python3 on "
                   "PATH, else /usr/bin/python3, the first that has matplotlib)")
      ->type_name("PYTHON");
  post->add_option("--plots-script", args->plots_script,
                   "The plotting script (default: $RUBBLE_PLOTS_SCRIPT, else plots.py beside rubble or in "
                   "../share/rubble/)")
      ->type_name("FILE");
  post->add_flag("--include-unfinished", args->include_unfinished,
                 "With --study: also fit and plot runs that did not run to their end (at rest or at the end time: "
                 "interrupted, killed, failed) or did not reach the window (--stable-after); they are flagged in "
                 "study.csv and drawn as open markers");
  post->add_flag("-q,--quiet", args->quiet, "Do not list progress and files");
  post->callback([args] {
    if (args->run_file.empty() && args->study.empty()) {
      throw CLI::ValidationError("rubble post", "give a run file, or --study with run files or folders");
    }
    const int code = post_command(*args);
    if (code != exit_ok) throw CLI::RuntimeError(code);
  });
}

}  // namespace rubble::apps
