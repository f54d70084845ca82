#pragma once
// Helpers of the run loop (run.cpp), kept apart so that run.cpp holds only the loop's pieces: the
// end-of-step checks for a non-finite or runaway state, the search for the stage that failed, the
// check of the grains' mass properties, and the texts of progress lines and stop reasons.
#include <cstddef>
#include <optional>
#include <string>

#include "core/model.hpp"
#include "core/state.hpp"
#include "simulation/run_control.hpp"
#include "simulation/step.hpp"

namespace rubble::run_support {

/// "1h02m", "3m05s", "12s" ("?" for a negative or non-finite time).
std::string format_duration(double seconds);

/// The runaway bound on body b's speed (m/s), or a negative number when there is none.
double speed_limit(const Model& model, std::size_t b, double h, double max_speed);

/// A bad body and what is wrong with it.
struct Problem {
  std::size_t body = 0;  ///< body id
  std::string what;      ///< what is wrong, in words
};

/// The first body (lowest id) whose end-of-step state is non-finite or runs away. Cheap: one
/// pass over the bodies per step.
std::optional<Problem> check_state(const Model& model, const State& state, double h, double max_speed);

/// After a failed step, finds the first stage whose output was bad (its name), reading the
/// stages' outputs left in the workspace in step order; may refine `problem`.
std::string locate_failure(const Model& model, const State& before, const StepWorkspace& workspace,
                           const StepOptions& options, double max_speed, Problem& problem);

/// Throws std::invalid_argument (bad input) if a grain's mass, inertia or size is not finite and positive.
void check_mass_properties(const Model& model);

/// The system's reason in an I/O error message (HDF5's buried "error message = '...'").
std::string short_reason(const std::string& what);

/// The rest watcher's measured values against their thresholds, for the progress line.
std::string rest_progress(const RestDetector& rest, double time);

/// The sentence for a run stopped at rest.
std::string rest_reason(const RestDetector& rest, double time);

}  // namespace rubble::run_support
