#pragma once
// Internal to the scene parser: the keys of the sections whose keys map one to one onto the
// members of an options struct ([solver], [detection], [output], [[contact_laws]] and
// [default_contact_law]) as tables, one row per key (name, the option it sets, its allowed values,
// its meaning). One table drives the parsing, the unknown-key check and the writing back of its
// section, so a new option is added in one place; tests/scene/test_scene_keys.cpp checks that
// docs/scene-file.md lists the same keys. [time], [gravity] and the body sections are still
// spelled out in scene_sections.cpp, scene_bodies.cpp and scene_writer.cpp (their keys depend on
// other keys: "auto" flags, the gravity type, the body's shape).
#include <cstdint>
#include <ostream>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "contact_detection/detection.hpp"
#include "core/model.hpp"
#include "nlgs_solver/nlgs.hpp"
#include "simulation/scene.hpp"
#include "simulation/scene_reader.hpp"

namespace rubble::scene_detail {

/// The option a key sets: a number, an integer (int, size_t or int64), a boolean or a string.
using OptionRef = std::variant<double*, int*, std::size_t*, std::int64_t*, bool*, std::string*>;

/// One key of a section whose keys map one to one onto the members of `Options`.
template <class Options>
struct SectionKey {
  std::string_view name;
  OptionRef (*option)(Options&);  ///< the member the key sets
  Range range{};                  ///< allowed numbers (double options)
  std::int64_t low = 0;           ///< allowed integers (int and size_t options): [low, high]
  std::int64_t high = 0;
  /// The string "auto" is accepted and read as -1 (the option's "automatic" value); a negative
  /// value is written back as "auto".
  bool auto_when_negative = false;
  bool required = false;  ///< no default: a missing key is an error
  /// Written back only when this holds (null: always), e.g. an optional term only when nonzero.
  bool (*written)(const Options&) = nullptr;
  /// A check against the keys read before, run right after this key is read (null: none), so
  /// that a file with several problems reports the same one whatever the check.
  void (*check)(const TableReader&, const Options&) = nullptr;
  std::string_view doc;  ///< what the key means, in short (docs/scene-file.md says it in full)
};

/// The [solver] keys, in the order they are read and written.
const std::vector<SectionKey<SolverOptions>>& solver_keys();
/// The [detection] keys, in the order they are read and written.
const std::vector<SectionKey<DetectionOptions>>& detection_keys();

/// The [output] keys, in the order they are read and written.
const std::vector<SectionKey<OutputOptions>>& output_keys();
/// The keys of a contact law ([[contact_laws]] besides `materials`, and [default_contact_law]).
const std::vector<SectionKey<ContactLaw>>& contact_law_keys();

/// The names of a section's keys, for TableReader::allow_only.
template <class Options>
std::vector<std::string_view> key_names(const std::vector<SectionKey<Options>>& keys) {
  std::vector<std::string_view> names;
  names.reserve(keys.size());
  for (const auto& key : keys) names.push_back(key.name);
  return names;
}

/// Reads the keys of a section into `options`, each in table order; an absent key leaves its
/// option as it is (the default).
template <class Options>
void read_section_keys(const TableReader& table, const std::vector<SectionKey<Options>>& keys, Options& options) {
  for (const auto& key : keys) {
    const OptionRef option = key.option(options);
    if (auto* const* number = std::get_if<double*>(&option)) {
      if (key.auto_when_negative && is_auto(table, key.name)) {
        **number = -1.0;
      } else {
        **number = key.required ? table.number(key.name, key.range) : table.number_or(key.name, **number, key.range);
      }
    } else if (auto* const* integer = std::get_if<int*>(&option)) {
      **integer = static_cast<int>(table.integer_or(key.name, **integer, key.low, key.high));
    } else if (auto* const* count = std::get_if<std::size_t*>(&option)) {
      **count =
          static_cast<std::size_t>(table.integer_or(key.name, static_cast<std::int64_t>(**count), key.low, key.high));
    } else if (auto* const* wide = std::get_if<std::int64_t*>(&option)) {
      **wide = table.integer_or(key.name, **wide, key.low, key.high);
    } else if (auto* const* flag = std::get_if<bool*>(&option)) {
      **flag = table.boolean_or(key.name, **flag);
    } else {
      std::string& text = *std::get<std::string*>(option);
      text = table.optional_string(key.name).value_or(text);
    }
    if (key.check) key.check(table, options);
  }
}

/// Writes the keys of a section as "name = value" lines, in table order.
template <class Options>
void write_section_keys(std::ostream& out, const std::vector<SectionKey<Options>>& keys, Options options) {
  for (const auto& key : keys) {
    if (key.written && !key.written(options)) continue;
    out << key.name << " = ";
    const OptionRef option = key.option(options);
    if (const auto* number = std::get_if<double*>(&option)) {
      out << (key.auto_when_negative && **number < 0.0 ? std::string("\"auto\"") : format_number(**number));
    } else if (const auto* integer = std::get_if<int*>(&option)) {
      out << **integer;
    } else if (const auto* count = std::get_if<std::size_t*>(&option)) {
      out << **count;
    } else if (const auto* wide = std::get_if<std::int64_t*>(&option)) {
      out << **wide;
    } else if (const auto* flag = std::get_if<bool*>(&option)) {
      out << (**flag ? "true" : "false");
    } else {
      out << toml_string(*std::get<std::string*>(option));
    }
    out << "\n";
  }
}

}  // namespace rubble::scene_detail
