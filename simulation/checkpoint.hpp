#pragma once
// Checkpoints: everything a run needs to go on from step K exactly as if it had never stopped
// (docs/checkpoints.md). A checkpoint is the scene text (the model is rebuilt from it), the State
// (core/state.hpp), the StepCarry (simulation/step_carry.hpp: last step's contacts with their
// impulses = the warm start, the detection memory, the held self-gravity field), and the run
// loop's own bookkeeping: RunProgress (end step, snapshot cadence, rows and snapshots already in
// the run file, summary accumulators) and RestWatch (the at-rest watcher's memory).
//
// File format (one binary file per checkpoint, little-endian as written by x86-64/aarch64):
//   "RUBBLECK" | u32 format version | u32 0 | u64 payload size P | P payload bytes | u64 CRC-64
// where the CRC-64 (ECMA-182 polynomial, reflected, as in xz: check value of "123456789" is
// 0x995DC9BBDF1939FA) covers every byte before it. A file whose size, magic, version or CRC does
// not match is rejected with a CheckpointError, so a truncated or damaged checkpoint is never
// loaded. The payload's layout is in checkpoint_codec.hpp (put_payload) and docs/checkpoints.md.
//
// Files live in DIR/checkpoints/ as step-NNNNNNNNNNNN.ckpt (NNNN = state.step, 12 digits, so that
// names sort by step). write_checkpoint streams the file from the run's own objects (a
// CheckpointView: no copy of the state or contacts, a 1 MiB buffer and a running CRC; the payload
// size in the header comes from a counting pass), writes it as a temporary file, fsyncs it, renames
// it into place and fsyncs the folder (POSIX: the rename is atomic, so a reader sees the old set of
// files or the new one, never half a file), then deletes all but the newest `keep` checkpoints.
//
// Code: checkpoint_format.cpp (bytes: CRC, serialise, parse, state hash), checkpoint.cpp (files:
// streamed atomic write, retention, listing, loading; the rest watcher's save and restore).
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "core/input_error.hpp"
#include "core/state.hpp"
#include "simulation/run_control.hpp"
#include "simulation/step_carry.hpp"

namespace rubble {

/// A checkpoint that cannot be used (missing, truncated, wrong format, checksum mismatch,
/// inconsistent content). what() names the file. An input error (exit code 2).
struct CheckpointError : InputError {
  using InputError::InputError;
};

/// The run loop's bookkeeping, saved so that a resumed run continues its outputs with no step
/// written twice or missing and ends with the same summary.
struct RunProgress {
  std::int64_t first_step = 0;  ///< state.step when the run started (the scene's initial step)
  /// s, state.time when the run started: the scene's initial time, or the saved state's for a run
  /// branched from another (rubble run SCENE --from DIR); the end step is counted from it.
  double first_time = 0.0;
  std::int64_t end_step = 0;           ///< state.step at which the run ends
  std::int64_t snapshot_period = 1;    ///< steps between snapshots, counted from first_step
  std::int64_t series_rows = 0;        ///< rows in the run file's /series up to this checkpoint
  std::int64_t snapshots = 0;          ///< snapshots in the run file up to this checkpoint
  double iteration_sum = 0.0;          ///< sum of NLGS sweeps over the steps taken
  double max_residual = 0.0;           ///< largest end-of-step residual so far
  std::int64_t unconverged_steps = 0;  ///< steps that hit max_iterations so far
  double wall_seconds = 0.0;           ///< wall time spent stepping so far, over every session
};

/// The memory of the "until at rest" watcher (simulation/run_control.hpp, RestDetector), so that
/// a resumed run stops at rest on the same step as an uninterrupted one.
struct RestWatch {
  bool armed = false;                   ///< the speed quantile has been above the rest speed
  bool window_open = false;             ///< window_start is set
  double window_start = 0.0;            ///< s, start of the current quiet window
  double reference_coordination = 0.0;  ///< Z at window_start
  /// Force-bearing contact pairs at window_start (sorted, lower id first).
  std::vector<std::pair<std::uint32_t, std::uint32_t>> reference_pairs;
  std::uint8_t last_failure = 0;                   ///< RestCondition that closed the last window
  double last_speed = 0.0;                         ///< m/s, last measured speed quantile
  double last_coordination_change = 0.0;           ///< last |Z - Z0|
  double last_contact_change = 0.0;                ///< last fraction of contacts changed
  std::vector<std::pair<double, double>> history;  ///< (t, ln s) samples of the decay fit
  double decay_window = 0.0;                       ///< s, span of the decay fit
};

/// Everything saved at a checkpoint.
struct Checkpoint {
  std::string scene_text;    ///< the scene as TOML (the model is rebuilt from it on resume)
  std::string scene_source;  ///< the name the scene was parsed under (anchors relative paths)
  double end_time = 0.0;     ///< s, the run's end time (after any --end-time override)
  /// Seed of the scene's random draws. A run draws no random numbers while stepping (the only
  /// generators are the scene's grain generators, which run once when the scene is parsed), so
  /// the seed is the whole random-generator state; it is saved to rebuild the same grains.
  std::uint64_t seed = 1;
  State state;           ///< positions, orientations, velocities, time, step
  StepCarry carry;       ///< what the last step hands to the next (warm start, detection memory, held gravity)
  RunProgress progress;  ///< run-loop bookkeeping
  RestWatch rest;        ///< the at-rest watcher's memory (until = "rest")
};

/// A checkpoint's content by reference: what write_checkpoint saves, taken straight from the run
/// loop's objects so that writing a checkpoint copies neither the State nor the contacts. Field
/// by field the same as Checkpoint (see there); the referenced objects must outlive the view.
struct CheckpointView {
  const std::string& scene_text;    ///< Checkpoint::scene_text
  const std::string& scene_source;  ///< Checkpoint::scene_source
  double end_time;                  ///< s, Checkpoint::end_time
  std::uint64_t seed;               ///< Checkpoint::seed
  const State& state;               ///< Checkpoint::state
  const StepCarry& carry;           ///< Checkpoint::carry (the detection memory's pairs and normals only)
  const RunProgress& progress;      ///< Checkpoint::progress
  const RestWatch& rest;            ///< Checkpoint::rest
};

/// A view of every field of `checkpoint`.
CheckpointView checkpoint_view(const Checkpoint& checkpoint);

/// Version of the checkpoint layout; bump on any change (older files are then rejected).
inline constexpr std::uint32_t checkpoint_format_version =
    4;  // 2: held gravity field; 3: rest watcher on speeds, Z, contacts; 4: contacts' angular impulses

/// CRC-64/XZ of `bytes`, continuing from `crc` (pass the previous result to chain; 0 to start).
std::uint64_t crc64(std::span<const std::byte> bytes, std::uint64_t crc = 0);

/// A hash of a state: CRC-64 of its time, step and every body's position, orientation (w, x, y, z),
/// velocity and angular velocity, bit for bit. Two states have the same hash if they are
/// bitwise equal (and almost surely only then): what the restart tests compare.
std::uint64_t state_hash(const State& state);

/// The checkpoint as file bytes (header, payload, CRC): exactly the bytes write_checkpoint streams
/// to its file.
std::vector<std::byte> serialize_checkpoint(const CheckpointView& checkpoint);

/// The same for a Checkpoint.
std::vector<std::byte> serialize_checkpoint(const Checkpoint& checkpoint);

/// Parses file bytes; `source` names the file in messages. Throws CheckpointError on any mismatch
/// (size, magic, version, CRC, array sizes, body ids out of range).
Checkpoint deserialize_checkpoint(std::span<const std::byte> bytes, const std::string& source);

/// The folder of a run's checkpoints: output_directory/checkpoints.
std::filesystem::path checkpoint_folder(const std::filesystem::path& output_directory);

/// Writes `checkpoint` atomically as folder/step-NNNNNNNNNNNN.ckpt (folder created if missing),
/// then deletes older checkpoints so that the newest `keep` (>= 1) remain, and any temporary file
/// left by an interrupted write. Returns the file's path. Throws std::runtime_error on I/O errors
/// (the previous checkpoints are then untouched).
/// The file is streamed (see the file comment): the memory it takes is 1 MiB whatever its size.
/// `keep_every` > 0 also keeps, among the older ones, the first checkpoint (lowest step) of every
/// interval of `keep_every` steps ([0, N), [N, 2N), ...): the retention policy of [output]
/// keep_checkpoint_every, which lets a run be restarted from an earlier step.
std::filesystem::path write_checkpoint(const std::filesystem::path& folder, const CheckpointView& checkpoint,
                                       int keep = 2, std::int64_t keep_every = 0);

/// The same for a Checkpoint.
std::filesystem::path write_checkpoint(const std::filesystem::path& folder, const Checkpoint& checkpoint, int keep = 2,
                                       std::int64_t keep_every = 0);

/// The step of a checkpoint file named step-NNNNNNNNNNNN.ckpt (-1 for any other name).
std::int64_t checkpoint_step(const std::filesystem::path& file);

/// Sets aside (renames to step-N.ckpt.superseded, which no listing returns) every checkpoint of
/// `folder` later than `step`: a run resumed from an earlier checkpoint leaves the later ones on
/// another branch of its history, which the retention and a later --resume must not take for its
/// own. Returns the files set aside.
std::vector<std::filesystem::path> set_aside_checkpoints_after(const std::filesystem::path& folder, std::int64_t step);

/// Reads and checks one checkpoint file. Throws CheckpointError.
Checkpoint read_checkpoint(const std::filesystem::path& file);

/// Checkpoint files in `folder`, newest (highest step) first; empty if the folder is missing.
std::vector<std::filesystem::path> list_checkpoints(const std::filesystem::path& folder);

/// A checkpoint found by load_newest_checkpoint.
struct LoadedCheckpoint {
  Checkpoint checkpoint;              ///< the newest valid one
  std::filesystem::path file;         ///< its file
  std::vector<std::string> rejected;  ///< why newer files were skipped (one message each)
};

/// Loads the newest checkpoint of `folder` that passes every check, skipping (and reporting in
/// `rejected`) damaged newer ones. Throws CheckpointError if there is none, listing why each
/// file was rejected.
LoadedCheckpoint load_newest_checkpoint(const std::filesystem::path& folder);

/// The watcher's memory as saved in a checkpoint.
RestWatch save_rest_watch(const RestDetector& detector);

/// Restores the watcher's memory from a checkpoint (its criterion is left as it is: the scene's,
/// or the command line's overrides).
void restore_rest_watch(const RestWatch& watch, RestDetector& detector);

}  // namespace rubble
