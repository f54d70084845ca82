#include "nlgs_solver/local_problem.hpp"

#include <Eigen/LU>  // Mat3::inverse
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <algorithm>
#include <limits>
#include <cmath>
#include <numeric>
#include <random>
#include <stdexcept>

#include "nlgs_solver/coulomb.hpp"
#include "nlgs_solver/sweep.hpp"

namespace rubble {
namespace {

/// W explicit: u_k is recomputed from its three rows, so applying a change needs no work.
struct ExplicitProblem {
  const LocalProblem& p;
  std::vector<Mat3> diagonal_blocks;
  std::vector<Mat3> inverse_blocks;  ///< diagonal_blocks[k].inverse(), filled before the sweeps
  std::vector<Vec3> r;

  std::size_t size() const { return p.contact_count(); }
  const Mat3& delassus(std::size_t k) const { return diagonal_blocks[k]; }
  const Mat3& delassus_inverse(std::size_t k) const { return inverse_blocks[k]; }
  double friction_coefficient(std::size_t k) const { return p.mu[k]; }
  Vec3& impulse(std::size_t k) { return r[k]; }
  Vec3 local_velocity(std::size_t k) const {
    Vec3 u;
    for (int i = 0; i < 3; ++i) {
      const std::size_t row = 3 * k + static_cast<std::size_t>(i);
      double sum = p.q[row];
      for (int e = p.W.row_start[row]; e < p.W.row_start[row + 1]; ++e) {
        const auto column = static_cast<std::size_t>(p.W.column[static_cast<std::size_t>(e)]);
        sum += p.W.value[static_cast<std::size_t>(e)] * r[column / 3][static_cast<Eigen::Index>(column % 3)];
      }
      u[i] = sum;
    }
    return u;
  }
  void apply_impulse_change(std::size_t, const Vec3&) {}
};

using SparseColumnMajor = Eigen::SparseMatrix<double>;

/// rho_alpha = 1 / W_nn,alpha: puts rho u in impulse units, so both halves of the Alart-Curnier
/// function (and of its Jacobian) are of one scale whatever the masses.
std::vector<double> normal_scalings(const LocalProblem& p) {
  std::vector<double> rho(p.contact_count(), 1.0);
  for (std::size_t k = 0; k < p.contact_count(); ++k) {
    const std::size_t row = 3 * k;
    for (int e = p.W.row_start[row]; e < p.W.row_start[row + 1]; ++e) {
      if (static_cast<std::size_t>(p.W.column[static_cast<std::size_t>(e)]) == row &&
          p.W.value[static_cast<std::size_t>(e)] > 0.0) {
        rho[k] = 1.0 / p.W.value[static_cast<std::size_t>(e)];
      }
    }
  }
  return rho;
}

/// The Alart-Curnier function F(r) and, when `jacobian` is given, one element of its generalized
/// (Clarke) Jacobian as triplets: per contact, with a = r_n - rho u_n, b = r_T - rho u_T,
/// R = mu max(a, 0) and du/dr = W,
///   a <= 0 (open):              F = r,                          dF = I
///   a > 0, |b| <= R (sticking): F = rho u,                      dF = rho W_alpha
///   a > 0, |b| > R (sliding):   F_n = rho u_n,  F_T = r_T - R b/|b|,
///                               dF_T = dr_T - mu bhat da - (R/|b|)(I - bhat bhat^T) db.
double alart_curnier(const LocalProblem& p, const std::vector<double>& rho, const std::vector<double>& r,
                     const std::vector<double>& u, std::vector<double>& F,
                     std::vector<Eigen::Triplet<double>>* jacobian) {
  const std::size_t n = p.contact_count();
  F.assign(3 * n, 0.0);
  double squared = 0.0;
  for (std::size_t k = 0; k < n; ++k) {
    const std::size_t i0 = 3 * k;
    const double mu = p.mu[k];
    const double a = r[i0] - rho[k] * u[i0];
    const int c0 = static_cast<int>(i0);
    auto add_w_row = [&](int out_row, std::size_t w_row, double factor) {
      for (int e = p.W.row_start[w_row]; e < p.W.row_start[w_row + 1]; ++e) {
        jacobian->emplace_back(out_row, p.W.column[static_cast<std::size_t>(e)],
                               factor * p.W.value[static_cast<std::size_t>(e)]);
      }
    };
    if (a <= 0.0) {
      for (int i = 0; i < 3; ++i) {
        F[i0 + static_cast<std::size_t>(i)] = r[i0 + static_cast<std::size_t>(i)];
        if (jacobian) jacobian->emplace_back(c0 + i, c0 + i, 1.0);
      }
    } else {
      F[i0] = rho[k] * u[i0];
      if (jacobian) add_w_row(c0, i0, rho[k]);
      const double radius = mu * a;
      const double b1 = r[i0 + 1] - rho[k] * u[i0 + 1], b2 = r[i0 + 2] - rho[k] * u[i0 + 2];
      const double b_norm = std::hypot(b1, b2);
      if (b_norm <= radius) {
        F[i0 + 1] = rho[k] * u[i0 + 1];
        F[i0 + 2] = rho[k] * u[i0 + 2];
        if (jacobian) {
          add_w_row(c0 + 1, i0 + 1, rho[k]);
          add_w_row(c0 + 2, i0 + 2, rho[k]);
        }
      } else {
        const double h1 = b1 / b_norm, h2 = b2 / b_norm;
        const double s = radius / b_norm;
        F[i0 + 1] = r[i0 + 1] - radius * h1;
        F[i0 + 2] = r[i0 + 2] - radius * h2;
        if (jacobian) {
          // P = s (I - bhat bhat^T); dF_T = dr_T - mu bhat (dr_n - rho dU_n) - P (dr_T - rho dU_T).
          const double P[2][2] = {{s * (1.0 - h1 * h1), -s * h1 * h2}, {-s * h1 * h2, s * (1.0 - h2 * h2)}};
          const double h[2] = {h1, h2};
          for (int i = 0; i < 2; ++i) {
            const int out = c0 + 1 + i;
            jacobian->emplace_back(out, c0, -mu * h[i]);
            for (int j = 0; j < 2; ++j) jacobian->emplace_back(out, c0 + 1 + j, (i == j ? 1.0 : 0.0) - P[i][j]);
            add_w_row(out, i0, mu * h[i] * rho[k]);
            for (int j = 0; j < 2; ++j) add_w_row(out, i0 + 1 + static_cast<std::size_t>(j), P[i][j] * rho[k]);
          }
        }
      }
    }
    for (int i = 0; i < 3; ++i) squared += F[i0 + static_cast<std::size_t>(i)] * F[i0 + static_cast<std::size_t>(i)];
  }
  return squared;
}

/// What one polish attempt did.
struct PolishResult {
  int iterations = 0;      ///< Newton steps taken
  bool improved = false;   ///< r holds a better iterate (lower FCLib error) than on entry
  double step_work = 0.0;  ///< cost of the first step (newton_step_work), 0 if none was taken
};

/// The cost of a polish attempt against that of the sweeps it would save, in the units of
/// newton_step_work and sweep_work: an attempt is taken to need 10 Newton steps (those that
/// converge on the FCLib problems and rubble's own steps take 2-30; bench/RESULTS.md, "rubble
/// against Siconos NSGS"), and a unit of Newton work to cost 3 of a sweep's (the sparse product and
/// the ordering run slower per multiply-add than the sweep's dense 3x3 rows: measured 1-5x).
constexpr double expected_newton_steps = 10.0;
constexpr double newton_unit_cost = 3.0;

/// Newton work (multiply-adds, about a second of CPU) a polish attempt may always cost where the
/// sweeps cannot reach the tolerance: beyond it the factorisation is refused (a settled 3D pile of
/// 4 763 points fills in past 10 min of CPU a step) and the sweeps go on to max_iterations.
constexpr double affordable_polish_work = 1e9;

/// Whether a polish attempt is worth its cost: `step_work` a Newton step's, `sweeps_work` that of the
/// sweeps still needed (or what an attempt may cost where the sweeps cannot get there).
bool polish_pays(double step_work, double sweeps_work) {
  return expected_newton_steps * newton_unit_cost * step_work <= sweeps_work;
}

/// Eigen's sparse LDL^T, with the column counts of its factor readable after the symbolic analysis
/// (they are computed there, before any numeric work).
class CountedLDLT : public Eigen::SimplicialLDLT<SparseColumnMajor> {
 public:
  /// Sum over the factor's columns of their squared lengths: the factorisation's multiply-adds
  /// (George & Liu 1981). Valid after analyzePattern().
  double factorisation_work() const {
    double work = 0.0;
    for (Eigen::Index j = 0; j < m_nonZerosPerCol.size(); ++j) {
      const auto count = static_cast<double>(m_nonZerosPerCol[j]);
      work += count * count;
    }
    return work;
  }
};

/// Multiply-adds of one Levenberg-Marquardt step, counted from the matrices (so a decision taken on
/// it is the same on every run): forming J^T J (each of its entries a dot product of two columns of
/// J, about nnz(J)/m terms) and its factorisation.
double newton_step_work(const SparseColumnMajor& J, const SparseColumnMajor& normal_matrix,
                        const CountedLDLT& factorization) {
  return static_cast<double>(normal_matrix.nonZeros()) * static_cast<double>(J.nonZeros()) /
             static_cast<double>(std::max<Eigen::Index>(J.cols(), 1)) +
         factorization.factorisation_work();
}

/// The rows of J that are unit rows e_i^T (an open contact's three; a frictionless sliding
/// contact's two tangential ones, whose other entries are zeros): their equation of the Newton
/// step J d = -F is d_i = -F_i, known before any factorisation.
std::vector<char> unit_rows(const Eigen::SparseMatrix<double, Eigen::RowMajor>& J) {
  std::vector<char> unit(static_cast<std::size_t>(J.rows()), 0);
  for (Eigen::Index i = 0; i < J.rows(); ++i) {
    int entries = 0;
    bool diagonal_one = false;
    for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator e(J, i); e; ++e) {
      if (e.value() == 0.0) continue;
      ++entries;
      diagonal_one = e.col() == i && e.value() == 1.0;
    }
    unit[static_cast<std::size_t>(i)] = entries == 1 && diagonal_one ? 1 : 0;
  }
  return unit;
}

/// One damped Gauss-Newton (Levenberg-Marquardt) step on the Alart-Curnier function at r. The
/// unit rows of J (unit_rows) fix their components, d_U = -F_U, as the undamped step does; the
/// other rows R then solve the damped least-squares problem left:
///   (J_RR^T J_RR + lambda I) d_R = -J_RR^T (F_R + J_RU d_U),
/// lambda = damping x mean diagonal of J_RR^T J_RR. As lambda -> 0 this is the Newton step of the
/// whole J; eliminating U first shrinks the factorised matrix to the closed contacts' rows (the
/// normal rows alone for frictionless contacts, a third of the unknowns, whose factor costs
/// ~1/27 of the whole one). Returns false when the factorization fails or d is not a descent
/// direction of psi = |F|^2 / 2.
/// `sweeps_work`: the sweeps' cost this step is weighed against (polish_pays, with its work written
/// to `work` after the symbolic analysis); a step that does not pay is not factorised (returns
/// false, `work` set).
bool levenberg_marquardt_step(const LocalProblem& p, const std::vector<double>& rho, const std::vector<double>& r,
                              const std::vector<double>& u, double damping, Eigen::VectorXd& step, double& psi,
                              double& slope, double sweeps_work = std::numeric_limits<double>::infinity(),
                              double* work = nullptr) {
  using SparseRowMajor = Eigen::SparseMatrix<double, Eigen::RowMajor>;
  const auto m = static_cast<Eigen::Index>(3 * p.contact_count());
  std::vector<double> F;
  std::vector<Eigen::Triplet<double>> triplets;
  psi = 0.5 * alart_curnier(p, rho, r, u, F, &triplets);
  SparseRowMajor J(m, m);
  J.setFromTriplets(triplets.begin(), triplets.end());
  const Eigen::Map<const Eigen::VectorXd> residual(F.data(), m);
  const Eigen::VectorXd gradient = J.transpose() * residual;
  if (work != nullptr) *work = 0.0;

  // Unknowns renumbered: the reduced index of each row of R, -1 for a unit row.
  const std::vector<char> unit = unit_rows(J);
  std::vector<Eigen::Index> reduced(static_cast<std::size_t>(m), -1);
  Eigen::Index rows_left = 0;
  step.resize(m);
  for (Eigen::Index i = 0; i < m; ++i) {
    if (unit[static_cast<std::size_t>(i)] != 0) {
      step[i] = -F[static_cast<std::size_t>(i)];
    } else {
      reduced[static_cast<std::size_t>(i)] = rows_left++;
    }
  }
  if (rows_left > 0) {
    std::vector<Eigen::Triplet<double>> reduced_triplets;
    Eigen::VectorXd shifted_residual(rows_left);  // F_R + J_RU d_U
    for (Eigen::Index i = 0; i < m; ++i) {
      const Eigen::Index row = reduced[static_cast<std::size_t>(i)];
      if (row < 0) continue;
      double value = F[static_cast<std::size_t>(i)];
      for (SparseRowMajor::InnerIterator e(J, i); e; ++e) {
        const Eigen::Index column = reduced[static_cast<std::size_t>(e.col())];
        if (column >= 0) {
          if (e.value() != 0.0) reduced_triplets.emplace_back(row, column, e.value());
        } else {
          value += e.value() * step[e.col()];
        }
      }
      shifted_residual[row] = value;
    }
    SparseColumnMajor J_RR(rows_left, rows_left);
    J_RR.setFromTriplets(reduced_triplets.begin(), reduced_triplets.end());
    SparseColumnMajor normal_matrix = SparseColumnMajor(J_RR.transpose()) * J_RR;
    const double lambda = damping * normal_matrix.diagonal().sum() / static_cast<double>(rows_left);
    for (Eigen::Index d = 0; d < rows_left; ++d) normal_matrix.coeffRef(d, d) += lambda;
    // The pattern of J follows the contacts' regimes, so the symbolic analysis is redone each step.
    CountedLDLT factorization;
    factorization.analyzePattern(normal_matrix);
    const double step_work = newton_step_work(J_RR, normal_matrix, factorization);
    if (work != nullptr) *work = step_work;
    if (!polish_pays(step_work, sweeps_work)) return false;
    factorization.factorize(normal_matrix);
    if (factorization.info() != Eigen::Success) return false;
    const Eigen::VectorXd reduced_step = factorization.solve(-(J_RR.transpose() * shifted_residual));
    for (Eigen::Index i = 0; i < m; ++i) {
      const Eigen::Index row = reduced[static_cast<std::size_t>(i)];
      if (row >= 0) step[i] = reduced_step[row];
    }
  }
  slope = gradient.dot(step);
  return std::isfinite(slope) && slope < 0.0;
}

/// Levenberg-Marquardt on the Alart-Curnier function from the sweeps' iterate. The damping
/// starts at `polish_initial_damping` and drops tenfold after every step, so the steps become
/// Gauss-Newton steps, which converge fast even where the solution r is not unique
/// (rank-deficient W, four contacts per box face: Yamashita & Fukushima 2001 need a local error
/// bound, not a nonsingular Jacobian). psi = |F|^2/2 is not smooth where a contact changes
/// regime, and a monotone line search stalls at those kinks (seen on the BoxesStack problem),
/// so full steps are taken even when psi grows, for at most `watchdog` steps in a row
/// (Chamberlain et al. 1982's watchdog); then the walk restarts from the best iterate with an
/// Armijo backtracking step and ten times the damping. Keeps the iterate of lowest FCLib error.
PolishResult newton_polish(const LocalProblem& p, const LocalProblemOptions& options, std::vector<double>& r,
                           std::vector<double>& u, double& error,
                           double sweeps_work = std::numeric_limits<double>::infinity()) {
  constexpr int watchdog = 4;
  PolishResult result;
  const std::size_t m = 3 * p.contact_count();
  const std::vector<double> rho = normal_scalings(p);
  std::vector<double> trial_r(m), trial_u(m), scratch;
  double best_error = error;
  std::vector<double> best_r = r, best_u = u;      // lowest FCLib error (the output)
  std::vector<double> anchor_r = r, anchor_u = u;  // lowest psi (the watchdog's fallback)
  double anchor_psi = std::numeric_limits<double>::infinity();
  int nonmonotone_steps = 0;
  double damping = options.polish_initial_damping;
  Eigen::VectorXd step;
  for (int it = 0; it < options.polish_iterations && best_error > options.tolerance; ++it) {
    double psi = 0.0, slope = 0.0, work = 0.0;
    // The first step's symbolic analysis tells what a Newton step costs here: when the attempt's
    // expected steps cost more than the sweeps still needed, the attempt ends before factorising.
    const bool stepped =
        levenberg_marquardt_step(p, rho, r, u, damping, step, psi, slope,
                                 it == 0 ? sweeps_work : std::numeric_limits<double>::infinity(), &work);
    if (it == 0) result.step_work = work;
    if (!stepped) break;
    if (psi < anchor_psi) {
      anchor_psi = psi;
      anchor_r = r;
      anchor_u = u;
      nonmonotone_steps = 0;
    }
    ++result.iterations;
    double t = 1.0;
    bool accepted = false;
    const bool backtrack = nonmonotone_steps >= watchdog;
    if (backtrack) {
      // The watchdog fired: back to the best iterate, a safeguarded step from there.
      r = anchor_r;
      u = anchor_u;
      damping *= 10.0;
      if (!levenberg_marquardt_step(p, rho, r, u, damping, step, psi, slope)) break;
      nonmonotone_steps = 0;
    }
    for (int halving = 0; halving < (backtrack ? 30 : 1); ++halving, t *= 0.5) {
      for (std::size_t i = 0; i < m; ++i) trial_r[i] = r[i] + t * step[static_cast<Eigen::Index>(i)];
      trial_u = local_velocities(p, trial_r);
      const double trial_psi = 0.5 * alart_curnier(p, rho, trial_r, trial_u, scratch, nullptr);
      if (!std::isfinite(trial_psi)) continue;
      if (trial_psi <= psi + 1e-4 * t * slope) {
        accepted = true;
        break;
      }
      if (!backtrack) {
        accepted = true;  // a nonmonotone full step, counted by the watchdog
        ++nonmonotone_steps;
      }
    }
    if (!accepted) break;
    if (!backtrack) damping = std::max(damping * 0.1, 1e-14);
    r.swap(trial_r);
    u.swap(trial_u);
    const double trial_error = fclib_error(p, r, u);
    if (trial_error < best_error) {
      best_error = trial_error;
      best_r = r;
      best_u = u;
    }
  }
  result.improved = best_error < error;
  r = std::move(best_r);
  u = std::move(best_u);
  error = best_error;
  return result;
}

}  // namespace

int polish_solution(const LocalProblem& problem, const LocalProblemOptions& options, std::vector<double>& r,
                    std::vector<double>& u, double& error) {
  return newton_polish(problem, options, r, u, error).iterations;
}

std::vector<double> alart_curnier_function(const LocalProblem& problem, const std::vector<double>& r) {
  std::vector<double> F;
  alart_curnier(problem, normal_scalings(problem), r, local_velocities(problem, r), F, nullptr);
  return F;
}

std::vector<double> local_velocities(const LocalProblem& p, const std::vector<double>& r) {
  std::vector<double> u(p.q);
  for (int row = 0; row < p.W.rows; ++row) {
    double sum = 0.0;
    for (int k = p.W.row_start[static_cast<std::size_t>(row)]; k < p.W.row_start[static_cast<std::size_t>(row) + 1];
         ++k) {
      sum +=
          p.W.value[static_cast<std::size_t>(k)] * r[static_cast<std::size_t>(p.W.column[static_cast<std::size_t>(k)])];
    }
    u[static_cast<std::size_t>(row)] += sum;
  }
  return u;
}

double fclib_error(const LocalProblem& problem, const std::vector<double>& r, const std::vector<double>& u) {
  double f2 = 0.0, q2 = 0.0;
  for (std::size_t k = 0; k < problem.contact_count(); ++k) {
    const Vec3 rk(r[3 * k], r[3 * k + 1], r[3 * k + 2]);
    const Vec3 uk(u[3 * k], u[3 * k + 1], u[3 * k + 2]);
    f2 += natural_map(rk, uk, problem.mu[k]).squaredNorm();
  }
  for (double x : problem.q) q2 += x * x;
  const double q_norm = std::sqrt(q2);
  return std::sqrt(f2) / (q_norm > 0.0 ? q_norm : 1.0);
}

std::vector<double> point_residuals(const LocalProblem& problem, const std::vector<double>& r,
                                    const std::vector<double>& u) {
  std::vector<double> out(problem.contact_count());
  const SparseMatrix& W = problem.W;
  for (std::size_t k = 0; k < out.size(); ++k) {
    const auto row = static_cast<int>(3 * k);
    double normal_diagonal = 1.0;
    for (int e = W.row_start[static_cast<std::size_t>(row)]; e < W.row_start[static_cast<std::size_t>(row) + 1]; ++e) {
      const auto entry = static_cast<std::size_t>(e);
      if (W.column[entry] == row && W.value[entry] > 0.0) normal_diagonal = W.value[entry];
    }
    const Vec3 rk(r[3 * k], r[3 * k + 1], r[3 * k + 2]);
    const Vec3 uk(u[3 * k], u[3 * k + 1], u[3 * k + 2]);
    out[k] = natural_map(rk, uk, problem.mu[k], normal_diagonal).norm();
  }
  return out;
}

namespace {

/// When the sweeps' FCLib error is computed. It costs a product u = W r + q, as much as the sweep
/// itself, so once the error falls at a steady rate it is computed only where that rate says it
/// may have met the tolerance (NLGS converges linearly once the contacts' statuses settle: the
/// error falls by a constant factor a sweep), and at least every 16 sweeps, so that a slowing rate
/// costs at most 16 sweeps of overshoot.
struct ErrorChecks {
  std::vector<int> sweep;     ///< sweeps after which the error was computed
  std::vector<double> error;  ///< the errors then
  int next = 1;               ///< the next sweep to compute it after

  /// Whether the error is to be computed after sweep `k` (always after the last one).
  bool due(int k, int last) const { return k >= next || k == last; }

  /// The error after sweep `k`; sets the next check.
  void record(int k, double value, double tolerance) {
    sweep.push_back(k);
    error.push_back(value);
    const double left = sweeps_left(tolerance);
    // Every sweep while the rate is unknown or the tolerance is near; else 90 % of the way there.
    const int skip = std::isfinite(left) && left > 2.0 ? static_cast<int>(0.9 * left) : 1;
    next = k + std::clamp(skip, 1, 16);
  }

  /// Sweeps still needed at the rate of the last ten or more sweeps; infinite when the error does
  /// not fall (a stalled sweep) or too few errors are known.
  double sweeps_left(double tolerance) const {
    if (sweep.size() < 2) return std::numeric_limits<double>::infinity();
    std::size_t first = sweep.size() - 2;
    while (first > 0 && sweep.back() - sweep[first] < 10) --first;
    const double now = error.back(), before = error[first];
    const double rate = std::pow(now / before, 1.0 / static_cast<double>(sweep.back() - sweep[first]));
    if (!(rate < 1.0) || !(now > 0.0)) return std::numeric_limits<double>::infinity();
    return std::max(0.0, std::log(tolerance / now) / std::log(rate));
  }
};

/// Multiply-adds of one sweep: the rows of W once (the local velocities; the error's product
/// u = W r + q is computed only now and then, ErrorChecks).
double sweep_work(const LocalProblem& problem) { return static_cast<double>(problem.W.value.size()); }

}  // namespace

LocalProblemSolution solve_local_problem(const LocalProblem& problem, const LocalProblemOptions& options) {
  const std::size_t n = problem.contact_count();
  if (problem.W.rows != static_cast<int>(3 * n) || problem.q.size() != 3 * n ||
      problem.W.row_start.size() != 3 * n + 1) {
    throw std::invalid_argument("local problem: W, q and mu sizes disagree");
  }
  ExplicitProblem explicit_problem{problem, std::vector<Mat3>(n, Mat3::Zero()), {}, std::vector<Vec3>(n, Vec3::Zero())};
  for (std::size_t row = 0; row < 3 * n; ++row) {
    for (int e = problem.W.row_start[row]; e < problem.W.row_start[row + 1]; ++e) {
      const auto column = static_cast<std::size_t>(problem.W.column[static_cast<std::size_t>(e)]);
      if (column / 3 == row / 3) {
        explicit_problem.diagonal_blocks[row / 3](static_cast<Eigen::Index>(row % 3),
                                                  static_cast<Eigen::Index>(column % 3)) =
            problem.W.value[static_cast<std::size_t>(e)];
      }
    }
  }
  explicit_problem.inverse_blocks.reserve(n);
  for (const Mat3& block : explicit_problem.diagonal_blocks) explicit_problem.inverse_blocks.push_back(block.inverse());
  std::vector<std::size_t> order(n);
  std::iota(order.begin(), order.end(), std::size_t{0});
  if (options.order == SweepOrder::shuffled) {
    std::mt19937_64 generator(options.seed);
    std::shuffle(order.begin(), order.end(), generator);
  }

  LocalProblemSolution solution;
  solution.r.assign(3 * n, 0.0);
  auto flatten = [&] {
    for (std::size_t k = 0; k < n; ++k)
      for (int i = 0; i < 3; ++i) solution.r[3 * k + static_cast<std::size_t>(i)] = explicit_problem.r[k][i];
  };
  int next_polish = std::max(options.polish_after, 1);
  ErrorChecks checks;
  double newton_work = 0.0;  // a Newton step's (newton_step_work), once an attempt has measured it
  for (solution.iterations = 1; solution.iterations <= options.max_iterations; ++solution.iterations) {
    nlgs_sweep(explicit_problem, order, options.relaxation);
    const bool polish_due = options.polish == PolishMethod::newton && solution.iterations == next_polish;
    if (!checks.due(solution.iterations, options.max_iterations) && !polish_due) continue;
    flatten();
    solution.u = local_velocities(problem, solution.r);
    solution.error = fclib_error(problem, solution.r, solution.u);
    checks.record(solution.iterations, solution.error, options.tolerance);
    if (solution.error <= options.tolerance) {
      solution.converged = true;
      break;
    }
    if (polish_due) {
      next_polish *= 2;
      // Where the sweeps cannot reach the tolerance within max_iterations only Newton can, and an
      // attempt may cost what the remaining sweeps would, or up to affordable_polish_work.
      const double left = checks.sweeps_left(options.tolerance);
      const double budget = options.max_iterations - solution.iterations;
      const double sweeps_work =
          left <= budget ? left * sweep_work(problem) : std::max(budget * sweep_work(problem), affordable_polish_work);
      if (newton_work > 0.0 && !polish_pays(newton_work, sweeps_work)) continue;
      ++solution.polish_attempts;
      const PolishResult polish = newton_polish(problem, options, solution.r, solution.u, solution.error, sweeps_work);
      newton_work = std::max(newton_work, polish.step_work);
      solution.newton_iterations += polish.iterations;
      if (solution.error <= options.tolerance) {
        solution.converged = true;
        break;
      }
      if (polish.improved) {
        for (std::size_t k = 0; k < n; ++k)
          explicit_problem.r[k] = Vec3(solution.r[3 * k], solution.r[3 * k + 1], solution.r[3 * k + 2]);
      }
    }
  }
  solution.iterations = std::min(solution.iterations, options.max_iterations);
  if (n == 0) {
    solution.u = problem.q;
    solution.converged = true;
  }
  return solution;
}

}  // namespace rubble
