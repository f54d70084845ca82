#pragma once
// The frictional contact problem as plain data (W, q, mu), as in FCLib and Siconos numerics:
// find r, u with u = W r + q and Signorini-Coulomb per contact. A file-backed problem is solved
// by the same sweep and local solver as the simulation's contacts.
#include <cstdint>
#include <vector>

#include "core/math.hpp"
#include "nlgs_solver/nlgs.hpp"

namespace rubble {

/// W in compressed sparse row form (3 rows per contact, ordered normal, t, s).
struct SparseMatrix {
  int rows = 0;                ///< number of rows (3 * contacts)
  int columns = 0;             ///< number of columns (3 * contacts)
  std::vector<int> row_start;  ///< rows + 1 offsets into column/value
  std::vector<int> column;     ///< column index of each stored value
  std::vector<double> value;   ///< stored values
};

/// A local frictional contact problem: u = W r + q, per contact K_mu ∋ r ⊥ û ∈ K_mu*.
struct LocalProblem {
  SparseMatrix W;          ///< Delassus operator
  std::vector<double> q;   ///< 3 * contacts
  std::vector<double> mu;  ///< friction coefficient per contact
  /// Number of contacts.
  std::size_t contact_count() const { return mu.size(); }
};

/// How to order the contacts within a sweep.
enum class SweepOrder { as_stored, shuffled };

/// What to do when the sweeps alone converge slowly (rank-deficient W, e.g. box stacks with four
/// contacts per face, where Gauss-Seidel crawls).
enum class PolishMethod {
  none,    ///< sweeps only (the simulation's solver as is)
  newton,  ///< Levenberg-Marquardt steps on the Alart-Curnier function, started from the sweeps' iterate
};

/// Options of the file-backed solve (the simulation's SolverOptions plus an order and a polish).
struct LocalProblemOptions {
  double tolerance = 1e-8;                   ///< on the FCLib error ||F||/||q|| (rho = 1)
  int max_iterations = 10000;                ///< sweeps at most
  double relaxation = 1.0;                   ///< omega
  SweepOrder order = SweepOrder::as_stored;  ///< contact order within a sweep
  std::uint64_t seed = 1;                    ///< for SweepOrder::shuffled (one shuffle, reused every sweep)
  PolishMethod polish = PolishMethod::none;  ///< none keeps the plain NLGS
  /// Sweeps before the first polish attempt; if it does not reach the tolerance (or is not worth
  /// its cost: nlgs_solver/README.md), sweeping resumes and the next attempt comes after twice as
  /// many sweeps (so a failing polish costs at most about as much as the sweeps themselves).
  int polish_after = 20;
  int polish_iterations = 30;  ///< Newton (LM) steps per attempt at most
  /// Levenberg-Marquardt damping of the first step, relative to the mean diagonal of J^T J.
  double polish_initial_damping = 1e-4;
};

/// Result of a file-backed solve.
struct LocalProblemSolution {
  std::vector<double> r;      ///< 3 * contacts
  std::vector<double> u;      ///< 3 * contacts
  int iterations = 0;         ///< sweeps done
  int newton_iterations = 0;  ///< polish steps done (all attempts)
  int polish_attempts = 0;    ///< polish attempts started
  double error = 0.0;         ///< ||F(r)|| / ||q||, natural map with rho = 1 (FCLib measure)
  bool converged = false;     ///< error <= tolerance
};

/// Newton polish of an iterate: Levenberg-Marquardt steps on the Alart-Curnier function from r
/// (u = W r + q on entry), at most `options.polish_iterations`, stopping once the FCLib error is
/// below `options.tolerance`. r, u and `error` (the FCLib error of r on entry) are replaced when a
/// better iterate is found. Returns the number of Newton steps taken. Used after the sweeps of
/// file-backed problems and of the simulation's contacts when they crawl.
int polish_solution(const LocalProblem& problem, const LocalProblemOptions& options, std::vector<double>& r,
                    std::vector<double>& u, double& error);

/// The local velocities u = W r + q of impulses r (3 nc each).
std::vector<double> local_velocities(const LocalProblem& problem, const std::vector<double>& r);

/// The FCLib error measure of (r, u) for the problem (Acary et al. 2014).
double fclib_error(const LocalProblem& problem, const std::vector<double>& r, const std::vector<double>& u);

/// Per contact, the norm of its natural map in velocity units, ||natural_map(r_k, u_k, mu_k,
/// W_nn)|| with W_nn contact k's normal diagonal entry (1 where it is not positive): the measure
/// the simulation's residual sums (nlgs_solver/README.md, "Convergence criterion"), point by point,
/// to see where a solution's residual sits.
std::vector<double> point_residuals(const LocalProblem& problem, const std::vector<double>& r,
                                    const std::vector<double>& u);

/// Solves the problem by NLGS from r = 0 with the simulation's sweep and local solver; the error
/// (one W r product) is evaluated after every sweep until it falls at a steady rate, then where
/// that rate says the tolerance may be met, and at least every 16 sweeps. With PolishMethod::newton,
/// Newton attempts are interleaved with the sweeps where they cost less than the sweeps left (see
/// LocalProblemOptions::polish_after and nlgs_solver/README.md).
LocalProblemSolution solve_local_problem(const LocalProblem& problem, const LocalProblemOptions& options);

/// Alart-Curnier function of the problem at r (Alart & Curnier 1991), per contact with
/// rho = 1 / W_nn:  a = r_n - rho u_n,  F_n = r_n - max(a, 0),
/// F_T = r_T - P_{disc(mu max(a, 0))}(r_T - rho u_T); F = 0 exactly at the solutions.
/// Returns F (3 nc); used by the Newton polish, exposed for its tests.
std::vector<double> alart_curnier_function(const LocalProblem& problem, const std::vector<double>& r);

}  // namespace rubble
