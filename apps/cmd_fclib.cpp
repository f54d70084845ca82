// `rubble fclib FILE.hdf5 [--tolerance 1e-8] [--max-iterations N] [--out SOL.h5] ...`
// Reads an FCLib local frictional-contact problem (FCLib 3.0 layout, Acary et al. 2014), solves it from r = 0
// with the simulation's NLGS sweep and local solver (plus the optional Newton polish), writes r
// and u to SOL.h5 (datasets `r`, `u`) and prints one JSON line: file, contacts, iterations, error
// (||F||/||q||, natural map), seconds, converged.
// Invalid input -> message on stderr naming the file and dataset, exit code 2. A contact whose
// Delassus diagonal W_nn is not positive is invalid input (the local solver divides by it; a
// zero diagonal is a contact between two bodies of infinite mass). A non-finite r, u or error
// after the solve is a numerical failure: exit code 3 naming the contact, and no solution file.
#include <chrono>
#include <cmath>
#include <fmt/format.h>
#include <iostream>
#include <optional>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "apps/commands.hpp"
#include "nlgs_solver/fclib_file.hpp"
#include "nlgs_solver/local_problem.hpp"

namespace rubble::apps {
namespace {

struct FclibArguments {
  std::string input;
  std::string output;
  std::string order = "as_stored";
  std::string polish = "newton";
  LocalProblemOptions options;
};

/// The first contact whose normal Delassus diagonal W_nn (row and column 3k) is missing, zero or
/// negative, with that value.
std::optional<std::string> bad_diagonal(const LocalProblem& problem) {
  const SparseMatrix& W = problem.W;
  for (std::size_t k = 0; k < problem.contact_count(); ++k) {
    const std::size_t row = 3 * k;
    double diagonal = 0.0;
    if (row + 1 < W.row_start.size()) {
      for (int e = W.row_start[row]; e < W.row_start[row + 1]; ++e) {
        if (static_cast<std::size_t>(W.column[static_cast<std::size_t>(e)]) == row) {
          diagonal += W.value[static_cast<std::size_t>(e)];
        }
      }
    }
    if (!(diagonal > 0.0)) {
      return fmt::format(
          "contact {}: W[{}][{}] (its normal Delassus diagonal) is {}: expected > 0 (W is positive "
          "definite on each contact; 0 is a contact between bodies of infinite mass)",
          k, row, row, diagonal);
    }
  }
  return std::nullopt;
}

/// The first non-finite entry of the solution, as "r[3k+i] of contact k = value".
std::optional<std::string> non_finite_solution(const LocalProblemSolution& solution) {
  const char* axis[] = {"normal", "t", "s"};
  for (const auto& [name, values] : {std::pair{"r (impulse)", &solution.r}, std::pair{"u (velocity)", &solution.u}}) {
    for (std::size_t i = 0; i < values->size(); ++i) {
      if (!std::isfinite((*values)[i])) {
        return fmt::format("contact {}: {} {} component is {}", i / 3, name, axis[i % 3], (*values)[i]);
      }
    }
  }
  if (!std::isfinite(solution.error)) return fmt::format("the error ||F||/||q|| is {}", solution.error);
  return std::nullopt;
}

int fclib_command(FclibArguments& args) {
  LocalProblem problem;
  try {
    problem = read_fclib_local(args.input);
  } catch (const FclibFileError& e) {
    std::cerr << "rubble fclib: error: " << e.what() << "\n";
    return exit_bad_input;
  }
  if (const auto problem_text = bad_diagonal(problem)) {
    std::cerr << "rubble fclib: error: " << args.input << ": " << *problem_text << "\n";
    return exit_bad_input;
  }
  LocalProblemOptions& options = args.options;
  if (args.order == "as_stored") {
    options.order = SweepOrder::as_stored;
  } else if (args.order == "shuffled") {
    options.order = SweepOrder::shuffled;
  } else {
    std::cerr << "rubble fclib: error: --order must be 'as_stored' or 'shuffled', got '" << args.order << "'\n";
    return exit_bad_input;
  }
  if (args.polish == "none") {
    options.polish = PolishMethod::none;
  } else if (args.polish == "newton") {
    options.polish = PolishMethod::newton;
  } else {
    std::cerr << "rubble fclib: error: --polish must be 'none' or 'newton', got '" << args.polish << "'\n";
    return exit_bad_input;
  }

  const auto start = std::chrono::steady_clock::now();
  LocalProblemSolution solution;
  try {
    solution = solve_local_problem(problem, options);
  } catch (const std::invalid_argument& e) {
    std::cerr << "rubble fclib: error: " << args.input << ": " << e.what() << "\n";
    return exit_bad_input;
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (const auto what = non_finite_solution(solution)) {
    std::cerr << "rubble fclib: numerical failure: " << args.input << ": after " << solution.iterations
              << " sweeps: " << *what << "; no solution written\n";
    return exit_numerical_failure;
  }

  if (!args.output.empty()) {
    try {
      write_fclib_solution(args.output, solution.r, solution.u);
      // Read back: HDF5 may buffer the data until the file's close, where a full disk goes
      // unreported; a solution file that does not read back equal was not written.
      std::vector<double> r, u;
      read_fclib_solution(args.output, r, u);
      if (r != solution.r || u != solution.u)
        throw FclibFileError(args.output + ": the solution did not read back equal");
    } catch (const FclibFileError& e) {
      std::cerr << "rubble fclib: output failure: cannot write the solution: " << e.what()
                << " (disk full or I/O error?)\n";
      return exit_output_failure;
    }
  }
  const nlohmann::json line = {{"file", args.input},
                               {"contacts", problem.contact_count()},
                               {"iterations", solution.iterations},
                               {"newton_iterations", solution.newton_iterations},
                               {"error", solution.error},
                               {"seconds", seconds},
                               {"converged", solution.converged},
                               {"tolerance", options.tolerance},
                               {"order", args.order},
                               {"seed", options.seed},
                               {"omega", options.relaxation},
                               {"polish", args.polish},
                               {"output", args.output}};
  std::cout << line.dump() << std::endl;
  return exit_ok;
}

}  // namespace

void register_fclib_command(CLI::App& app) {
  auto args = std::make_shared<FclibArguments>();
  CLI::App* cmd = app.add_subcommand("fclib", "Solve an FCLib local frictional-contact problem (HDF5) by NLGS");
  cmd->add_option("file", args->input, "FCLib HDF5 file with /fclib_local (W, q, mu)")->required();
  cmd->add_option("--tolerance", args->options.tolerance, "Stop when ||F(r)||/||q|| (natural map) <= this")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  cmd->add_option("--max-iterations", args->options.max_iterations, "NLGS sweeps at most")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  cmd->add_option("--out", args->output, "Solution file: datasets 'r' and 'u' (3 x contacts each)");
  cmd->add_option("--order", args->order, "Contact order in a sweep: as_stored or shuffled")->capture_default_str();
  cmd->add_option("--seed", args->options.seed, "Seed of the shuffled order")->capture_default_str();
  cmd->add_option("--omega", args->options.relaxation, "Relaxation of the sweep, in (0, 2)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 2.0));
  cmd->add_option("--polish", args->polish,
                  "After the sweeps stall: none, or newton (semismooth Newton on the Alart-Curnier function)")
      ->capture_default_str();
  cmd->add_option("--polish-after", args->options.polish_after,
                  "Sweeps before the first polish attempt (later attempts after twice as many sweeps)")
      ->capture_default_str();
  cmd->callback([args] {
    const int code = fclib_command(*args);
    if (code != exit_ok) throw CLI::RuntimeError(code);
  });
}

}  // namespace rubble::apps
