// bench_matched_accuracy: which solver tolerance gives the contact forces of a tight solve, and
// what it costs (bench/solver/README.md; issue 22's "matched accuracy").
//
// From a checkpoint (a run's state with its warm start), each candidate setting runs STEPS steps
// on its own trajectory. Before each of its steps, the same step is also solved from the same
// state and warm start with the reference setting (tolerance 1e-8 unless --reference-tolerance),
// so each step's forces are compared with a tight solve of the very same problem, warm start and
// error carried over from earlier steps included. Per candidate it prints one JSON line: CPU
// seconds per step (process CPU time around step(), the tight solves excluded), sweeps, and the
// worst step's
//   grain_error  = ||P - P_ref|| / ||P_ref||  over the grains' net contact impulses P_b (N s, the
//                  sum of the impulses of a grain's contacts: what moves the grain),
//   force_error  = ||r - r_ref|| / ||r_ref||  over every contact's impulse (contact frame, N s),
//   loaded_error = |{r_n > 0} xor {r_ref,n > 0}| / |{r_ref,n > 0}|.
// The grain error is the one that can be matched: a deposit is hyperstatic (a frictional grain
// needs 4 contacts for rigidity and has more; a polyhedron face touches at up to 8 points), so the
// point forces of a rigid deposit are not unique (Radjai et al. 1998's force indeterminacy; Unger,
// Kertesz & Wolf 2005) and two solves meeting the same tolerance may split a grain's load among
// its contacts differently, while every grain's net impulse, set by its velocity, is the same.
// Usage: bench_matched_accuracy CHECKPOINT.ckpt [--tolerances 1e-2,1e-3,1e-4] [--steps 5]
//        [--max-iterations N] [--relaxation OMEGA] [--anderson-depth M] [--reference-tolerance 1e-8]
//        [--reference-sweeps 50000] [--reference-polish]
//        bench_matched_accuracy CHECKPOINT.ckpt --write-fclib FILE.hdf5
// The second form writes the contact problem of the checkpoint's next step (W, q, mu) as an FCLib
// local problem and stops: the step's problem replayed by `rubble fclib`, bench_fclib and
// bench_siconos (bench/solver/README.md).
#include <time.h>

#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <limits>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "nlgs_solver/fclib_file.hpp"
#include "simulation/checkpoint.hpp"
#include "simulation/scene_file.hpp"
#include "simulation/step.hpp"

namespace {

using namespace rubble;

double process_cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

/// How far one step's impulses are from the reference solve of the same step.
struct StepError {
  double grain = 0.0;   ///< ||P - P_ref|| / ||P_ref|| over the grains' net impulses
  double force = 0.0;   ///< ||r - r_ref|| / ||r_ref||
  double loaded = 0.0;  ///< loaded-set mismatch over the reference's loaded count
  std::size_t loaded_reference = 0;
};

/// Net world contact impulse on every body (walls included; they are left out of the norms).
std::vector<Vec3> net_impulses(const ContactList& contacts, std::size_t bodies) {
  std::vector<Vec3> net(bodies, Vec3::Zero());
  for (const Contact& c : contacts) {
    const Vec3 p = c.frame * c.impulse;  // on b; -p on a
    net[c.id.body_b] += p;
    net[c.id.body_a] -= p;
  }
  return net;
}

StepError compare(const Model& model, const ContactList& candidate, const ContactList& reference) {
  if (candidate.size() != reference.size()) throw std::runtime_error("the two solves saw different contacts");
  StepError error;
  const std::size_t bodies = model.inverse_mass.size();
  const std::vector<Vec3> net = net_impulses(candidate, bodies), net_reference = net_impulses(reference, bodies);
  double grain_difference = 0.0, grain_norm = 0.0;
  for (std::size_t b = 0; b < bodies; ++b) {
    if (model.inverse_mass[b] == 0.0) continue;  // walls and driven bodies
    grain_difference += (net[b] - net_reference[b]).squaredNorm();
    grain_norm += net_reference[b].squaredNorm();
  }
  error.grain = grain_norm > 0.0 ? std::sqrt(grain_difference / grain_norm) : 0.0;
  double difference = 0.0, norm = 0.0;
  std::size_t mismatched = 0;
  for (std::size_t k = 0; k < reference.size(); ++k) {
    difference += (candidate[k].impulse - reference[k].impulse).squaredNorm();
    norm += reference[k].impulse.squaredNorm();
    const bool loaded = candidate[k].impulse.x() > 0.0, loaded_reference = reference[k].impulse.x() > 0.0;
    if (loaded != loaded_reference) ++mismatched;
    if (loaded_reference) ++error.loaded_reference;
  }
  error.force = norm > 0.0 ? std::sqrt(difference / norm) : 0.0;
  error.loaded =
      error.loaded_reference > 0 ? static_cast<double>(mismatched) / static_cast<double>(error.loaded_reference) : 0.0;
  return error;
}

nlohmann::json run_candidate(const Model& model, const Checkpoint& start, const StepOptions& base, double tolerance,
                             int max_iterations, double relaxation, int anderson_depth, const SolverOptions& reference,
                             int steps) {
  StepOptions options = base;
  if (anderson_depth >= 0) options.solver.anderson_depth = anderson_depth;
  options.solver.tolerance = tolerance;
  if (max_iterations > 0) options.solver.max_iterations = max_iterations;
  if (relaxation > 0.0) options.solver.relaxation = relaxation;
  StepOptions tight = base;
  tight.solver = reference;
  State state = start.state;
  StepWorkspace workspace;
  workspace.carry = start.carry;
  double cpu = 0.0, sweeps = 0.0, worst_grain = 0.0, worst_force = 0.0, worst_loaded = 0.0, reference_residual = 0.0;
  int reference_sweeps = 0;
  std::size_t loaded = 0;
  for (int s = 0; s < steps; ++s) {
    State tight_state = state;
    StepWorkspace tight_workspace = workspace;
    const StepReport exact = step(model, tight_state, tight_workspace, tight);
    reference_residual = std::max(reference_residual, exact.solver.residual);
    reference_sweeps = std::max(reference_sweeps, exact.solver.iterations);
    const double before = process_cpu_seconds();
    const StepReport report = step(model, state, workspace, options);
    cpu += process_cpu_seconds() - before;
    sweeps += report.solver.iterations;
    const StepError error = compare(model, workspace.carry.contacts, tight_workspace.carry.contacts);
    worst_grain = std::max(worst_grain, error.grain);
    worst_force = std::max(worst_force, error.force);
    worst_loaded = std::max(worst_loaded, error.loaded);
    loaded = error.loaded_reference;
  }
  return {{"tolerance", tolerance},
          {"relaxation", options.solver.relaxation},
          {"anderson_depth", options.solver.anderson_depth},
          {"steps", steps},
          {"cpu_ms_per_step", 1e3 * cpu / steps},
          {"sweeps_per_step", sweeps / steps},
          {"grain_error_max", worst_grain},
          {"force_error_max", worst_force},
          {"loaded_error_max", worst_loaded},
          {"loaded_contacts", loaded},
          {"contacts", workspace.carry.contacts.size()},
          {"reference_residual_max", reference_residual},
          {"reference_sweeps_max", reference_sweeps}};
}

/// Steps once from the checkpoint with the scene's settings and writes that step's contact problem
/// to `file`; returns the number of contacts written.
std::size_t write_step_problem(const Model& model, const Checkpoint& start, StepOptions options,
                               const std::string& file, const std::string& title) {
  State state = start.state;
  StepWorkspace workspace;
  workspace.carry = start.carry;
  std::size_t contacts = 0;
  options.solver.problem_observer = [&](const LocalProblem& problem) {
    write_fclib_local(file, problem, SparseStorage::compressed_row, title);
    contacts = problem.contact_count();
  };
  step(model, state, workspace, options);
  return contacts;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Contact forces of each solver setting against a tight solve of the same steps"};
  std::string checkpoint_file;
  std::vector<double> tolerances{1e-2, 1e-3, 1e-4};
  int steps = 5;
  double reference_tolerance = 1e-8;
  int reference_sweeps = 50000;
  int max_iterations = 0;
  bool reference_polish = false;
  double relaxation = 0.0;
  int anderson_depth = -1;
  app.add_option("checkpoint", checkpoint_file, "checkpoint file (run folder/checkpoints/step-*.ckpt)")->required();
  app.add_option("--tolerances", tolerances, "candidate tolerances")->delimiter(',');
  app.add_option("--steps", steps, "steps per candidate")->check(CLI::PositiveNumber);
  app.add_option("--reference-tolerance", reference_tolerance, "tolerance of the tight solve");
  app.add_option("--reference-sweeps", reference_sweeps, "sweeps at most in the tight solve");
  app.add_option("--max-iterations", max_iterations, "sweeps at most in the candidates' solves (default: the scene's)");
  // The scene key's open range (0, 2): CLI::Range would let 0 (read below as "the scene's") and 2 through.
  app.add_option("--relaxation", relaxation, "omega of the candidates' sweeps in (0, 2) (default: the scene's)")
      ->check(CLI::Validator(
          [](const std::string& text) {
            const double omega = std::strtod(text.c_str(), nullptr);
            return omega > 0.0 && omega < 2.0 ? std::string() : "expected omega in (0, 2), got '" + text + "'";
          },
          ""));
  app.add_option("--anderson-depth", anderson_depth,
                 "sweeps the candidates' Anderson acceleration remembers, 0 = off (default: the scene's); the tight "
                 "solve never mixes")
      ->check(CLI::Range(0, 50));
  app.add_flag("--reference-polish", reference_polish,
               "let the tight solve use the Newton polish whatever its size (nlgs.hpp polish_max_contacts)");
  std::string fclib_file;
  app.add_option("--write-fclib", fclib_file,
                 "write the next step's contact problem as an FCLib local problem to this file and stop");
  CLI11_PARSE(app, argc, argv);
  try {
    const Checkpoint start = read_checkpoint(checkpoint_file);
    const Scene scene = parse_scene(start.scene_text, start.scene_source);
    if (!fclib_file.empty()) {
      const std::string title =
          "rubble: the contact problem of step " + std::to_string(start.state.step + 1) + " after " + checkpoint_file;
      const std::size_t contacts = write_step_problem(scene.model, start, scene.run.step, fclib_file, title);
      std::cout << fclib_file << ": " << contacts << " contacts\n";
      return 0;
    }
    SolverOptions reference = scene.run.step.solver;
    reference.tolerance = reference_tolerance;
    reference.max_iterations = reference_sweeps;
    reference.anderson_depth = 0;
    if (reference_polish) {
      reference.polish_max_contacts = std::numeric_limits<std::size_t>::max();
      reference.polish_attempts_per_step = 100;
      reference.polish_iterations = 50;
    }
    for (const double tolerance : tolerances) {
      std::cout << run_candidate(scene.model, start, scene.run.step, tolerance, max_iterations, relaxation,
                                 anderson_depth, reference, steps)
                       .dump()
                << std::endl;
    }
  } catch (const std::exception& e) {
    std::cerr << "bench_matched_accuracy: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
