#pragma once
// Internal to the scene parser (simulation/scene_*.cpp): reading a TOML table key by key with
// messages that name the file, line and dotted key (SceneError), number formats for messages and
// for writing scenes back, and the allowed ranges of numbers. Not part of the public API
// (simulation/scene_file.hpp is).
#include <cmath>
#include <cstdint>
#include <initializer_list>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <toml++/toml.h>

#include "core/math.hpp"

namespace rubble::scene_detail {

inline constexpr double infinity = std::numeric_limits<double>::infinity();

/// Shortest text that reads back to the same double (std::to_chars), always with a '.' or an
/// exponent so that TOML reads it as a float.
std::string format_number(double x);
/// Shortest text of a number for messages ("-1", "0.5", "nan").
std::string show(double x);
/// A computed number for messages, to 6 significant digits.
std::string show_short(double x);
/// [x, y, z] for messages.
std::string show_vec3(const Vec3& v);
/// [x, y, z] as TOML floats.
std::string format_vec3(const Vec3& v);
/// [w, x, y, z] as TOML floats.
std::string format_quaternion(const Quat& q);
/// A string as a TOML basic string, quoted and escaped.
std::string toml_string(const std::string& s);

/// A closed, open or half-open interval of allowed values, with its description for messages.
struct Range {
  double low = -infinity;
  double high = infinity;
  bool low_closed = true;
  bool high_closed = true;

  bool contains(double x) const { return (low_closed ? x >= low : x > low) && (high_closed ? x <= high : x < high); }
  /// "> 0", "in [0, 1]", "" for any number.
  std::string describe() const;
};

inline Range positive() { return Range{0.0, infinity, false, true}; }
inline Range non_negative() { return Range{0.0, infinity, true, true}; }
inline Range any_number() { return Range{}; }
inline Range closed(double a, double b) { return Range{a, b, true, true}; }
inline Range open(double a, double b) { return Range{a, b, false, false}; }
/// Positions and lengths of a scene, m. Past 10^12 m (7 AU) a double resolves no better than
/// 10^-4 m, coarser than the grains' contact geometry, and region sizes, volumes and capacities
/// derived from larger values overflow (a ±1e308 region gave an infinite first snapshot).
inline constexpr double max_scene_length = 1e12;
inline Range coordinate() { return closed(-max_scene_length, max_scene_length); }
inline Range length() { return Range{0.0, max_scene_length, false, true}; }
inline Range length_or_zero() { return closed(0.0, max_scene_length); }

/// "a finite number > 0" etc.
std::string expected_number(const Range& range);

/// What a TOML node holds, for "got ..." in messages.
std::string describe_node(const toml::node& node);

inline int line_of(const toml::node* node) { return node ? static_cast<int>(node->source().begin.line) : 0; }

/// Levenshtein distance, for "did you mean" hints on misspelt keys.
std::size_t edit_distance(std::string_view a, std::string_view b);

/// A TOML table being read, with its dotted path for messages. Every problem throws SceneError.
class TableReader {
 public:
  TableReader(const std::string& file, const toml::table& table, std::string path, const toml::node* anchor)
      : file_(file), table_(table), path_(std::move(path)), anchor_(anchor) {}

  const std::string& path() const { return path_; }
  const toml::table& table() const { return table_; }
  /// Dotted path of a key of this table.
  std::string key_path(std::string_view key) const {
    return path_.empty() ? std::string(key) : path_ + "." + std::string(key);
  }
  /// Line of this table (0 for the root, whose "line" would point nowhere useful).
  const toml::node* anchor() const { return anchor_; }

  [[noreturn]] void fail(const toml::node* at, const std::string& key, const std::string& message) const;
  [[noreturn]] void fail_key(std::string_view key, const std::string& message) const {
    const toml::node* node = table_.get(key);
    fail(node ? node : anchor_, key_path(key), message);
  }
  [[noreturn]] void fail_table(const std::string& message) const { fail(anchor_, path_, message); }

  /// Rejects keys not in `allowed` (typos!), suggesting the closest allowed key.
  void allow_only(std::initializer_list<std::string_view> allowed, std::string_view context = {}) const {
    allow_only(std::vector<std::string_view>(allowed), context);
  }
  void allow_only(const std::vector<std::string_view>& allowed, std::string_view context = {}) const;

  bool has(std::string_view key) const { return table_.contains(key); }
  const toml::node* get(std::string_view key) const { return table_.get(key); }

  [[noreturn]] void missing(std::string_view key, const std::string& expected) const {
    fail(anchor_, key_path(key), "missing required key (expected " + expected + ")");
  }

  /// A number checked against `range`; integers are accepted as numbers.
  double number_of(const toml::node& node, const std::string& key, const Range& range) const;
  std::optional<double> optional_number(std::string_view key, const Range& range) const {
    const toml::node* node = get(key);
    if (!node) return std::nullopt;
    return number_of(*node, key_path(key), range);
  }
  double number(std::string_view key, const Range& range) const {
    const auto value = optional_number(key, range);
    if (!value) missing(key, expected_number(range));
    return *value;
  }
  double number_or(std::string_view key, double fallback, const Range& range) const {
    return optional_number(key, range).value_or(fallback);
  }

  /// An integer in [low, high]; a float with an integral value (1e6) is accepted too.
  std::optional<std::int64_t> optional_integer(std::string_view key, std::int64_t low, std::int64_t high) const;
  std::int64_t integer(std::string_view key, std::int64_t low, std::int64_t high) const {
    const auto value = optional_integer(key, low, high);
    if (!value) missing(key, "an integer in [" + std::to_string(low) + ", " + std::to_string(high) + "]");
    return *value;
  }
  std::int64_t integer_or(std::string_view key, std::int64_t fallback, std::int64_t low, std::int64_t high) const {
    return optional_integer(key, low, high).value_or(fallback);
  }

  bool boolean_or(std::string_view key, bool fallback) const {
    const toml::node* node = get(key);
    if (!node) return fallback;
    if (const auto* b = node->as_boolean()) return b->get();
    fail(node, key_path(key), "expected true or false, got " + describe_node(*node));
  }

  std::optional<std::string> optional_string(std::string_view key) const {
    const toml::node* node = get(key);
    if (!node) return std::nullopt;
    if (const auto* s = node->as_string()) return std::string(s->get());
    fail(node, key_path(key), "expected a string, got " + describe_node(*node));
  }
  std::string string(std::string_view key) const {
    const auto value = optional_string(key);
    if (!value) missing(key, "a string");
    return *value;
  }

  /// One of the listed words.
  std::optional<std::string> optional_choice(std::string_view key, std::initializer_list<std::string_view> words) const;
  std::string choice(std::string_view key, std::initializer_list<std::string_view> words) const;

  /// An array of N finite numbers.
  template <int N>
  std::optional<Eigen::Matrix<double, N, 1>> optional_vector(std::string_view key,
                                                             const Range& range = any_number()) const {
    const toml::node* node = get(key);
    if (!node) return std::nullopt;
    const std::string expected = "an array of " + std::to_string(N) + " numbers";
    const auto* array = node->as_array();
    if (!array || array->size() != static_cast<std::size_t>(N)) {
      fail(node, key_path(key), "expected " + expected + ", got " + describe_node(*node));
    }
    Eigen::Matrix<double, N, 1> value;
    for (int i = 0; i < N; ++i) {
      value[i] =
          number_of(*array->get(static_cast<std::size_t>(i)), key_path(key) + "[" + std::to_string(i) + "]", range);
    }
    return value;
  }
  Vec3 vec3(std::string_view key, const Range& range = any_number()) const {
    const auto value = optional_vector<3>(key, range);
    if (!value) missing(key, "an array of 3 numbers [x, y, z]");
    return *value;
  }
  Vec3 vec3_or(std::string_view key, const Vec3& fallback) const { return optional_vector<3>(key).value_or(fallback); }
  /// A rotation as a quaternion [w, x, y, z], normalised (must not be zero).
  Quat orientation_or_identity(std::string_view key) const;

  /// An optional sub-table.
  std::optional<TableReader> optional_table(std::string_view key) const;

  /// The tables of an array of tables ([[key]] entries), in order.
  std::vector<TableReader> tables(std::string_view key) const;

 private:
  const std::string& file_;
  const toml::table& table_;
  std::string path_;
  const toml::node* anchor_;
};

/// True when `key` holds the string "auto"; any other string is an error (numbers are read later).
bool is_auto(const TableReader& table, std::string_view key);

}  // namespace rubble::scene_detail
