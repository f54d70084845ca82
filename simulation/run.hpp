#pragma once
// The run loop: steps a scene to its end time, prints progress, writes the run file.
#include <cstdint>
#include <filesystem>
#include <iosfwd>
#include <string>

#include "simulation/scene.hpp"

namespace rubble {

/// Raised when the state becomes non-finite or runs away; names the step, body and stage.
struct NumericalFailure : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// What the caller of run_scene controls besides the scene.
struct RunControl {
  std::ostream* progress = nullptr;  ///< where progress lines go (nullptr: silent)
  std::string scene_text;            ///< the scene as TOML, stored in the run file
};

/// What a run did.
struct RunSummary {
  std::int64_t steps = 0;              ///< steps taken
  double simulated_time = 0.0;         ///< s
  double wall_seconds = 0.0;           ///< s
  double mean_iterations = 0.0;        ///< NLGS sweeps per step
  double max_residual = 0.0;           ///< largest end-of-step residual
  std::int64_t unconverged_steps = 0;  ///< steps that hit max_iterations
  std::int64_t snapshots = 0;          ///< snapshots written
  std::filesystem::path run_file;      ///< the HDF5 file written
};

/// Runs `scene` from its initial state to its end time. Writes DIR/run.h5 (model, per-step
/// series, snapshots; docs/output-format.md) into scene.run.output.directory.
RunSummary run_scene(const Scene& scene, const RunControl& control);

}  // namespace rubble
