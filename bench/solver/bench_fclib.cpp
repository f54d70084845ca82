// bench_fclib: solves FCLib local problems (shared/fclib) with solve_local_problem, for a list of
// tolerances, and prints one JSON line per (file, tolerance): contacts, sweeps, Newton steps,
// FCLib error, best-of-N wall seconds, converged. Used by bench/solver/run.sh and charts.py.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <iostream>
#include <limits>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "nlgs_solver/fclib_file.hpp"
#include "nlgs_solver/local_problem.hpp"

int main(int argc, char** argv) {
  CLI::App app{"Times solve_local_problem on FCLib files"};
  std::vector<std::string> files;
  std::vector<double> tolerances{1e-8};
  std::string polish = "none", order = "as_stored";
  int repetitions = 2;
  rubble::LocalProblemOptions options;
  app.add_option("files", files, "FCLib HDF5 files")->required();
  app.add_option("--tolerances", tolerances, "Tolerances on ||F||/||q||")->delimiter(',');
  app.add_option("--max-iterations", options.max_iterations, "Sweeps at most");
  app.add_option("--polish", polish, "none | newton");
  app.add_option("--polish-after", options.polish_after, "Sweeps before the first polish");
  app.add_option("--omega", options.relaxation, "Relaxation");
  app.add_option("--order", order, "as_stored | shuffled");
  app.add_option("--seed", options.seed, "Seed of the shuffled order");
  app.add_option("--reps", repetitions, "Repetitions (the best time is reported)");
  CLI11_PARSE(app, argc, argv);
  options.polish = polish == "newton" ? rubble::PolishMethod::newton : rubble::PolishMethod::none;
  options.order = order == "shuffled" ? rubble::SweepOrder::shuffled : rubble::SweepOrder::as_stored;
  for (const std::string& file : files) {
    rubble::LocalProblem problem;
    try {
      problem = rubble::read_fclib_local(file);
    } catch (const rubble::FclibFileError& e) {
      std::cerr << "bench_fclib: " << e.what() << "\n";
      return 2;
    }
    for (const double tolerance : tolerances) {
      options.tolerance = tolerance;
      double best = std::numeric_limits<double>::infinity();
      rubble::LocalProblemSolution solution;
      for (int rep = 0; rep < repetitions; ++rep) {
        const auto start = std::chrono::steady_clock::now();
        solution = rubble::solve_local_problem(problem, options);
        best = std::min(best, std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
      }
      const nlohmann::json line = {{"file", file.substr(file.find_last_of('/') + 1)},
                                   {"contacts", problem.contact_count()},
                                   {"tolerance", tolerance},
                                   {"polish", polish},
                                   {"omega", options.relaxation},
                                   {"order", order},
                                   {"iterations", solution.iterations},
                                   {"newton_iterations", solution.newton_iterations},
                                   {"polish_attempts", solution.polish_attempts},
                                   {"error", solution.error},
                                   {"seconds", best},
                                   {"converged", solution.converged}};
      std::cout << line.dump() << std::endl;
    }
  }
  return 0;
}
