#pragma once
// Internal to the scene parser: the keys of every section of a scene file as tables, one row per
// key (name, the member it sets, its allowed values, whether it is required, when it is written,
// its meaning). A section's table is its one list of keys: it gives the unknown-key check its
// allowed keys, docs/scene-file.md its key table (tests/scene/test_scene_keys.cpp checks the two
// agree), and, for every key that sets one member, the parsing (read_section_keys) and the writing
// back (write_section_keys). Where the keys depend on another key (the gravity's type, a wall's
// type, a body's shape, a generator's type and shape), there is one table per kind. A key whose
// value is not one member (a material name, a prescribed motion, a polyhedron's mesh, "until"
// which sets a flag and checks other keys) is read by hand, by the row's `read` or by the
// section's parser; its row says why.
#include <array>
#include <cstdint>
#include <map>
#include <ostream>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "contact_detection/detection.hpp"
#include "core/model.hpp"
#include "nlgs_solver/nlgs.hpp"
#include "preprocessing/random_polyhedron.hpp"
#include "simulation/initial_conditions.hpp"
#include "simulation/scene.hpp"
#include "simulation/scene_parser.hpp"
#include "simulation/scene_reader.hpp"

namespace rubble::scene_detail {

/// The option a key sets: a number, an integer (int, size_t or int64), a boolean, a string, a
/// vector or a quaternion.
using OptionRef = std::variant<double*, int*, std::size_t*, std::int64_t*, bool*, std::string*, Vec3*, Quat*>;

/// One key of a section. The fields are in the order rows give them (designated initializers).
template <class Options>
struct SectionKey {
  std::string_view name;
  /// The member the key sets, read by read_section_keys and written by write_section_keys; null
  /// for a key read by hand (by `read`, or by the section's parser: a comment at the row says why).
  OptionRef (*option)(Options&) = nullptr;
  /// Allowed numbers (double options and vectors) and integers; a key read by hand checks its own.
  Range range{};
  std::int64_t low = 0;  ///< allowed integers (integer options): [low, high]
  std::int64_t high = 0;
  /// The string "auto" is accepted and read as -1 (the option's "automatic" value); a negative
  /// value is written back as "auto".
  bool auto_when_negative = false;
  /// The string "auto" (or, for a key that is not required, no key) sets this flag (the value is
  /// then chosen from the scene); the number is read only without it and written as "auto" with it.
  bool* (*automatic)(Options&) = nullptr;
  bool required = false;  ///< no default: a missing key is an error
  /// The words a string key takes, the rest empty (docs/scene-file.md lists each, quoted). An
  /// array: a std::vector member here crashes GCC 12 (internal compiler error in nothrow_spec_p).
  std::array<std::string_view, 4> choices{};
  /// For a key without `option`: the kind of value, as docs/scene-file.md's type column starts
  /// ("number", "vector", "material name", ...); keys with an option take it from the option.
  std::string_view type{};
  /// Written back only when this holds (null: always), e.g. an optional term only when nonzero.
  bool (*written)(const Options&) = nullptr;
  /// A check against the keys read before, run right after this key is read (null: none), so
  /// that a file with several problems reports the same one whatever the check.
  void (*check)(const TableReader&, const Options&) = nullptr;
  /// Reads a key whose value is not simply its option's (null: read from `option`).
  void (*read)(const TableReader&, Options&) = nullptr;
  /// The written text of a key without `option` (null: written by the section's writer, if at all).
  std::string (*write)(const Options&) = nullptr;
  /// Read before the table's other keys, written after them: the order of the files and of the
  /// messages from before the tables, which the tables keep.
  bool read_first = false;
  bool written_last = false;
  std::string_view doc;  ///< what the key means, in short (docs/scene-file.md says it in full)
};

/// A section whose keys are all read by hand: its table lists them (allowed keys, docs).
struct ByHand {};

/// Never written by write_section_keys (the section's writer writes the key itself).
template <class Options>
bool never(const Options&) {
  return false;
}

/// Top level: `name`, `seed`, then the sections (tables, read by their parsers).
const std::vector<SectionKey<Scene>>& top_level_keys();

/// The [time] keys, in the order they are read and written.
const std::vector<SectionKey<RunOptions>>& time_keys();
/// The [solver] keys, in the order they are read and written.
const std::vector<SectionKey<SolverOptions>>& solver_keys();
/// The [detection] keys, in the order they are read and written.
const std::vector<SectionKey<DetectionOptions>>& detection_keys();
/// The [gravity] types, in the order docs/scene-file.md lists them.
const std::vector<std::string_view>& gravity_types();
/// The [gravity] keys of one type ("none", "uniform", "direct", "tree", "central"), `type` first.
const std::vector<SectionKey<GravitySettings>>& gravity_keys(std::string_view type);

/// The [output] keys, in the order they are read and written.
const std::vector<SectionKey<OutputOptions>>& output_keys();
/// The keys of a contact law ([[contact_laws]] besides `materials`, and [default_contact_law]).
const std::vector<SectionKey<ContactLaw>>& contact_law_keys();

/// A [[materials]] entry being read: the material and the names defined before it.
struct MaterialEntry {
  Material material;
  const std::map<std::string, int>* defined = nullptr;  ///< the names of the entries before
};
/// The [[materials]] keys.
const std::vector<SectionKey<MaterialEntry>>& material_keys();

/// The [[walls]] keys of one type ("plane" or "box"), `type` first.
const std::vector<SectionKey<WallSpec>>& wall_keys(std::string_view type);
/// The [[bodies]] keys of a sphere.
const std::vector<SectionKey<GrainSpec>>& sphere_body_keys();
/// The ways a polyhedron body is given ("file", "vertices", "diameter": the key that picks it).
const std::vector<std::string_view>& polyhedron_ways();
/// The [[bodies]] keys of a polyhedron given one way (polyhedron_ways()): the placement keys,
/// then the way's keys.
const std::vector<SectionKey<GrainSpec>>& polyhedron_body_keys(std::string_view way);
/// The keys of a random polyhedron's shape, common to [[bodies]] and [[generators]].
const std::vector<SectionKey<RandomPolyhedronOptions>>& random_polyhedron_keys();
/// The [[generators]] keys common to every type and shape.
const std::vector<SectionKey<ByHand>>& generator_common_keys();
/// The keys a grain shape of a generator adds ("sphere": none, "polyhedron", "mix").
const std::vector<SectionKey<ByHand>>& generator_shape_keys(std::string_view shape);
/// The keys a generator type adds ("box_deposit", "cubic_grid", "sphere_cloud").
const std::vector<SectionKey<ByHand>>& generator_type_keys(std::string_view type);
/// The [[initial_conditions]] keys.
const std::vector<SectionKey<InitialCondition>>& initial_condition_keys();
/// The [[inflow]] keys besides a grain shape's (generator_shape_keys): the grains' (a
/// generator's common keys but `type`), then the inflow's own.
const std::vector<SectionKey<ByHand>>& inflow_keys();

/// The names of a section's keys, for TableReader::allow_only.
template <class Options>
std::vector<std::string_view> key_names(const std::vector<SectionKey<Options>>& keys) {
  std::vector<std::string_view> names;
  names.reserve(keys.size());
  for (const auto& key : keys) names.push_back(key.name);
  return names;
}

/// The kind of value a key holds, as docs/scene-file.md's type column starts: "number",
/// "integer", "boolean", "string", "vector", "quaternion", or the row's `type`.
template <class Options>
std::string_view key_type(const SectionKey<Options>& key) {
  if (!key.option) return key.type;
  Options options{};
  const OptionRef option = key.option(options);
  if (std::holds_alternative<double*>(option)) return "number";
  if (std::holds_alternative<bool*>(option)) return "boolean";
  if (std::holds_alternative<std::string*>(option)) return "string";
  if (std::holds_alternative<Vec3*>(option)) return "vector";
  if (std::holds_alternative<Quat*>(option)) return "quaternion";
  return "integer";
}

/// The rows of another section's table as keys read by hand here, by that table (e.g. the random
/// polyhedron's keys in a [[bodies]] entry, where they make the shape, not a member of the grain).
template <class To, class From>
std::vector<SectionKey<To>> keys_read_by_hand(const std::vector<SectionKey<From>>& keys) {
  std::vector<SectionKey<To>> rows;
  rows.reserve(keys.size());
  for (const auto& key : keys) {
    rows.push_back(
        {.name = key.name, .required = key.required, .choices = key.choices, .type = key_type(key), .doc = key.doc});
  }
  return rows;
}

/// Appends the rows of `more` to `keys`.
template <class Options>
std::vector<SectionKey<Options>> joined(std::vector<SectionKey<Options>> keys,
                                        const std::vector<SectionKey<Options>>& more) {
  keys.insert(keys.end(), more.begin(), more.end());
  return keys;
}

/// Reads one key into `options` (nothing for a key read by the section's parser).
template <class Options>
void read_key(const TableReader& table, const SectionKey<Options>& key, Options& options) {
  if (key.read) {
    key.read(table, options);
  } else if (!key.option) {
    return;
  } else if (const OptionRef option = key.option(options); auto* const* number = std::get_if<double*>(&option)) {
    if (key.automatic) {
      bool& automatic = *key.automatic(options);
      automatic = is_auto(table, key.name) || (!key.required && !table.has(key.name));
      if (!automatic) **number = table.number(key.name, key.range);
    } else if (key.auto_when_negative && is_auto(table, key.name)) {
      **number = -1.0;
    } else {
      **number = key.required ? table.number(key.name, key.range) : table.number_or(key.name, **number, key.range);
    }
  } else if (auto* const* integer = std::get_if<int*>(&option)) {
    **integer = static_cast<int>(key.required ? table.integer(key.name, key.low, key.high)
                                              : table.integer_or(key.name, **integer, key.low, key.high));
  } else if (auto* const* count = std::get_if<std::size_t*>(&option)) {
    **count =
        static_cast<std::size_t>(table.integer_or(key.name, static_cast<std::int64_t>(**count), key.low, key.high));
  } else if (auto* const* wide = std::get_if<std::int64_t*>(&option)) {
    **wide = table.integer_or(key.name, **wide, key.low, key.high);
  } else if (auto* const* flag = std::get_if<bool*>(&option)) {
    **flag = table.boolean_or(key.name, **flag);
  } else if (auto* const* vector = std::get_if<Vec3*>(&option)) {
    **vector = key.required ? table.vec3(key.name, key.range)
                            : table.optional_vector<3>(key.name, key.range).value_or(**vector);
  } else if (auto* const* rotation = std::get_if<Quat*>(&option)) {
    if (table.has(key.name)) **rotation = table.orientation_or_identity(key.name);
  } else {
    std::string& text = *std::get<std::string*>(option);
    text = key.required ? table.string(key.name) : table.optional_string(key.name).value_or(text);
  }
  if (key.check) key.check(table, options);
}

/// Reads the keys of a section into `options`, each in table order (those marked read_first
/// before the others); an absent key leaves its option as it is (the default). Keys without an
/// option or a `read` are left to the section's parser.
template <class Options>
void read_section_keys(const TableReader& table, const std::vector<SectionKey<Options>>& keys, Options& options) {
  for (const auto& key : keys) {
    if (key.read_first) read_key(table, key, options);
  }
  for (const auto& key : keys) {
    if (!key.read_first) read_key(table, key, options);
  }
}

/// The text a key's value is written as.
template <class Options>
std::string written_value(const SectionKey<Options>& key, const Options& options) {
  if (key.write) return key.write(options);
  // The accessors take the options to set; here the member is only read.
  auto& readable = const_cast<Options&>(options);  // NOLINT(cppcoreguidelines-pro-type-const-cast)
  const OptionRef option = key.option(readable);
  if (const auto* number = std::get_if<double*>(&option)) {
    if (key.automatic && *key.automatic(readable)) return "\"auto\"";
    return key.auto_when_negative && **number < 0.0 ? std::string("\"auto\"") : format_number(**number);
  }
  if (const auto* integer = std::get_if<int*>(&option)) return std::to_string(**integer);
  if (const auto* count = std::get_if<std::size_t*>(&option)) return std::to_string(**count);
  if (const auto* wide = std::get_if<std::int64_t*>(&option)) return std::to_string(**wide);
  if (const auto* flag = std::get_if<bool*>(&option)) return **flag ? "true" : "false";
  if (const auto* vector = std::get_if<Vec3*>(&option)) return format_vec3(**vector);
  if (const auto* rotation = std::get_if<Quat*>(&option)) return format_quaternion(**rotation);
  return toml_string(*std::get<std::string*>(option));
}

/// Writes the keys of a section as "name = value" lines, in table order (those marked
/// written_last after the others). Keys without an option or a `write` are left to the
/// section's writer.
template <class Options>
void write_section_keys(std::ostream& out, const std::vector<SectionKey<Options>>& keys, const Options& options) {
  for (const bool last : {false, true}) {
    for (const auto& key : keys) {
      if (key.written_last != last || (!key.option && !key.write)) continue;
      if (key.written && !key.written(options)) continue;
      out << key.name << " = " << written_value(key, options) << "\n";
    }
  }
}

}  // namespace rubble::scene_detail
