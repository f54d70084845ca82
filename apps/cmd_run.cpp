// `rubble run`: runs a scene file (or the built-in default) and writes DIR/run.h5, with
// checkpoints in DIR/checkpoints; `rubble run --resume DIR` goes on from the newest valid
// checkpoint (docs/checkpoints.md).
//
// Signals: while a run is stepping, SIGINT and SIGTERM only store their number in `stop_signal`
// (the one piece of global mutable state of the program: a signal handler can reach nothing
// else, and a lock-free atomic store is async-signal-safe). The run loop reads it after each
// step, writes a checkpoint and returns; the command then exits with 128 + the signal's number,
// as a shell reports a process stopped by that signal. The handlers are installed with
// SA_RESETHAND: a second Ctrl-C during the final checkpoint kills at once (the checkpoint being
// written is a temporary file, so the previous ones stay valid).
#include <signal.h>
#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include <atomic>
#include <cmath>
#include <cstddef>
#include <filesystem>
#include <fmt/format.h>
#include <fstream>
#include <iostream>
#include <optional>
#include <sstream>
#include <string>

#include "apps/commands.hpp"
#include "core/input_error.hpp"
#include "core/input_file.hpp"
#include "gravity/gravity.hpp"
#include "simulation/branch.hpp"
#include "simulation/checkpoint.hpp"
#include "simulation/output_lock.hpp"
#include "simulation/run.hpp"
#include "simulation/run_control.hpp"
#include "simulation/scene_file.hpp"

namespace rubble::apps {
namespace {

/// The signal that asked the run to stop (0: none). See the file comment.
std::atomic<int> stop_signal{0};
static_assert(std::atomic<int>::is_always_lock_free, "the signal flag must be lock-free to be set in a handler");

extern "C" void request_stop(int signal_number) { stop_signal.store(signal_number, std::memory_order_relaxed); }

/// Installs the stop handlers for SIGINT and SIGTERM while alive; restores the previous ones.
class StopOnSignals {
 public:
  StopOnSignals() {
    stop_signal.store(0);
    struct sigaction action {};
    action.sa_handler = request_stop;
    sigemptyset(&action.sa_mask);
    action.sa_flags = SA_RESETHAND;
    sigaction(SIGINT, &action, &previous_int_);
    sigaction(SIGTERM, &action, &previous_term_);
  }
  ~StopOnSignals() {
    sigaction(SIGINT, &previous_int_, nullptr);
    sigaction(SIGTERM, &previous_term_, nullptr);
  }
  StopOnSignals(const StopOnSignals&) = delete;
  StopOnSignals& operator=(const StopOnSignals&) = delete;

 private:
  struct sigaction previous_int_ {};
  struct sigaction previous_term_ {};
};

struct RunArguments {
  std::string scene_path;
  std::string output_directory;
  std::string resume_directory;
  std::int64_t from_step = -1;  ///< --from-step: resume from this checkpoint instead of the newest
  double end_time = 0.0;
  std::int64_t checkpoint_every = 0;
  double checkpoint_minutes = 10.0;
  double max_speed = 0.0;
  bool no_runaway_check = false;
  bool print_default = false;
  std::string default_scene = "spheres";  ///< without SCENE: "spheres" or "polyhedra"
  bool quiet = false;
  std::string from;                        ///< --from RUN_DIR[:last|:snapshot=K|:time=T]: branch from a saved state
  std::string until;                       ///< --until rest|end_time ("": the scene's)
  double rest_speed = -1.0;                ///< --rest-speed (< 0: the scene's)
  double rest_quantile = -1.0;             ///< --rest-quantile
  double rest_coordination_change = -1.0;  ///< --rest-coordination-change
  double rest_contact_change = -1.0;       ///< --rest-contact-change
  double rest_duration = -1.0;             ///< --rest-duration
};

/// Applies --until and the --rest-* overrides to `scene` (a new run, a branch or a resumed one).
/// Returns an error message, or "" when fine; sets `overridden` when any was given.
std::string apply_rest_overrides(const RunArguments& args, Scene& scene, bool& overridden) {
  RunOptions& run = scene.run;
  overridden = !args.until.empty() || args.rest_speed >= 0.0 || args.rest_quantile >= 0.0 ||
               args.rest_coordination_change >= 0.0 || args.rest_contact_change >= 0.0 || args.rest_duration >= 0.0;
  if (!args.until.empty()) {
    const bool was = run.until_rest;
    run.until_rest = args.until == "rest";
    if (run.until_rest && !was) {
      // The scene had no rest criterion: the automatic one, from the scene's grains.
      try {
        run.rest = automatic_rest_criterion(scene_scales(scene.model, scene.state, run.step.gravity));
      } catch (const std::invalid_argument& error) {
        return std::string("--until rest: ") + error.what() + " (give --rest-speed and --rest-duration)";
      }
      run.automatic_rest_speed = true;
      run.automatic_rest_duration = true;
      run.automatic_rest_coordination_change = true;
    }
  }
  const bool thresholds = args.rest_speed >= 0.0 || args.rest_quantile >= 0.0 || args.rest_coordination_change >= 0.0 ||
                          args.rest_contact_change >= 0.0 || args.rest_duration >= 0.0;
  if (thresholds && !run.until_rest) {
    return "--rest-* options are used with until = \"rest\" (the scene's [time] until, or --until rest)";
  }
  if (args.rest_speed >= 0.0) {
    run.rest.speed = args.rest_speed;
    run.automatic_rest_speed = false;
  }
  if (args.rest_quantile >= 0.0) run.rest.quantile = args.rest_quantile;
  if (args.rest_coordination_change >= 0.0) {
    run.rest.coordination_change = args.rest_coordination_change;
    run.automatic_rest_coordination_change = false;
  }
  if (args.rest_contact_change >= 0.0) run.rest.contact_change = args.rest_contact_change;
  if (args.rest_duration >= 0.0) {
    run.rest.duration = args.rest_duration;
    run.automatic_rest_duration = false;
  }
  return "";
}

/// "  time per stage: ..." with each stage's share of the summed stage and output time.
std::string stage_breakdown(const RunSummary& summary) {
  double total = summary.output_seconds;
  for (const double s : summary.stage_seconds) total += s;
  if (!(total > 0.0)) return "";
  std::string text = "  time per stage (wall):";
  for (std::size_t s = 0; s < summary.stage_seconds.size(); ++s) {
    text += fmt::format(" {} {:.3g} s ({:.0f}%),", stage_name(static_cast<Stage>(s)), summary.stage_seconds[s],
                        100.0 * summary.stage_seconds[s] / total);
  }
  text += fmt::format(" output {:.3g} s ({:.0f}%)\n", summary.output_seconds, 100.0 * summary.output_seconds / total);
  return text;
}

DefaultScene default_variant(const RunArguments& args) {
  return args.default_scene == "polyhedra" ? DefaultScene::polyhedra : DefaultScene::spheres;
}

int bad_input(const std::string& message) {
  std::cerr << "rubble run: error: " << message << "\n";
  return exit_bad_input;
}

std::string signal_name(int signal_number) {
  if (signal_number == SIGINT) return "SIGINT";
  if (signal_number == SIGTERM) return "SIGTERM";
  return fmt::format("signal {}", signal_number);
}

/// An input problem to report with exit code 2 (bad_input), or nothing when all is well.
using InputProblem = std::optional<std::string>;

/// The options that go with --resume, --from-step and --from, checked against each other and
/// against the folder to resume.
InputProblem resume_options_problem(const RunArguments& args) {
  const bool resuming = !args.resume_directory.empty();
  if (!resuming && args.from_step >= 0) return "--from-step is used with --resume DIR";
  if (resuming && !args.from.empty()) {
    return "--from starts a new run from a saved state and --resume goes on with one: give one of them";
  }
  if (!resuming) return std::nullopt;
  if (!args.scene_path.empty()) return "give a scene file or --resume DIR, not both";
  if (!args.output_directory.empty()) {
    return "--out cannot be used with --resume (the run goes on in the folder it resumes)";
  }
  if (!std::filesystem::is_directory(args.resume_directory)) {
    return args.resume_directory + ": no such run folder to resume";
  }
  return std::nullopt;
}

/// The checkpoint to resume from: the one of step --from-step, or else the newest valid one
/// (docs/checkpoints.md). Throws CheckpointError when it cannot be read.
InputProblem load_checkpoint_to_resume(const RunArguments& args, LoadedCheckpoint& loaded) {
  if (args.from_step < 0) {
    loaded = load_newest_checkpoint(checkpoint_folder(args.resume_directory));
    return std::nullopt;
  }
  const std::filesystem::path folder = checkpoint_folder(args.resume_directory);
  const std::filesystem::path file = folder / fmt::format("step-{:012}.ckpt", args.from_step);
  if (!std::filesystem::is_regular_file(file)) {
    std::string steps;
    for (const auto& path : list_checkpoints(folder)) steps += fmt::format(" {}", checkpoint_step(path));
    return fmt::format("--from-step {}: no checkpoint of that step in {} (checkpoints at steps:{})", args.from_step,
                       folder.string(), steps.empty() ? " none" : steps);
  }
  loaded.checkpoint = read_checkpoint(file);
  loaded.file = file;
  return std::nullopt;
}

/// A run that goes on from a checkpoint: the scene the checkpoint carries, in the folder it
/// resumes, to the checkpoint's end time or --end-time. Throws CheckpointError, SceneError.
InputProblem open_resumed_run(const RunArguments& args, Scene& scene, RunControl& control, LoadedCheckpoint& loaded) {
  if (InputProblem problem = load_checkpoint_to_resume(args, loaded)) return problem;
  for (const std::string& reason : loaded.rejected) std::cerr << "rubble run: warning: skipped " << reason << "\n";
  const Checkpoint& checkpoint = loaded.checkpoint;
  control.scene_text = checkpoint.scene_text;
  control.scene_source = checkpoint.scene_source;
  scene = parse_scene(control.scene_text, control.scene_source);
  scene.run.output.directory = args.resume_directory;
  scene.run.end_time = args.end_time > 0.0 ? args.end_time : checkpoint.end_time;
  if (scene.run.end_time < checkpoint.state.time - 0.5 * scene.run.step.integrator.time_step) {
    return fmt::format("--end-time {} s is before the checkpoint's time {} s", scene.run.end_time,
                       checkpoint.state.time);
  }
  control.resume = &loaded.checkpoint;
  return std::nullopt;
}

/// A new run: the scene file, or the built-in default scene. Throws SceneError, InputFileError.
void open_new_run(const RunArguments& args, Scene& scene, RunControl& control) {
  if (args.scene_path.empty()) {
    control.scene_text = default_scene_toml(default_variant(args));
    control.scene_source = "<built-in default scene>";
    scene = parse_scene(control.scene_text, control.scene_source);
    return;
  }
  // Read once, with the scene file's cap and only from a regular file (core/input_file.hpp).
  control.scene_text = read_input_file(args.scene_path, max_scene_file_bytes, "scene file");
  scene = parse_scene(control.scene_text, args.scene_path);
  // Absolute, so that a resumed run anchors the scene's relative paths the same way.
  control.scene_source = std::filesystem::absolute(args.scene_path).string();
}

/// The scene and its text: a new run's, or a resumed run's with its checkpoint in `loaded`
/// (control.resume points at it).
InputProblem open_run(const RunArguments& args, Scene& scene, RunControl& control, LoadedCheckpoint& loaded) {
  try {
    if (InputProblem problem = resume_options_problem(args)) return problem;
    if (!args.resume_directory.empty()) return open_resumed_run(args, scene, control, loaded);
    open_new_run(args, scene, control);
  } catch (const CheckpointError& e) {
    return std::string("cannot resume: ") + e.what();
  } catch (const InputError& e) {  // SceneError, InputFileError and every other input error (core/input_error.hpp)
    return std::string(e.what());
  }
  return std::nullopt;
}

/// --from: the bodies' state from the saved run, everything else from the scene
/// (docs/checkpoints.md, "Branching"). Sets `description` to the state it starts from and
/// `warm_start` to a checkpoint's contacts rescaled to the scene's dt (branch_warm_start).
InputProblem branch_from_saved_state(const RunArguments& args, const std::string& scene_source, Scene& scene,
                                     std::string& description, ContactList& warm_start) {
  if (scene.inflow.active()) {
    // Its bodies in play grow during a run; a saved state would have to say which are in play.
    return fmt::format(
        "--from {}: the scene {} has [[inflow]] entries, which a branch does not support: branch "
        "with a scene without them (rubble export writes the grains in play as a scene)",
        args.from, scene_source);
  }
  try {
    SavedState saved = load_saved_state(parse_branch_source(args.from));
    if (const auto mismatch = body_mismatch(scene.model, saved.model)) {
      return fmt::format("--from {}: the bodies of {} differ from those of the scene {}: {}", args.from,
                         saved.description, scene_source, *mismatch);
    }
    scene.state = std::move(saved.state);
    // The scene's driving acts on the branch: driven bodies take their prescribed velocities at
    // the saved time, and [[initial_conditions]] add their rigid motions to the saved velocities
    // (an aggregate at rest set spinning).
    set_prescribed_velocities(scene.model, scene.state);
    if (const auto k = apply_initial_conditions(scene.model, scene.initial_conditions, scene.state)) {
      return fmt::format(
          "--from {}: [[initial_conditions]] entry {} of {} selects no grain of the saved "
          "state",
          args.from, *k + 1, scene_source);
    }
    description = saved.description;
    warm_start = branch_warm_start(saved, scene.run.step.integrator.time_step);
    if (!warm_start.empty()) {
      const double ratio = scene.run.step.integrator.time_step / saved.time_step;
      description +=
          fmt::format("; warm start: its {} contacts' impulses{}", warm_start.size(),
                      ratio == 1.0 ? std::string() : fmt::format(" times {:.6g} (the ratio of the time steps)", ratio));
    }
  } catch (const BranchError& e) {
    return std::string("--from: ") + e.what();
  }
  return std::nullopt;
}

/// The command line's overrides of the scene: --until and --rest-*, then --out and --end-time.
/// An --end-time, and a branch's end time, are held to the scene's own rule for [time] end_time
/// (run_control.hpp): the step count from the scene's initial time.
InputProblem apply_overrides(const RunArguments& args, Scene& scene, RunControl& control) {
  const bool resuming = !args.resume_directory.empty();
  bool overridden = false;
  std::string problem = apply_rest_overrides(args, scene, overridden);
  if (!problem.empty()) return problem;
  control.rest_overridden = resuming && overridden;
  if (!resuming) {
    if (!args.output_directory.empty()) scene.run.output.directory = args.output_directory;
    if (args.end_time > 0.0) scene.run.end_time = args.end_time;
  }
  const double h = scene.run.step.integrator.time_step;
  if (args.end_time > 0.0) {
    if (const auto end_problem = end_time_problem(args.end_time, scene.state.time, h)) {
      return "--end-time: " + *end_problem;
    }
  } else if (!args.from.empty()) {
    // The scene's end time counts from t = 0; a branch starts at its saved time.
    if (const auto end_problem = end_time_problem(scene.run.end_time, scene.state.time, h)) {
      return fmt::format("the scene's [time] end_time for a branch from t = {:.6g} s: {} (give --end-time)",
                         scene.state.time, *end_problem);
    }
  }
  return std::nullopt;
}

/// Checkpoints, the runaway check, the stop on a signal and where the progress lines go.
void set_run_control(const RunArguments& args, RunControl& control) {
  control.checkpoint_every_steps = args.checkpoint_every;
  control.checkpoint_interval = 60.0 * args.checkpoint_minutes;
  control.max_speed = args.no_runaway_check ? -1.0 : args.max_speed;
  control.stop_requested = &stop_signal;
  control.progress = args.quiet ? nullptr : &std::cout;
  control.warnings = &std::cerr;
}

/// The first progress lines: the scene, its time step and when it stops; where a branch starts
/// (`branched_from` when not null) or a resumed run goes on (`resumed` when not null).
void print_run_header(std::ostream& out, const Scene& scene, const std::string* branched_from,
                      const LoadedCheckpoint* resumed) {
  out << "rubble run: " << scene.name << ": " << scene.model.body_count() << " bodies"
      << (scene.inflow.active() ? fmt::format(" ({} of them enter by [[inflow]])", scene.inflow.grains.size())
                                : std::string())
      << ", dt = " << scene.run.step.integrator.time_step << (scene.run.automatic_time_step ? " s (auto)" : " s")
      << (scene.run.until_rest ? fmt::format(", until at rest ({}) or t = ", describe_rest_criterion(scene.run.rest))
                               : std::string(", until t = "))
      << scene.run.end_time << " s\n";
  if (branched_from != nullptr) out << "rubble run: branching from " << *branched_from << "\n";
  if (resumed != nullptr) {
    out << "rubble run: resuming from " << resumed->file.string() << " (step " << resumed->checkpoint.state.step
        << ", t = " << resumed->checkpoint.state.time << " s)\n";
  }
}

/// The lines of a finished run: steps, time, solver figures, the time per stage, the output and
/// the final state's hash, and how to look at it. `hash_note`: what the hash depends on besides the
/// scene (empty, or the gravity kernels' instruction set).
void print_run_summary(const RunSummary& summary, bool resuming, const std::string& hash_note) {
  std::cout << "rubble run: done: " << summary.steps << " steps"
            << (summary.first_step > 0
                    ? fmt::format(" ({} at step {})", resuming ? "resumed" : "branched", summary.first_step)
                    : std::string())
            << ", t = " << summary.simulated_time << " s in " << summary.wall_seconds << " s wall ("
            << summary.steps / std::max(summary.wall_seconds, 1e-9) << " steps/s), "
            << (resuming ? "over the whole run (every session): " : "") << "mean NLGS iterations "
            << summary.mean_iterations << ", max residual " << summary.max_residual << ", " << summary.unconverged_steps
            << " steps at the iteration cap"
            << (summary.polish_attempts > 0 ? fmt::format(", {} Newton polishes", summary.polish_attempts)
                                            : std::string())
            << "\n"
            << stage_breakdown(summary) << "  output: " << summary.run_file.string() << " (" << summary.snapshots
            << " snapshots; layout in docs/output-format.md)\n"
            << "  final state: step " << summary.final_step << ", hash " << fmt::format("{:016x}", summary.state_hash)
            << hash_note << ", checkpoint " << summary.last_checkpoint.string() << "\n"
            << "  look at it: rubble post " << summary.run_file.string()
            << " --vtk, then open the .pvd in ParaView, or h5py.File('" << summary.run_file.string() << "')\n";
}

/// Scenes up to this many bodies keep the memory their steps free (serve_step_blocks_from_heap).
constexpr std::size_t heap_served_bodies = 20000;

/// main.cpp fixes glibc's trim threshold at 1 MiB for the resident memory of large scenes. That
/// also stops glibc's dynamic raise of the mmap threshold, which then stays at 128 KiB: every
/// block above it (a step's contact list, the solver's copy, their scratch: ~0.8 MB each for 1 500
/// grains) was mapped fresh and unmapped every step, and the heap's top given back past 1 MiB,
/// so each step's new pages faulted in zeroed again. On a virtual machine whose page faults cost
/// ~10 us that was a quarter to a half of a small scene's CPU time (bench/RESULTS.md, "Page
/// faults"). Up to `heap_served_bodies` bodies, blocks up to 32 MiB (glibc's own ceiling for its
/// dynamic raise) come from the heap and up to 64 MiB of free heap is kept, so the freed memory is
/// reused step after step, for a few MB of resident memory (7 MB at 1e4 spheres). Larger scenes
/// keep main.cpp's settings: for 1e5 settling spheres the 32 MiB mmap threshold saved 15 % of the
/// CPU but its heap's holes cost 0.15 kB a grain, past the 2 kB that "Memory per grain" holds them to.
/// Results do not depend on either threshold.
void serve_step_blocks_from_heap([[maybe_unused]] std::size_t bodies) {
#if defined(__GLIBC__)
  if (bodies <= heap_served_bodies) {
    mallopt(M_MMAP_THRESHOLD, 32 << 20);
    mallopt(M_TRIM_THRESHOLD, 64 << 20);
  }
#endif
}

/// Steps the scene to its end (or a stop signal) and reports how it ended, with the exit code
/// of docs/exit-codes.md: 0, 128 + the signal, or 2, 3, 4 by the type of what stopped it.
/// `warm_start`: a branch's first-step warm start (empty otherwise).
int step_the_run(Scene& scene, const RunControl& control, bool resuming, ContactList warm_start) {
  try {
    const StopOnSignals handlers;
    // The run works on the scene's initial state itself, not a copy (one state less in memory).
    State initial_state = std::move(scene.state);
    serve_step_blocks_from_heap(scene.model.body_count());
    const RunSummary summary = run_scene(scene, std::move(initial_state), std::move(warm_start), control);
    if (summary.interrupted) {
      const int signal_number = stop_signal.load();
      std::cout << "rubble run: stopped by " << signal_name(signal_number) << " at step " << summary.final_step
                << " (t = " << summary.simulated_time << " s); checkpoint written: " << summary.last_checkpoint.string()
                << "; the state at the stop is the last snapshot of " << summary.run_file.string()
                << "\n  go on with: rubble run --resume " << scene.run.output.directory << "\n";
      return 128 + signal_number;
    }
    // The CPU gravity kernels' last bits depend on the CPU's instruction set (gravity.hpp), so a
    // self-gravitating run's hash is comparable only between machines of the same set.
    const bool cpu_self_gravity = scene.run.step.gravity.kind == GravitySettings::Kind::self &&
                                  scene.run.step.gravity.self_gravity.backend == gravity::Backend::cpu;
    print_run_summary(summary, resuming,
                      cpu_self_gravity ? " (gravity kernels: " + gravity::kernel_instruction_set() + ")" : "");
  } catch (const NumericalFailure& e) {
    std::cerr << "rubble run: numerical failure: " << e.what() << "\n";
    return exit_numerical_failure;
  } catch (const OutputError& e) {
    std::cerr << "rubble run: output failure: " << e.what() << "\n";
    return exit_output_failure;
  } catch (const CheckpointError& e) {
    return bad_input(std::string("cannot resume: ") + e.what());
  } catch (const InputError& e) {  // OutputFolderBusy, OutputFolderError, ...
    return bad_input(e.what());
  } catch (const std::invalid_argument& e) {  // run_scene's checks of the grains and the end time
    return bad_input(e.what());
  } catch (const std::runtime_error& e) {
    std::cerr << "rubble run: error: " << e.what() << "\n";
    return exit_failure;
  }
  return exit_ok;
}

/// `rubble run`: open the run (new, resumed or branched), apply the command line's overrides,
/// then step it.
int run_command(const RunArguments& args) {
  Scene scene;
  RunControl control;
  LoadedCheckpoint loaded;  // a resumed run's checkpoint: control.resume points into it
  if (const InputProblem problem = open_run(args, scene, control, loaded)) return bad_input(*problem);
  std::string branch_description;
  ContactList warm_start;  // a branch's: the saved run's contacts
  if (!args.from.empty()) {
    if (const InputProblem problem =
            branch_from_saved_state(args, control.scene_source, scene, branch_description, warm_start)) {
      return bad_input(*problem);
    }
    control.rest_armed = true;
  }
  if (const InputProblem problem = apply_overrides(args, scene, control)) return bad_input(*problem);
  set_run_control(args, control);
  const bool resuming = !args.resume_directory.empty();
  if (control.progress != nullptr) {
    print_run_header(*control.progress, scene, args.from.empty() ? nullptr : &branch_description,
                     resuming ? &loaded : nullptr);
  }
  return step_the_run(scene, control, resuming, std::move(warm_start));
}

}  // namespace

// NOLINTNEXTLINE(readability-function-size): over 80 lines, listed in docs/architecture.md
void register_run_command(CLI::App& app) {
  auto args = std::make_shared<RunArguments>();
  CLI::App* run = app.add_subcommand("run", "Run a scene file (without SCENE: the built-in default scene)");
  // CLI11 reads "nan" and "inf" as numbers and its range checks print the whole double range:
  // these say what was expected in words.
  const auto number = [](const std::string& expected, auto accept) {
    return CLI::Validator(
        [expected, accept](const std::string& text) {
          double value = 0.0;
          std::size_t used = 0;
          try {
            value = std::stod(text, &used);
          } catch (const std::exception&) {
            used = 0;
          }
          if (used == 0 || used != text.size() || !std::isfinite(value) || !accept(value)) {
            return "expected " + expected + ", got '" + text + "'";
          }
          return std::string();
        },
        "");
  };
  const auto positive = number("a finite number > 0", [](double v) { return v > 0.0; });
  const auto non_negative = number("a finite number >= 0", [](double v) { return v >= 0.0; });
  // Below 2^62: a count must fit the 64-bit step counters with room to add to them.
  const auto count =
      number("an integer >= 0 and < 2^62", [](double v) { return v >= 0.0 && v == std::floor(v) && v < 0x1p62; });
  CLI::Option* scene_option = run->add_option("scene", args->scene_path, "Scene file (TOML, see docs/scene-file.md)");
  run->add_option("-o,--out", args->output_directory, "Output directory (overrides the scene's output.directory)");
  run->add_option("--end-time", args->end_time, "Override the scene's end time (s)")->check(positive);
  run->add_option("--resume", args->resume_directory,
                  "Go on with the run in DIR from its newest valid checkpoint (DIR/checkpoints)")
      ->type_name("DIR");
  run->add_option("--from-step", args->from_step,
                  "With --resume: go on from the checkpoint of step K instead of the newest (later ones are set "
                  "aside; [output] keep_checkpoint_every keeps older ones)")
      ->check(count)
      ->type_name("K");
  run->add_option("--checkpoint-every", args->checkpoint_every, "Write a checkpoint every N steps (default 0: off)")
      ->check(count);
  run->add_option("--checkpoint-minutes", args->checkpoint_minutes,
                  "Write a checkpoint every T minutes of wall time (default 10; 0: off)")
      ->check(non_negative);
  run->add_option("--max-speed", args->max_speed,
                  "Stop when a grain is faster than V m/s (default: when a grain moves more than its own radius "
                  "in one step)")
      ->check(positive);
  run->add_flag("--no-runaway-check", args->no_runaway_check, "Only stop on non-finite values, not on speed");
  run->add_flag("--print-default-scene", args->print_default, "Print the built-in default scene as TOML and exit");
  run->add_option("--default-scene", args->default_scene,
                  "Without SCENE: the study's 1000 spheres (default) or the same accretion with random polyhedra")
      ->check(CLI::IsMember({"spheres", "polyhedra"}))
      ->excludes(scene_option);
  run->add_flag("-q,--quiet", args->quiet, "No progress lines");
  run->add_option("--from", args->from,
                  "Start a new run of SCENE from a state saved by another run: positions, orientations, velocities "
                  "(and time, step) from RUN_DIR's newest checkpoint (RUN_DIR or RUN_DIR:last; bit for bit), or "
                  "from its run.h5 (RUN_DIR:snapshot=K, K < 0 from the end; RUN_DIR:time=T, the last snapshot at or "
                  "before T s); materials, contact laws, solver, gravity, dt and end from SCENE. The bodies must "
                  "match (count, shape, size)")
      ->type_name("RUN_DIR[:SELECTOR]");
  run->add_option("--until", args->until,
                  "Override the scene's [time] until: rest (stop when the grains are at rest, or at the end time) "
                  "or end_time (run to the end time); also with --resume")
      ->check(CLI::IsMember({"rest", "end_time"}));
  run->add_option("--rest-speed", args->rest_speed,
                  "Rest: the speed quantile of |v| + |w| r must stay below V m/s (default: 5% of the free-fall "
                  "velocity sqrt(2GM/R) under self-gravity, of sqrt(g d_min) under uniform gravity; "
                  "docs/scene-file.md)")
      ->check(positive)
      ->type_name("V");
  run->add_option("--rest-quantile", args->rest_quantile,
                  "Rest: which quantile of the grain speeds is held to --rest-speed (default 0.99; 1: the fastest)")
      ->check(number("a number in (0, 1]", [](double v) { return v > 0.0 && v <= 1.0; }))
      ->type_name("Q");
  run->add_option("--rest-coordination-change", args->rest_coordination_change,
                  "Rest: largest change of the coordination number Z over the rest duration (default 0.05 "
                  "sqrt(1000/N) for N grains, and at least 4/N: two contacts)")
      ->check(non_negative)
      ->type_name("DZ");
  run->add_option("--rest-contact-change", args->rest_contact_change,
                  "Rest: largest fraction of contacts created or broken over the rest duration (default 0.2)")
      ->check(number("a number in [0, 1]", [](double v) { return v >= 0.0 && v <= 1.0; }))
      ->type_name("F");
  run->add_option("--rest-duration", args->rest_duration,
                  "Rest: how long every rest condition must hold, s (default: half a characteristic time, "
                  "0.5/sqrt(G rho) under self-gravity, 0.5 sqrt(2H/g) under uniform gravity)")
      ->check(non_negative)
      ->type_name("T");
  run->callback([args] {
    if (args->print_default) {
      std::cout << default_scene_toml(default_variant(*args));
      return;
    }
    const int code = run_command(*args);
    if (code != exit_ok) throw CLI::RuntimeError(code);
  });
}

}  // namespace rubble::apps
