// Anderson acceleration of the sweeps (anderson.hpp).
#include "nlgs_solver/anderson.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <cstddef>
#include <limits>

#include "nlgs_solver/coulomb.hpp"

namespace rubble {

AndersonAcceleration::AndersonAcceleration(const CompactProblem& compact, int depth)
    : depth_(depth),
      live_position_(compact.points.size(), not_live),
      delta_g_(static_cast<std::size_t>(depth)),
      delta_f_(static_cast<std::size_t>(depth)),
      gram_(static_cast<std::size_t>(depth * depth), 0.0),
      right_(static_cast<std::size_t>(depth), 0.0) {
  add_new_live_points(compact);
}

void AndersonAcceleration::add_new_live_points(const CompactProblem& compact) {
  for (std::size_t p = 0; p < compact.points.size(); ++p) {
    if (live_position_[p] != not_live || compact.points[p].impulse == Vec3::Zero()) continue;
    // Until now its impulse was 0 at every sweep's start and end: its past entries are zeros.
    live_position_[p] = live_.size();
    live_.push_back(p);
    const std::size_t size = 3 * live_.size();
    for (std::vector<double>* v : {&start_, &g_, &f_, &g_previous_, &f_previous_}) v->resize(size, 0.0);
    for (std::size_t s = 0; s < delta_g_.size(); ++s) {
      delta_g_[s].resize(size, 0.0F);
      delta_f_[s].resize(size, 0.0F);
    }
  }
}

void AndersonAcceleration::before_sweep(const CompactProblem& compact) {
  for (std::size_t l = 0; l < live_.size(); ++l) {
    for (int j = 0; j < 3; ++j) start_[3 * l + static_cast<std::size_t>(j)] = compact.points[live_[l]].impulse(j);
  }
}

void AndersonAcceleration::restart() {
  count_ = 0;
  newest_ = -1;
  have_previous_ = false;
}

void AndersonAcceleration::after_sweep(CompactProblem& compact, double relative_residual, double relaxation) {
  add_new_live_points(compact);
  // G(x), and f = G(x) - x in velocity units (W_nn r, as the residual), over the live points.
  const std::size_t size = 3 * live_.size();
  for (std::size_t l = 0; l < live_.size(); ++l) {
    const CompactProblem::Point& c = compact.points[live_[l]];
    for (int j = 0; j < 3; ++j) {
      const std::size_t i = 3 * l + static_cast<std::size_t>(j);
      g_[i] = c.impulse(j);
      f_[i] = c.delassus(0, 0) * (g_[i] - start_[i]);
    }
  }
  // A sweep that did not lower the residual: the mixing stopped helping (statuses changed, the
  // map is far from linear here); start again from this sweep. A change of the relaxation changes
  // the map itself.
  if (have_previous_ && (relative_residual >= previous_residual_ || relaxation != previous_relaxation_)) restart();
  previous_residual_ = relative_residual;
  previous_relaxation_ = relaxation;
  if (have_previous_) add_difference(size);
  g_previous_.swap(g_);
  f_previous_.swap(f_);
  have_previous_ = true;
  if (count_ == 0) return;

  // gamma = argmin || f - dF gamma ||, by the normal equations (m <= a few), slightly regularised:
  // the differences become nearly dependent as the sweeps converge.
  Eigen::MatrixXd normal(count_, count_);
  Eigen::VectorXd right(count_);
  for (int a = 0; a < count_; ++a) {
    const std::size_t sa = slot(a);
    for (int b = 0; b < count_; ++b) normal(a, b) = gram_[sa * static_cast<std::size_t>(depth_) + slot(b)];
    right(a) = right_[sa];
  }
  normal.diagonal().array() += 1e-10 * normal.trace() + std::numeric_limits<double>::min();
  const Eigen::VectorXd gamma = normal.ldlt().solve(right);

  // x = G(x) - dG gamma (g_previous_ holds G(x)), projected on the cones. The velocities follow
  // the impulses (v = v_free + M^-1 H r): each point's change is applied to its bodies, which also
  // adds it to their drifts, so the open points the sweeps pass by (CompactProblem::stays_open)
  // stay sound.
  for (std::size_t l = 0; l < live_.size(); ++l) {
    Vec3 mixed(g_previous_[3 * l], g_previous_[3 * l + 1], g_previous_[3 * l + 2]);
    for (int a = 0; a < count_; ++a) {
      const std::vector<float>& delta = delta_g_[slot(a)];
      for (int j = 0; j < 3; ++j)
        mixed(j) -= gamma(a) * static_cast<double>(delta[3 * l + static_cast<std::size_t>(j)]);
    }
    const std::size_t p = live_[l];
    CompactProblem::Point& c = compact.points[p];
    const Vec3 next = project_onto_coulomb_cone(mixed, c.friction_coefficient);
    if (next == c.impulse) continue;
    compact.forget_open_point(p);
    const Vec3 change = next - c.impulse;
    c.impulse = next;
    compact.apply_impulse_change(p, change);
  }
}

void AndersonAcceleration::add_difference(std::size_t size) {
  newest_ = (newest_ + 1) % depth_;
  if (count_ < depth_) ++count_;
  const std::size_t fresh = slot(0);
  std::vector<float>& delta_f = delta_f_[fresh];
  std::vector<float>& delta_g = delta_g_[fresh];
  for (std::size_t i = 0; i < size; ++i) {
    delta_f[i] = static_cast<float>(f_[i] - f_previous_[i]);
    delta_g[i] = static_cast<float>(g_[i] - g_previous_[i]);
  }
  // The new row of dF^T dF, and dF^T f: dF_a . f = dF_a . f_previous + dF_a . dF_fresh for the
  // older ones, the fresh one's in full.
  double fresh_right = 0.0;
  for (std::size_t i = 0; i < size; ++i) fresh_right += static_cast<double>(delta_f[i]) * f_[i];
  for (int a = 0; a < count_; ++a) {
    const std::size_t other = slot(a);
    const std::vector<float>& y = delta_f_[other];
    double value = 0.0;
    for (std::size_t i = 0; i < size; ++i) value += static_cast<double>(delta_f[i]) * static_cast<double>(y[i]);
    gram_[fresh * static_cast<std::size_t>(depth_) + other] = value;
    gram_[other * static_cast<std::size_t>(depth_) + fresh] = value;
    if (a > 0) right_[other] += value;
  }
  right_[fresh] = fresh_right;
}

}  // namespace rubble
