#pragma once
// Branching: a new run from a state saved by another run (`rubble run SCENE --from RUN_DIR[:...]`,
// docs/checkpoints.md "Branching"), and a saved state written back as a scene (`rubble export`).
// The state (bodies' positions, orientations, velocities, angular velocities, time and step)
// comes from the saved run; everything else (materials, contact laws, solver, gravity, dt, end)
// from the scene. The bodies must be the same: count, kind and size of each.
#include <cstdint>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>

#include "core/contact.hpp"
#include "core/input_error.hpp"
#include "core/model.hpp"
#include "core/state.hpp"

namespace rubble {

/// A saved state that cannot be used for a branch or an export (no such run, snapshot or time;
/// damaged file; bodies that differ from the scene's). what() names the file and what differs.
/// An input error (exit code 2).
struct BranchError : InputError {
  using InputError::InputError;
};

/// Which saved state of a run: `DIR` or `DIR:last` (the newest valid checkpoint, bit for bit; the
/// run file's last snapshot when the folder has no checkpoint), `DIR:snapshot=K` (snapshot K of
/// DIR/run.h5, 0-based; negative counts from the end: -1 is the last), `DIR:time=T` (the last
/// snapshot at or before T s). DIR may also be a run file (RUN.h5) itself, for snapshots.
struct BranchSource {
  /// How the state is picked.
  enum class Kind { last, snapshot, time };
  std::filesystem::path path;  ///< the run folder, or a run file
  Kind kind = Kind::last;      ///< which state
  std::int64_t snapshot = -1;  ///< Kind::snapshot: the index (negative: from the end)
  double time = 0.0;           ///< Kind::time: s
};

/// Parses `DIR`, `DIR:last`, `DIR:snapshot=K`, `DIR:time=T`. Throws BranchError on a malformed
/// selector (a path that merely contains ':' and no selector is taken whole).
BranchSource parse_branch_source(std::string_view text);

/// A saved state and where it came from.
struct SavedState {
  State state;              ///< every body's state, bit for bit as saved
  Model model;              ///< the saved run's model (to check the bodies against a scene's)
  std::string scene_text;   ///< the saved run's scene (/scene or the checkpoint's)
  std::string description;  ///< "checkpoint F (step K, t = T s)" or "snapshot K of F (step, t)"
  /// The saved run's last contacts with their impulses (a checkpoint's warm start); empty when the
  /// state comes from a snapshot, whose contacts lack the ids the warm start matches on.
  ContactList contacts;
  double time_step = 0.0;  ///< s, the saved run's dt (with `contacts`; 0 when they are empty)
};

/// The warm start of a branch's first step: the saved contacts with their impulses (and angular
/// impulses) multiplied by time_step / saved.time_step, so that a pile at rest keeps the same
/// forces when the branch changes dt (an impulse is a force times the step). Without it a branch
/// solved its first step from zero impulses: on a deposit of 1 500 grains at rest the sweep cap
/// stopped that solve short of its tolerance and the step set the grains moving (docs/checkpoints.md,
/// "Branching"). Empty when `saved` has no contacts.
ContactList branch_warm_start(const SavedState& saved, double time_step);

/// Reads the state `source` names. Throws BranchError (naming the file) when it cannot.
SavedState load_saved_state(const BranchSource& source);

/// What differs between the bodies of a scene and those of a saved run, as one sentence naming
/// the first difference (count, or body id with kind, size or vertex count); nullopt when they
/// are the same bodies. Sizes compare to a relative 1e-9: the same shapes written as a scene and
/// read back (rubble export) must match.
std::optional<std::string> body_mismatch(const Model& scene_model, const Model& saved_model);

}  // namespace rubble
