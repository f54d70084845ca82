#pragma once
// Run control for accretion runs, as pure functions of the scene: the automatic time step
// (`[time] dt = "auto"`), the "until at rest" stop condition (`[time] until = "rest"`) and the
// ETA of a run whose end is not known in advance. The rules are documented in docs/scene-file.md
// ("Automatic time step", "Stopping at rest"); the run loop (run.cpp) only calls these.
#include <cstddef>
#include <deque>
#include <optional>
#include <string>

#include "core/model.hpp"
#include "core/state.hpp"
#include "simulation/step.hpp"

namespace rubble {

/// The scales of a scene that the automatic time step and the rest threshold are built from.
struct SceneScales {
  std::size_t grains = 0;              ///< moving grains (walls excluded)
  bool has_polyhedra = false;          ///< some grains are polyhedra (their rest threshold is higher)
  double total_mass = 0.0;             ///< M, kg, of the grains
  double mean_mass = 0.0;              ///< kg per grain
  double min_diameter = 0.0;           ///< d_min, m: smallest grain diameter (2 x bounding radius)
  double cloud_radius = 0.0;           ///< R, m: max over grains of |x - x_cm| + bounding radius
  double mean_density = 0.0;           ///< rho, kg/m^3: grain mass / grain volume
  /// v_ref, m/s: the largest speed the scene's gravity can give a grain: free-fall velocity
  /// sqrt(2 G M / R) for self-gravity, sqrt(2 g H) (H: height of the grains along g plus d_min)
  /// for a uniform field, else the largest initial speed.
  double reference_velocity = 0.0;
  /// T, s: the gravitational time: 1/sqrt(G rho) for self-gravity (the LMGC90 accretion paper's characteristic
  /// time), sqrt(2 H / g) for a uniform field, d_min / v_ref without gravity.
  double characteristic_time = 0.0;
};

/// Measures the scales of the grains of `state`. A scene without gravity and at rest has
/// reference_velocity = 0 and characteristic_time = inf.
SceneScales scene_scales(const Model& model, const State& state, const GravitySettings& gravity);

/// Fraction of d_min a grain may travel in one step at the reference velocity (dt = "auto").
inline constexpr double auto_step_travel_fraction = 0.01;
/// Fraction of the characteristic time one step may last (dt = "auto"): the gravity integration
/// alone is accurate for h well below T (the EPSC 2018 presentation of a gravitational-aggregate code allows h < T/2).
inline constexpr double auto_step_time_fraction = 0.01;

/// The automatic time step and the numbers it came from.
struct TimeStepChoice {
  double time_step = 0.0;     ///< h, s
  SceneScales scales{};       ///< what it was computed from
  std::string rule;           ///< which bound decided, for messages: "travel" or "time"
};

/// dt = "auto": h = min(0.01 d_min / v_ref, 0.01 T) (SceneScales gives v_ref and T): a grain at
/// the largest speed gravity can give it moves 1% of the smallest diameter per step, so contacts
/// are found before grains interpenetrate much, and gravity's orbit is resolved by >= 100 steps
/// per characteristic time. Throws std::invalid_argument when neither bound is finite (no
/// gravity and no motion: nothing sets a time scale).
TimeStepChoice automatic_time_step(const Model& model, const State& state, const GravitySettings& gravity);

/// The default rest threshold as a fraction of 1/2 m_mean v_ref^2: grains at rest move at
/// <= 3% of the free-fall velocity. Measured on the 1000-sphere accretion (bench/RESULTS.md): the
/// energy peaks near 0.1 of 1/2 m v_ref^2 and its plateau (solver noise) sits near 3e-4 of it, so
/// 1e-3 is crossed once the aggregate has formed and stays above the noise.
inline constexpr double auto_rest_energy_fraction = 1e-3;
/// The same for scenes with polyhedral grains: their energy plateau is higher (1.8e-3 of
/// 1/2 m v_ref^2 in the 1000-polyhedra accretion, which 1e-3 never reaches: faces switching
/// between contact points keep the grains jiggling), so grains at rest move at <= 10% of v_ref.
inline constexpr double auto_rest_energy_fraction_polyhedra = 1e-2;
/// The default time the kinetic energy must stay below the threshold, as a fraction of T: half a
/// characteristic time, so the aggregate has settled, not merely slowed down for a moment.
inline constexpr double auto_rest_duration_fraction = 0.5;

/// "until at rest": the mean kinetic energy per grain must stay below `mean_kinetic_energy`
/// for `duration` seconds of simulated time.
struct RestCriterion {
  double mean_kinetic_energy = 0.0;  ///< J per grain, > 0
  double duration = 0.0;             ///< s of simulated time, >= 0
};

/// The automatic rest criterion: threshold 1e-3 x 1/2 m_mean v_ref^2 (1e-2 with polyhedra), duration 0.5 T, each
/// replaced by `threshold` or `duration` when those are > 0. Throws std::invalid_argument if a
/// needed scale is zero or infinite (give the values explicitly then).
RestCriterion automatic_rest_criterion(const SceneScales& scales, double threshold = 0.0, double duration = 0.0);

/// Watches the mean kinetic energy per grain, step after step, and says when the grains are at
/// rest. A cloud that starts at rest is not "at rest" yet: the detector arms only once the
/// energy has exceeded the threshold, and then reports rest when it has stayed below the
/// threshold for criterion.duration (so a run that never moves stops at its end time instead).
struct RestDetector {
  RestCriterion criterion{};  ///< threshold and duration
  bool armed = false;         ///< the energy has been above the threshold at least once
  /// s, simulated time since which the energy has been below the threshold (nullopt: above now)
  std::optional<double> below_since;
  /// (t, ln E) samples for the decay rate, spaced by >= decay_window / 16, covering decay_window.
  std::deque<std::pair<double, double>> history;
  double decay_window = 0.0;  ///< s of simulated time the decay rate is fitted over (0: 10% of t)

  /// Records the mean kinetic energy at `time`; returns true when the grains are at rest.
  bool update(double time, double mean_kinetic_energy);

  /// Estimated simulated time at which update() will return true, from the exponential decay
  /// of the energy over the last decay window: E(t) = E_now exp(-(t - t_now)/tau), rest at
  /// t_now + tau ln(E_now / threshold) + the remaining duration. nullopt while unknown (before
  /// the first rise, or when the energy is not decaying).
  std::optional<double> estimated_rest_time() const;
};

/// The most steps a run may take: a guard against typos in an exponent (dt = 1e-40, an end time
/// of 1e9 s), which would otherwise ask for more steps than any run can take. The scene file's
/// [time] keys and `rubble run --end-time` are held to it alike.
inline constexpr double max_run_steps = 1e12;

/// What is wrong with an end time for a run from `start_time` by steps of `time_step` (s), as
/// "expected ..., got ..."; nullopt when it is fine: it must be finite, at least one step after
/// the start, and at most max_run_steps steps after it.
std::optional<std::string> end_time_problem(double end_time, double start_time, double time_step);

/// The wall-time ETA of a run, s: from the simulated-time rate of the session so far to the
/// simulated time `target_time`. Negative when unknown (no progress yet).
double eta_seconds(double elapsed_wall, double start_time, double time_now, double target_time);

}  // namespace rubble
