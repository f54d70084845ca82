// bench_siconos: rubble's solver and Siconos' NSGS side by side on the same FCLib local problems,
// in one process, runs interleaved (rubble, Siconos, rubble, Siconos, ...), one thread, CPU time
// of the process (clock_gettime(CLOCK_PROCESS_CPUTIME_ID)). Prints one JSON line per (file,
// tolerance): each solver's iterations, its error by the FCLib measure (computed by rubble's
// fclib_error on each solver's own r, so both are judged alike) and Siconos' own error, the best CPU
// milliseconds of each and their ratio. Built only where Debian's libsiconos-numerics-dev is
// installed (bench/solver/README.md); the Siconos side is its default NSGS (Acary, Brémond, Dubois
// et al., FCLib's reference solver), from r = 0 like rubble's.
#include <siconos/numerics/FrictionContactProblem.h>
#include <siconos/numerics/Friction_cst.h>
#include <siconos/numerics/NonSmoothDrivers.h>
#include <siconos/numerics/NumericsMatrix.h>
#include <siconos/numerics/SiconosNumerics_Solvers.h>
#include <siconos/numerics/SolverOptions.h>
#include <time.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <limits>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "nlgs_solver/fclib_file.hpp"
#include "nlgs_solver/local_problem.hpp"

namespace {

/// CPU seconds of the process so far (every thread; run with OMP_NUM_THREADS=1).
double cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

/// The problem as Siconos' FrictionContactProblem: W as a sparse (triplet-built) NumericsMatrix,
/// q and mu copied into malloc'd arrays, which the problem owns.
FrictionContactProblem* siconos_problem(const rubble::LocalProblem& problem) {
  const rubble::SparseMatrix& W = problem.W;
  NumericsMatrix* M = NM_create(NM_SPARSE, W.rows, W.columns);
  NM_triplet_alloc(M, static_cast<CS_INT>(W.value.size()));
  M->matrix2->origin = NSM_TRIPLET;
  for (int row = 0; row < W.rows; ++row) {
    for (int e = W.row_start[static_cast<std::size_t>(row)]; e < W.row_start[static_cast<std::size_t>(row) + 1]; ++e) {
      NM_entry(M, row, W.column[static_cast<std::size_t>(e)], W.value[static_cast<std::size_t>(e)]);
    }
  }
  auto* q = static_cast<double*>(std::malloc(problem.q.size() * sizeof(double)));
  auto* mu = static_cast<double*>(std::malloc(problem.mu.size() * sizeof(double)));
  std::memcpy(q, problem.q.data(), problem.q.size() * sizeof(double));
  std::memcpy(mu, problem.mu.data(), problem.mu.size() * sizeof(double));
  return frictionContactProblem_new_with_data(3, static_cast<int>(problem.contact_count()), M, q, mu);
}

/// One solver's best of the repetitions.
struct Timed {
  double best_cpu = std::numeric_limits<double>::infinity();  ///< s
  int iterations = 0;                                         ///< sweeps (+ Newton steps for rubble)
  int newton_iterations = 0;                                  ///< rubble's polish steps
  double error = 0.0;                                         ///< FCLib measure of the solver's r
  double own_error = 0.0;                                     ///< Siconos' own reported error
  bool converged = false;                                     ///< FCLib error <= tolerance
};

void solve_with_rubble(const rubble::LocalProblem& problem, const rubble::LocalProblemOptions& options, Timed& out) {
  const double start = cpu_seconds();
  const rubble::LocalProblemSolution solution = rubble::solve_local_problem(problem, options);
  out.best_cpu = std::min(out.best_cpu, cpu_seconds() - start);
  out.iterations = solution.iterations;
  out.newton_iterations = solution.newton_iterations;
  out.error = solution.error;
  out.converged = solution.converged;
}

void solve_with_siconos(FrictionContactProblem* siconos, const rubble::LocalProblem& problem, double tolerance,
                        int max_iterations, Timed& out) {
  const std::size_t m = problem.q.size();
  std::vector<double> r(m, 0.0), u(m, 0.0);
  SolverOptions* options = solver_options_create(SICONOS_FRICTION_3D_NSGS);
  options->dparam[SICONOS_DPARAM_TOL] = tolerance;
  options->iparam[SICONOS_IPARAM_MAX_ITER] = max_iterations;
  const double start = cpu_seconds();
  fc3d_driver(siconos, r.data(), u.data(), options);
  out.best_cpu = std::min(out.best_cpu, cpu_seconds() - start);
  out.iterations = options->iparam[SICONOS_IPARAM_ITER_DONE];
  out.own_error = options->dparam[SICONOS_DPARAM_RESIDU];
  solver_options_delete(options);
  // Judged like rubble's: the FCLib measure of r, with u recomputed as W r + q.
  out.error = rubble::fclib_error(problem, r, rubble::local_velocities(problem, r));
  out.converged = out.error <= tolerance;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"rubble's NLGS (+ Newton polish) against Siconos NSGS on FCLib files, interleaved, CPU time"};
  std::vector<std::string> files;
  std::vector<double> tolerances{1e-4, 1e-8};
  int repetitions = 3;
  int max_iterations = 100000;
  app.add_option("files", files, "FCLib HDF5 files")->required();
  app.add_option("--tolerances", tolerances, "Tolerances")->delimiter(',');
  app.add_option("--reps", repetitions, "Repetitions of each solver, interleaved (the best CPU time is reported)");
  app.add_option("--max-iterations", max_iterations, "Sweeps at most, for both solvers");
  CLI11_PARSE(app, argc, argv);
  for (const std::string& file : files) {
    rubble::LocalProblem problem;
    try {
      problem = rubble::read_fclib_local(file);
    } catch (const rubble::FclibFileError& e) {
      std::cerr << "bench_siconos: " << e.what() << "\n";
      return 2;
    }
    FrictionContactProblem* siconos = siconos_problem(problem);
    for (const double tolerance : tolerances) {
      // `rubble fclib`'s defaults: NLGS sweeps, Newton polish after 20.
      rubble::LocalProblemOptions options;
      options.tolerance = tolerance;
      options.max_iterations = max_iterations;
      options.polish = rubble::PolishMethod::newton;
      Timed ours, theirs;
      for (int rep = 0; rep < repetitions; ++rep) {
        solve_with_rubble(problem, options, ours);
        solve_with_siconos(siconos, problem, tolerance, max_iterations, theirs);
      }
      const nlohmann::json line = {{"file", file.substr(file.find_last_of('/') + 1)},
                                   {"contacts", problem.contact_count()},
                                   {"tolerance", tolerance},
                                   {"rubble",
                                    {{"sweeps", ours.iterations},
                                     {"newton_steps", ours.newton_iterations},
                                     {"error", ours.error},
                                     {"converged", ours.converged},
                                     {"cpu_ms", 1e3 * ours.best_cpu}}},
                                   {"siconos_nsgs",
                                    {{"iterations", theirs.iterations},
                                     {"error", theirs.error},
                                     {"own_error", theirs.own_error},
                                     {"converged", theirs.converged},
                                     {"cpu_ms", 1e3 * theirs.best_cpu}}},
                                   {"siconos_over_rubble", theirs.best_cpu / ours.best_cpu}};
      std::cout << line.dump() << std::endl;
    }
    frictionContactProblem_free(siconos);
  }
  return 0;
}
