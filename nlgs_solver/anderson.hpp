#pragma once
// Anderson acceleration of the sweeps (nlgs_solver/README.md, "Anderson acceleration"): a sweep
// is a fixed-point map x -> G(x) of the impulses (the bodies' velocities follow them affinely),
// and Gauss-Seidel's slow modes are nearly linear once the contacts keep their status.
// After each sweep the next iterate is the combination of the last sweeps' results whose
// combined change f = G(x) - x is least (Anderson 1965; the "type II" form of Walker and Ni
// 2011), projected back on the Coulomb cones; a sweep whose residual does not fall below the
// previous one's empties the history (and solve_contacts ends the mixing for the step after a
// window of sweeps without progress, nlgs.cpp's ProgressWindow).
#include <cstddef>
#include <vector>

#include "nlgs_solver/compact_problem.hpp"

namespace rubble {

/// The history and the small least-squares problem of Anderson acceleration, kept for one step.
/// Serial and in a fixed order: the same iterate for any thread count.
class AndersonAcceleration {
 public:
  /// `depth`: sweeps remembered (m of Walker and Ni), >= 1. The points loaded in `compact` now
  /// (warm start) are live from the start.
  AndersonAcceleration(const CompactProblem& compact, int depth);

  /// Before a sweep: remembers the impulses x the sweep starts from.
  void before_sweep(const CompactProblem& compact);

  /// After the sweep (G(x) in `compact`), with its relative residual and the relaxation it used:
  /// records it and, when the history allows, replaces the iterate by the mixed one.
  void after_sweep(CompactProblem& compact, double relative_residual, double relaxation);

  /// Forgets the history: the iterate changed outside the sweeps (a polish).
  void restart();

 private:
  /// The ring slot of the difference `age` sweeps old (0: the newest).
  std::size_t slot(int age) const { return static_cast<std::size_t>((newest_ - age + depth_) % depth_); }
  /// Adds G(x) - G(x_previous) and f - f_previous (`size` entries) to the ring, with their products.
  void add_difference(std::size_t size);
  /// Makes live every point whose impulse is not zero now (and was zero until now).
  void add_new_live_points(const CompactProblem& compact);

  static constexpr std::size_t not_live = static_cast<std::size_t>(-1);
  int depth_;
  /// The points whose impulse has not been zero at some sweep of the step: the mixed state. The
  /// others (most points of a deposit are open) have zero entries everywhere and are left out,
  /// so the mixing costs what the loaded points cost, not what the whole list does.
  std::vector<std::size_t> live_;
  std::vector<std::size_t> live_position_;             ///< per point, its index in live_, or not_live
  std::vector<double> start_;                          ///< x: the impulses before the sweep
  std::vector<double> g_, f_;                          ///< G(x), and f = W_nn (G(x) - x)
  std::vector<double> g_previous_, f_previous_;        ///< the same of the sweep before
  std::vector<std::vector<float>> delta_g_, delta_f_;  ///< ring of the last `depth` differences
  std::vector<double> gram_;                           ///< dF_a . dF_b, depth x depth, by slot
  std::vector<double> right_;                          ///< dF_a . f, by slot
  int count_ = 0;                                      ///< differences held (<= depth)
  int newest_ = -1;                                    ///< ring slot of the newest difference
  bool have_previous_ = false;
  double previous_residual_ = 0.0;
  double previous_relaxation_ = 0.0;
};

}  // namespace rubble
