// Self-gravity evaluated every k steps ([gravity] evaluate_every, simulation/external_forces.cpp): the error
// of the held field against the field a k = 1 run would use at the same positions, and the time
// of the gravity stage.
//   every_k SCENE.toml --steps N --k 1,2,4,8,16 --csv OUT.csv
// For each k, runs N steps of the scene with evaluate_every = k; before every step evaluates the
// field exactly as k = 1 would (same method, theta, order, G, softening) at the current positions,
// and after the step compares it with the acceleration the step used (workspace.carry.held_gravity, or
// the exact one for k = 1). Per step: max and median over grains of |a_used - a_exact| / |a_exact|.
// The gravity stage's wall time is StepReport::stage_seconds[external_forces], the figure the run
// file stores per step (docs/output-format.md); the exact reference evaluation is outside step()
// and not counted.
#include <algorithm>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "simulation/scene_file.hpp"
#include "simulation/step.hpp"

namespace {

using namespace rubble;

std::vector<int> parse_list(const std::string& text) {
  std::vector<int> values;
  std::stringstream in(text);
  std::string item;
  while (std::getline(in, item, ',')) values.push_back(std::stoi(item));
  return values;
}

/// The self-gravity acceleration at every body, as a k = 1 step computes it.
std::vector<Vec3> exact_field(const Model& model, const State& state, const gravity::GravityOptions& options) {
  std::vector<std::size_t> grains;
  for (std::size_t b = 0; b < model.body_count(); ++b) {
    if (!model.is_fixed(b)) grains.push_back(b);
  }
  std::vector<double> positions(3 * grains.size()), masses(grains.size()), acceleration(3 * grains.size());
  for (std::size_t k = 0; k < grains.size(); ++k) {
    for (int i = 0; i < 3; ++i) positions[3 * k + static_cast<std::size_t>(i)] = state.position[grains[k]][i];
    masses[k] = model.mass[grains[k]];
  }
  gravity::compute_field(options, positions, masses, acceleration, {});
  std::vector<Vec3> field(model.body_count(), Vec3::Zero());
  for (std::size_t k = 0; k < grains.size(); ++k) {
    field[grains[k]] = Vec3(acceleration[3 * k], acceleration[3 * k + 1], acceleration[3 * k + 2]);
  }
  return field;
}

}  // namespace

int main(int argc, char** argv) {
  std::string scene_path, csv_path = "every_k.csv";
  long steps = 300;
  std::vector<int> ks = {1, 2, 4, 8, 16};
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    const auto next = [&]() -> std::string {
      if (i + 1 >= argc) throw std::invalid_argument(arg + " needs a value");
      return argv[++i];
    };
    if (arg == "--steps")
      steps = std::stol(next());
    else if (arg == "--k")
      ks = parse_list(next());
    else if (arg == "--csv")
      csv_path = next();
    else
      scene_path = arg;
  }
  if (scene_path.empty()) {
    std::cerr << "usage: every_k SCENE.toml [--steps N] [--k 1,2,4] [--csv OUT.csv]\n";
    return 2;
  }
  const Scene scene = load_scene_file(scene_path);
  if (scene.run.step.gravity.kind != GravitySettings::Kind::self) {
    std::cerr << scene_path << ": [gravity] must be self-gravity (direct or tree)\n";
    return 2;
  }
  std::ofstream csv(csv_path);
  csv << "k,step,max_rel_error,median_rel_error,gravity_seconds,step_seconds,kinetic_energy\n";
  std::printf("%4s %12s %12s %12s %14s %14s\n", "k", "max err", "median err", "p50 max err", "gravity s/step",
              "step s/step");
  for (const int k : ks) {
    State state = scene.state;
    StepWorkspace workspace;
    StepOptions options = scene.run.step;
    options.gravity.evaluate_every = k;
    double worst = 0.0, gravity_seconds = 0.0, step_seconds = 0.0;
    std::vector<double> step_max;
    for (long n = 0; n < steps; ++n) {
      const std::vector<Vec3> exact = exact_field(scene.model, state, options.gravity.self_gravity);
      const StepReport report = step(scene.model, state, workspace, options);
      std::vector<double> errors;
      for (std::size_t b = 0; b < exact.size(); ++b) {
        if (scene.model.is_fixed(b) || exact[b].norm() == 0.0) continue;
        const Vec3 used = k == 1 ? exact[b] : workspace.carry.held_gravity[b];
        errors.push_back((used - exact[b]).norm() / exact[b].norm());
      }
      std::sort(errors.begin(), errors.end());
      const double max_error = errors.empty() ? 0.0 : errors.back();
      const double median_error = errors.empty() ? 0.0 : errors[errors.size() / 2];
      double stage_total = 0.0;
      for (double s : report.stage_seconds) stage_total += s;
      const double g = report.stage_seconds[static_cast<std::size_t>(Stage::external_forces)];
      gravity_seconds += g;
      step_seconds += stage_total;
      worst = std::max(worst, max_error);
      step_max.push_back(max_error);
      double kinetic = 0.0;
      for (std::size_t b = 0; b < scene.model.body_count(); ++b) {
        if (!scene.model.is_fixed(b)) kinetic += 0.5 * scene.model.mass[b] * state.velocity[b].squaredNorm();
      }
      csv << k << "," << state.step << "," << max_error << "," << median_error << "," << g << "," << stage_total << ","
          << kinetic << "\n";
    }
    std::sort(step_max.begin(), step_max.end());
    std::printf("%4d %12.3e %12s %12.3e %14.3e %14.3e\n", k, worst, "(csv)", step_max[step_max.size() / 2],
                gravity_seconds / static_cast<double>(steps), step_seconds / static_cast<double>(steps));
    std::fflush(stdout);
  }
  return 0;
}
