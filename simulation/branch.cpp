#include "simulation/branch.hpp"

#include <cmath>
#include <fmt/format.h>

#include "postprocessing/run_reader.hpp"
#include "simulation/checkpoint.hpp"
#include "simulation/scene_file.hpp"

namespace rubble {

namespace fs = std::filesystem;

namespace {

/// The run file of a source: the path itself when it is a file, else DIR/run.h5.
fs::path run_file_of(const fs::path& path) { return fs::is_directory(path) ? path / "run.h5" : path; }

std::string_view shape_name(ShapeKind kind) {
  switch (kind) {
    case ShapeKind::sphere:
      return "sphere";
    case ShapeKind::polyhedron:
      return "polyhedron";
    case ShapeKind::plane:
      return "plane wall";
    case ShapeKind::box:
      return "box wall";
  }
  return "?";
}

std::size_t grains(const Model& model) {
  std::size_t n = 0;
  for (std::size_t b = 0; b < model.body_count(); ++b) n += model.is_grain(b) ? 1 : 0;
  return n;
}

bool close(double a, double b) { return std::abs(a - b) <= 1e-9 * std::max(std::abs(a), std::abs(b)); }

/// The snapshot of `reader` that `source` names, as a SavedState.
SavedState from_snapshot(const BranchSource& source, const fs::path& file) {
  try {
    RunReader reader = RunReader::open(file);
    const auto count = static_cast<std::int64_t>(reader.snapshot_count());
    if (count == 0) throw BranchError(file.string() + ": the run file has no snapshot");
    std::int64_t index = count - 1;
    if (source.kind == BranchSource::Kind::snapshot) {
      index = source.snapshot < 0 ? count + source.snapshot : source.snapshot;
      if (index < 0 || index >= count) {
        throw BranchError(fmt::format("{}: no snapshot {} (the file has {}: 0 to {}, or -1 for the last)",
                                      file.string(), source.snapshot, count, count - 1));
      }
    } else if (source.kind == BranchSource::Kind::time) {
      // Snapshots are in time order: the last one at or before T, by bisection.
      const double first = reader.read_snapshot(0).state.time;
      if (source.time < first) {
        throw BranchError(fmt::format("{}: no snapshot at or before t = {:.6g} s (the first is at t = {:.6g} s)",
                                      file.string(), source.time, first));
      }
      std::int64_t low = 0;  // time(low) <= T
      std::int64_t high = count;
      while (high - low > 1) {
        const std::int64_t middle = (low + high) / 2;
        if (reader.read_snapshot(static_cast<std::size_t>(middle)).state.time <= source.time) {
          low = middle;
        } else {
          high = middle;
        }
      }
      index = low;
    }
    SavedState saved;
    saved.state = reader.read_snapshot(static_cast<std::size_t>(index)).state;
    saved.model = reader.model();
    saved.scene_text = reader.scene_text();
    saved.description = fmt::format("snapshot {} of {} (step {}, t = {:.6g} s)", index, file.string(), saved.state.step,
                                    saved.state.time);
    return saved;
  } catch (const BranchError&) {
    throw;
  } catch (const std::exception& error) {
    throw BranchError(error.what());
  }
}

}  // namespace

BranchSource parse_branch_source(std::string_view text) {
  BranchSource source;
  source.path = std::string(text);
  const auto colon = text.rfind(':');
  if (colon == std::string_view::npos) return source;
  const std::string_view path = text.substr(0, colon);
  const std::string_view selector = text.substr(colon + 1);
  const auto number = [&](std::string_view value, bool integer) {
    const std::string owned(value);
    std::size_t used = 0;
    double parsed = 0.0;
    try {
      parsed = std::stod(owned, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (owned.empty() || used != owned.size() || !std::isfinite(parsed) || (integer && parsed != std::floor(parsed)) ||
        std::abs(parsed) > 9e15) {
      throw BranchError(fmt::format("{}: expected {} after '{}', got '{}'", text,
                                    integer ? "an integer" : "a finite time in s",
                                    selector.substr(0, selector.find('=') + 1), owned));
    }
    return parsed;
  };
  if (selector == "last") {
    source.path = std::string(path);
  } else if (selector.starts_with("snapshot=")) {
    source.path = std::string(path);
    source.kind = BranchSource::Kind::snapshot;
    source.snapshot = static_cast<std::int64_t>(number(selector.substr(9), true));
  } else if (selector.starts_with("time=")) {
    source.path = std::string(path);
    source.kind = BranchSource::Kind::time;
    source.time = number(selector.substr(5), false);
  } else if (selector.find('=') != std::string_view::npos || selector.empty()) {
    throw BranchError(
        fmt::format("{}: unknown selector '{}' (expected DIR, DIR:last, DIR:snapshot=K or "
                    "DIR:time=T)",
                    text, selector));
  }
  // Otherwise the colon is part of the path.
  if (source.path.empty()) throw BranchError(fmt::format("{}: expected a run folder before ':'", text));
  return source;
}

SavedState load_saved_state(const BranchSource& source) {
  if (!fs::exists(source.path)) throw BranchError(source.path.string() + ": no such run folder or run file");
  if (source.kind == BranchSource::Kind::last && fs::is_directory(source.path)) {
    const fs::path folder = checkpoint_folder(source.path);
    if (!list_checkpoints(folder).empty()) {
      // The newest checkpoint: the state bit for bit as the run holds it.
      LoadedCheckpoint loaded;
      try {
        loaded = load_newest_checkpoint(folder);
      } catch (const CheckpointError& error) {
        // None readable (written by an older rubble, whose format this one does not read, or
        // damaged): the run file's last snapshot is the same state to its precision, written
        // at the same step when the run ended; said so in the description.
        const fs::path file = run_file_of(source.path);
        if (!fs::exists(file)) {
          throw BranchError(fmt::format("{}; and there is no run file {} to take the last snapshot from", error.what(),
                                        file.string()));
        }
        SavedState saved = from_snapshot(source, file);
        saved.description += fmt::format(
            " (no checkpoint of {} could be read: {}; the run file's last snapshot is used instead, which starts "
            "the branch without the checkpoint's warm start)",
            folder.string(), error.what());
        return saved;
      }
      SavedState saved;
      saved.state = std::move(loaded.checkpoint.state);
      saved.scene_text = loaded.checkpoint.scene_text;
      saved.contacts = std::move(loaded.checkpoint.carry.contacts);
      try {
        Scene saved_scene = parse_scene(loaded.checkpoint.scene_text, loaded.checkpoint.scene_source);
        saved.model = std::move(saved_scene.model);
        saved.time_step = saved_scene.run.step.integrator.time_step;
      } catch (const std::exception& error) {
        throw BranchError(
            fmt::format("{}: the checkpoint's scene cannot be read back: {}", loaded.file.string(), error.what()));
      }
      saved.description = fmt::format("checkpoint {} (step {}, t = {:.6g} s)", loaded.file.string(), saved.state.step,
                                      saved.state.time);
      return saved;
    }
  }
  const fs::path file = run_file_of(source.path);
  if (!fs::exists(file)) {
    throw BranchError(
        fmt::format("{}: no checkpoint and no run file {} to take a state from", source.path.string(), file.string()));
  }
  return from_snapshot(source, file);
}

ContactList branch_warm_start(const SavedState& saved, double time_step) {
  if (saved.contacts.empty() || !(saved.time_step > 0.0)) return {};
  const double scale = time_step / saved.time_step;
  ContactList contacts = saved.contacts;
  for (Contact& contact : contacts) {
    contact.impulse *= scale;
    contact.angular_impulse *= scale;
  }
  return contacts;
}

std::optional<std::string> body_mismatch(const Model& scene_model, const Model& saved_model) {
  if (scene_model.body_count() != saved_model.body_count()) {
    return fmt::format("the scene has {} bodies ({} grains), the saved run {} bodies ({} grains)",
                       scene_model.body_count(), grains(scene_model), saved_model.body_count(), grains(saved_model));
  }
  for (std::size_t b = 0; b < scene_model.body_count(); ++b) {
    const ShapeKind kind = scene_model.shape_kind[b];
    if (kind != saved_model.shape_kind[b]) {
      return fmt::format("body {} is a {} in the scene, a {} in the saved run", b, shape_name(kind),
                         shape_name(saved_model.shape_kind[b]));
    }
    const auto index = static_cast<std::size_t>(scene_model.shape_index[b]);
    const auto saved_index = static_cast<std::size_t>(saved_model.shape_index[b]);
    if (kind == ShapeKind::sphere) {
      const double r = scene_model.spheres[index].radius;
      const double saved_r = saved_model.spheres[saved_index].radius;
      if (!close(r, saved_r)) {
        return fmt::format("body {} (a sphere) has radius {:.9g} m in the scene, {:.9g} m in the saved run", b, r,
                           saved_r);
      }
    } else if (kind == ShapeKind::polyhedron) {
      const std::size_t v = scene_model.polyhedra[index].vertices.size();
      const std::size_t saved_v = saved_model.polyhedra[saved_index].vertices.size();
      if (v != saved_v || !close(scene_model.bounding_radius[b], saved_model.bounding_radius[b])) {
        return fmt::format(
            "body {} (a polyhedron) has {} vertices and bounding radius {:.9g} m in the scene, {} and "
            "{:.9g} m in the saved run",
            b, v, scene_model.bounding_radius[b], saved_v, saved_model.bounding_radius[b]);
      }
    }
  }
  return std::nullopt;
}

}  // namespace rubble
