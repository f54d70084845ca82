#pragma once
// Scene files: a TOML description of a scene (materials, contact laws, walls, grains or grain
// generators, gravity, time stepping, solver, output) turned into a Scene, and back.
// The format is documented key by key in docs/scene-file.md.
//
// Every problem in a file (syntax, unknown key, missing key, wrong type, value out of range,
// non-finite number, unknown material, grain outside a wall, ...) is reported as a SceneError
// naming the file, the line when known, the key and what was expected; nothing else is thrown
// for bad input. The CLI turns a SceneError into exit code 2.
#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <string_view>

#include "simulation/scene.hpp"

#include "core/input_error.hpp"

namespace rubble {

/// A problem in a scene file. what() is "FILE:LINE: KEY: message" (":LINE" left out when the line
/// is unknown, "KEY: " when the problem is not tied to one key).
class SceneError : public InputError {
 public:
  /// Builds the error and its what() text from the parts.
  SceneError(std::string file, int line, std::string key, std::string message);

  std::string file;     ///< the scene file's name, as given to the loader
  int line = 0;         ///< 1-based line of the offending key or table, 0 if unknown
  std::string key;      ///< dotted path of the key, e.g. "bodies[3].radius" (empty if none)
  std::string message;  ///< what is wrong and what was expected, e.g. "expected a number > 0, got -1"
};

/// Reads and parses a scene file. Relative paths inside it are relative to the file's folder.
/// The scene's name defaults to the file's stem. Throws SceneError (also when the file cannot be read).
Scene load_scene_file(const std::filesystem::path& path);

/// Parses scene text; `source_name` is the file name used in messages (and whose folder anchors
/// relative paths). Throws SceneError.
Scene parse_scene(std::string_view toml_text, const std::string& source_name);

/// Which built-in scene: the study's spheres (the default) or the same set-up with polyhedra.
enum class DefaultScene { spheres, polyhedra };

/// The built-in scene `rubble run` uses without a scene file: the accretion of a thousand
/// spheres (or polyhedra) under self-gravity, run until they are at rest (the LMGC90 accretion paper's set-up).
/// Equal to parse_scene(default_scene_toml(variant), ...).
Scene default_scene(DefaultScene variant = DefaultScene::spheres);

/// The built-in scene as scene-file text (what `rubble run --print-default-scene` prints;
/// examples/accretion-1000.toml holds the spheres' text, examples/accretion-1000-polyhedra.toml
/// the polyhedra's).
std::string default_scene_toml(DefaultScene variant = DefaultScene::spheres);

/// Writes a scene as scene-file text with every grain and wall listed explicitly (generators
/// expanded), such that parse_scene(scene_to_toml(s)) gives back the same model and state when
/// grains come before walls in s (as parse_scene orders them). Polyhedral grains are written with
/// their body-frame vertices and faces (read back up to round-off in the mass properties).
/// Throws std::invalid_argument for a scene with [[inflow]] entries (its grains are not placed).
std::string scene_to_toml(const Scene& scene);

}  // namespace rubble
