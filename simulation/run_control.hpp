#pragma once
// Run control for accretion runs, as pure functions of the scene: the automatic time step
// (`[time] dt = "auto"`), the "until at rest" stop condition (`[time] until = "rest"`) and the
// ETA of a run whose end is not known in advance. The rules are documented in docs/scene-file.md
// ("Automatic time step", "Stopping at rest"); the run loop (run.cpp) only calls these.
#include <cstddef>
#include <deque>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "core/contact.hpp"

#include "core/model.hpp"
#include "core/state.hpp"
#include "simulation/step.hpp"

namespace rubble {

/// The scales of a scene that the automatic time step and the rest threshold are built from.
struct SceneScales {
  std::size_t grains = 0;      ///< moving grains (walls excluded)
  bool has_polyhedra = false;  ///< some grains are polyhedra
  double total_mass = 0.0;     ///< M, kg, of the grains
  double mean_mass = 0.0;      ///< kg per grain
  double min_diameter = 0.0;   ///< d_min, m: smallest grain diameter (2 x bounding radius)
  double cloud_radius = 0.0;   ///< R, m: max over grains of |x - x_cm| + bounding radius
  double mean_density = 0.0;   ///< rho, kg/m^3: grain mass / grain volume
  /// v_ref, m/s: the largest speed the scene's gravity can give a grain: free-fall velocity
  /// sqrt(2 G M / R) for self-gravity, sqrt(2 g H) (H: height of the grains along g plus d_min)
  /// for a uniform field, else the largest initial speed.
  double reference_velocity = 0.0;
  /// v_rest, m/s: the speed scale of the rest criterion. Self-gravity and a central field: v_ref
  /// (the aggregate's own free-fall speed). Uniform field: sqrt(g d_min), the speed of a fall over
  /// one grain size, which does not depend on the height the grains were dropped from (a grain at
  /// rest in a deposit moves much less than that). No gravity: v_ref.
  double rest_reference_velocity = 0.0;
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
  double time_step = 0.0;  ///< h, s
  SceneScales scales{};    ///< what it was computed from
  std::string rule;        ///< which bound decided, for messages: "travel" or "time"
};

/// dt = "auto": h = min(0.01 d_min / v_ref, 0.01 T) (SceneScales gives v_ref and T): a grain at
/// the largest speed gravity can give it moves 1% of the smallest diameter per step, so contacts
/// are found before grains interpenetrate much, and gravity's orbit is resolved by >= 100 steps
/// per characteristic time. Throws std::invalid_argument when neither bound is finite (no
/// gravity and no motion: nothing sets a time scale).
TimeStepChoice automatic_time_step(const Model& model, const State& state, const GravitySettings& gravity);

/// The default rest speed as a fraction of the rest reference velocity (SceneScales: v_ref under
/// self-gravity, sqrt(g d_min) under uniform gravity): grains at rest move at less than 5% of the
/// free-fall velocity, at the quantile below. In the 1000-sphere
/// accretion the 99th percentile falls below it at t = 4 700 s and settles at 1.5-3% of v_ref
/// (the solver's noise) after 8 000 s (docs/scene-file.md, "Stopping at rest").
inline constexpr double auto_rest_speed_fraction = 0.05;
/// The default quantile of the grain speeds held to the rest speed: the 99th percentile, so that a
/// handful of rattlers (grains without neighbours, which the solver's noise keeps jiggling) do not
/// hold up the run, while 1% of moving grains does (at 200 grains: the 2 fastest may move).
inline constexpr double auto_rest_quantile = 0.99;
/// The default bound on the change of the coordination number Z over the rest duration, for 1000
/// grains: an aggregate that still compacts gains contacts (force-bearing Z from 3.85 to 4.71 in
/// the 1000-sphere accretion between t = 60 and 125 min, issue 18) though its grains are slow. The
/// watcher's Z counts geometric contacts (rest_contact_gap_fraction); near-contacts at the gap
/// tolerance still come and go, each moving Z by 2/N, and the sum of N such independent changes
/// fluctuates as sqrt(N): Z's noise falls as 1/sqrt(N). The automatic bound is therefore
/// 0.05 sqrt(1000 / N) (0.14 for 125 grains, 0.027 for 3375): in the settled 1000-sphere aggregate
/// Z moved by 0.034-0.038 within half a characteristic time.
inline constexpr double auto_rest_coordination_change = 0.05;
/// The grain count at which the automatic Z bound is auto_rest_coordination_change.
inline constexpr double auto_rest_coordination_grains = 1000.0;
/// The default bound on the fraction of contacts created or broken over the rest duration
/// (|P xor P0| / |P union P0|): rearrangements that leave Z unchanged. Near-contacts at the gap
/// tolerance come and go with the solver's noise: 1-2% of them between two snapshots 60 s apart
/// in a settled 1000-sphere aggregate, 10-20% over half a characteristic time.
inline constexpr double auto_rest_contact_change = 0.2;
/// The default time every condition must hold, as a fraction of T: half a characteristic time,
/// so the aggregate has settled, not merely slowed down for a moment.
inline constexpr double auto_rest_duration_fraction = 0.5;
/// Two bodies are in contact for the rest watcher when their gap is at most this fraction of the
/// smaller bounding radius: geometric contacts. (Force-bearing ones, normal impulse > 0, flicker
/// in a frictionless aggregate whose contact forces are not unique, Radjai & Dubois 2011: 15-20%
/// of them change between two snapshots of a settled aggregate.)
inline constexpr double rest_contact_gap_fraction = 0.01;

/// "until at rest": the grains are at rest when, for `duration` seconds of simulated time,
/// (1) the `quantile` of the grain speeds |v| + |w| r (r: bounding radius, so a spinning grain
/// counts by the speed of its surface) stays below `speed`, (2) the coordination number Z stays
/// within `coordination_change` (at least 4 / N_p: two contacts) of its value at the start of
/// that time, and (3) the fraction of
/// contacts created or broken since then stays below `contact_change`.
struct RestCriterion {
  double speed = 0.0;                    ///< m/s, > 0: rest speed
  double quantile = auto_rest_quantile;  ///< in (0, 1]: which quantile of the speeds (1: the fastest grain)
  double coordination_change = auto_rest_coordination_change;  ///< |Z - Z0| allowed, >= 0
  double contact_change = auto_rest_contact_change;            ///< fraction of contacts changed allowed, in [0, 1]
  double duration = 0.0;                                       ///< s of simulated time, >= 0
};

/// The automatic rest criterion: speed 0.05 v_rest (SceneScales::rest_reference_velocity), duration 0.5 T,
/// Z bound 0.05 sqrt(1000 / N), the quantile and changes at their
/// defaults; `speed` or `duration` > 0 replace the automatic values. Throws std::invalid_argument
/// if a needed scale is zero or infinite (give the values explicitly then).
/// `coordination_change` > 0 replaces the automatic Z bound 0.05 sqrt(1000 / N).
RestCriterion automatic_rest_criterion(const SceneScales& scales, double speed = 0.0, double duration = 0.0,
                                       double coordination_change = 0.0);

/// What the rest watcher reads of the grains at one step (rest_sample).
struct RestSample {
  double time = 0.0;          ///< s
  double speed = 0.0;         ///< m/s, the criterion's quantile of |v| + |w| r over the moving grains
  double coordination = 0.0;  ///< Z = 2 N_c / N_p over geometric grain-grain contacts (rest_contact_gap_fraction)
  std::size_t grains = 0;     ///< N_p
  /// Body pairs in geometric contact (gap <= rest_contact_gap_fraction x the smaller bounding
  /// radius; lower id first), sorted: grain-grain and grain-wall, so that a grain leaving a wall
  /// counts as a change.
  std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs;
};

/// Measures a RestSample from the end-of-step state and that step's contacts. O(N + C log C).
RestSample rest_sample(const Model& model, const State& state, const ContactList& contacts, double quantile);

/// Fraction of pairs in one sorted pair list and not the other: |a xor b| / |a union b| (0 when
/// both are empty).
double contact_change_fraction(std::span<const std::pair<std::uint32_t, std::uint32_t>> a,
                               std::span<const std::pair<std::uint32_t, std::uint32_t>> b);

/// Which rest condition failed last (or none): what the progress line and /run@stop_reason say.
enum class RestCondition : std::uint8_t {
  none = 0,          ///< all hold (or nothing measured yet)
  speed = 1,         ///< the speed quantile is above the rest speed
  coordination = 2,  ///< Z moved more than coordination_change
  contacts = 3,      ///< more than contact_change of the contacts changed
};

/// Short name of a condition ("speed", "coordination", "contacts", "none").
std::string_view rest_condition_name(RestCondition condition);

/// Watches the grains step after step and says when they are at rest (RestCriterion). A cloud
/// that starts at rest is not "at rest" yet: the watcher arms only once the speed quantile has
/// exceeded the rest speed. Then a window opens at the first step where the speed is below it,
/// with Z and the contact set of that step as reference; any step whose speed is above, or whose
/// Z or contacts moved beyond the bounds from the reference, closes the window (a new one opens at
/// the next quiet step, with that step as reference). Rest is reported when a window has lasted
/// criterion.duration.
struct RestDetector {
  RestCriterion criterion{};            ///< thresholds and duration
  bool armed = false;                   ///< the speed has been above the rest speed at least once
  std::optional<double> window_start;   ///< s, start of the current quiet window (nullopt: none open)
  double reference_coordination = 0.0;  ///< Z at window_start
  std::vector<std::pair<std::uint32_t, std::uint32_t>> reference_pairs;  ///< contact pairs at window_start
  RestCondition last_failure = RestCondition::none;                      ///< the condition that closed the last window
  /// Last measured values (for the progress line and the run file).
  double last_speed = 0.0;                ///< m/s
  double last_coordination_change = 0.0;  ///< |Z - Z0|
  double last_contact_change = 0.0;       ///< fraction of contacts changed since window_start
  /// (t, ln s) samples of the speed quantile for the decay rate, spaced by >= decay_window / 16,
  /// covering decay_window.
  std::deque<std::pair<double, double>> history;
  double decay_window = 0.0;  ///< s of simulated time the decay rate is fitted over (0: 10% of t)

  /// Records a sample; returns true when the grains are at rest.
  bool update(const RestSample& sample);

  /// Estimated simulated time at which update() will return true, from the exponential decay
  /// of the speed over the last decay window: s(t) = s_now exp(-(t - t_now)/tau), below the rest
  /// speed at t_now + tau ln(s_now / speed), plus the duration. nullopt while unknown (before
  /// the first rise, or when the speed is not decaying). Changes of Z or contacts may still
  /// delay the rest past it.
  std::optional<double> estimated_rest_time() const;
};

/// True when some grain of `state` moves (nonzero velocity or angular velocity): the rest watcher
/// then starts armed. A cloud released at rest must move before it can come to rest; a state taken
/// from a run that already moved (rubble export, rubble run --from) need not move more.
bool rest_starts_armed(const Model& model, const State& state);

/// The "until at rest" thresholds as one line: "p99(|v| + |w| r) < 2.6e-03 m/s, |dZ| < 0.02,
/// contacts changed < 5% for 1720 s".
std::string describe_rest_criterion(const RestCriterion& criterion);

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
