#include "simulation/scene_file.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <random>
#include <sstream>
#include <vector>

#include <toml++/toml.h>

#include "core/units.hpp"
#include "core/polyhedron.hpp"
#include "preprocessing/grain_shapes.hpp"
#include "preprocessing/packing.hpp"
#include "preprocessing/polyhedron_file.hpp"
#include "preprocessing/random_polyhedron.hpp"
#include "core/input_file.hpp"
#include "simulation/memory_estimate.hpp"
#include "simulation/run_control.hpp"

namespace rubble {

SceneError::SceneError(std::string file_, int line_, std::string key_, std::string message_)
    : std::runtime_error(file_ + (line_ > 0 ? ":" + std::to_string(line_) : std::string()) + ": " +
                         (key_.empty() ? std::string() : key_ + ": ") + message_),
      file(std::move(file_)),
      line(line_),
      key(std::move(key_)),
      message(std::move(message_)) {}

namespace {

constexpr double infinity = std::numeric_limits<double>::infinity();

/// Grains may start overlapping a wall or each other by at most this fraction of the (smaller)
/// radius: the solver's penetration correction removes such small overlaps (e.g. a settled pile
/// written back with scene_to_toml), larger ones are mistakes in the scene.
constexpr double allowed_initial_overlap = 0.01;

/// Shortest text that reads back to the same double (std::to_chars), always with a '.' or an
/// exponent so that TOML reads it as a float.
std::string format_number(double x) {
  if (std::isnan(x)) return "nan";
  if (std::isinf(x)) return x > 0 ? "inf" : "-inf";
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof buffer, x);
  std::string text(buffer, result.ptr);
  if (text.find_first_of(".e") == std::string::npos) text += ".0";
  return text;
}

/// Shortest text of a number for messages ("-1", "0.5", "nan").
std::string show(double x) {
  if (std::isnan(x)) return "nan";
  if (std::isinf(x)) return x > 0 ? "inf" : "-inf";
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof buffer, x);
  return std::string(buffer, result.ptr);
}

/// A computed number for messages, to 6 significant digits.
std::string show_short(double x) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.6g", x);
  return buffer;
}

/// A closed, open or half-open interval of allowed values, with its description for messages.
struct Range {
  double low = -infinity;
  double high = infinity;
  bool low_closed = true;
  bool high_closed = true;

  bool contains(double x) const {
    return (low_closed ? x >= low : x > low) && (high_closed ? x <= high : x < high);
  }
  std::string describe() const {
    const bool has_low = low > -infinity;
    const bool has_high = high < infinity;
    if (has_low && has_high) {
      return "in " + std::string(low_closed ? "[" : "(") + show(low) + ", " + show(high) +
             (high_closed ? "]" : ")");
    }
    if (has_low) return std::string(low_closed ? ">= " : "> ") + show(low);
    if (has_high) return std::string(high_closed ? "<= " : "< ") + show(high);
    return "";
  }
};

Range positive() { return Range{0.0, infinity, false, true}; }
Range non_negative() { return Range{0.0, infinity, true, true}; }
Range any_number() { return Range{}; }
Range closed(double a, double b) { return Range{a, b, true, true}; }
/// Positions and lengths of a scene, m. Past 10^12 m (7 AU) a double resolves no better than
/// 10^-4 m, coarser than the grains' contact geometry, and region sizes, volumes and capacities
/// derived from larger values overflow (a ±1e308 region gave an infinite first snapshot).
constexpr double max_scene_length = 1e12;
Range coordinate() { return closed(-max_scene_length, max_scene_length); }
Range length() { return Range{0.0, max_scene_length, false, true}; }
Range length_or_zero() { return closed(0.0, max_scene_length); }
Range open(double a, double b) { return Range{a, b, false, false}; }

/// "a number > 0" etc.
std::string expected_number(const Range& range) {
  const std::string bounds = range.describe();
  return bounds.empty() ? "a finite number" : "a finite number " + bounds;
}

/// What a TOML node holds, for "got ..." in messages.
std::string describe_node(const toml::node& node) {
  switch (node.type()) {
    case toml::node_type::string: return "the string \"" + std::string(node.as_string()->get()) + "\"";
    case toml::node_type::integer: return std::to_string(node.as_integer()->get());
    case toml::node_type::floating_point: return show(node.as_floating_point()->get());
    case toml::node_type::boolean: return node.as_boolean()->get() ? "true" : "false";
    case toml::node_type::array: return "an array of " + std::to_string(node.as_array()->size()) + " elements";
    case toml::node_type::table: return "a table";
    default: return "a date/time";
  }
}

int line_of(const toml::node* node) { return node ? static_cast<int>(node->source().begin.line) : 0; }

/// Levenshtein distance, for "did you mean" hints on misspelt keys.
std::size_t edit_distance(std::string_view a, std::string_view b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diagonal = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = up;
    }
  }
  return row[b.size()];
}

/// A TOML table being read, with its dotted path for messages.
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

  [[noreturn]] void fail(const toml::node* at, const std::string& key, const std::string& message) const {
    throw SceneError(file_, line_of(at), key, message);
  }
  [[noreturn]] void fail_key(std::string_view key, const std::string& message) const {
    const toml::node* node = table_.get(key);
    fail(node ? node : anchor_, key_path(key), message);
  }
  [[noreturn]] void fail_table(const std::string& message) const { fail(anchor_, path_, message); }

  /// Rejects keys not in `allowed` (typos!), suggesting the closest allowed key.
  void allow_only(std::initializer_list<std::string_view> allowed, std::string_view context = {}) const {
    allow_only(std::vector<std::string_view>(allowed), context);
  }
  void allow_only(const std::vector<std::string_view>& allowed, std::string_view context = {}) const {
    for (const auto& [key, node] : table_) {
      const std::string_view name = key.str();
      if (std::find(allowed.begin(), allowed.end(), name) != allowed.end()) continue;
      std::string message = "unknown key";
      if (!context.empty()) message += " " + std::string(context);
      std::string_view best;
      std::size_t best_distance = 3;
      for (std::string_view candidate : allowed) {
        const std::size_t d = edit_distance(name, candidate);
        if (d < best_distance) {
          best_distance = d;
          best = candidate;
        }
      }
      if (!best.empty()) {
        message += " (did you mean \"" + std::string(best) + "\"?)";
      } else {
        message += " (expected one of:";
        for (std::string_view candidate : allowed) {
          // Appended piece by piece: `" " + std::string(...)` trips GCC 12's -Wrestrict false positive.
          message += ' ';
          message.append(candidate);
        }
        message += ")";
      }
      fail(&node, key_path(name), message);
    }
  }

  bool has(std::string_view key) const { return table_.contains(key); }
  const toml::node* get(std::string_view key) const { return table_.get(key); }

  [[noreturn]] void missing(std::string_view key, const std::string& expected) const {
    fail(anchor_, key_path(key), "missing required key (expected " + expected + ")");
  }

  /// A number checked against `range`; integers are accepted as numbers.
  double number_of(const toml::node& node, const std::string& key, const Range& range) const {
    double value = 0;
    if (const auto* f = node.as_floating_point()) {
      value = f->get();
    } else if (const auto* i = node.as_integer()) {
      value = static_cast<double>(i->get());
    } else {
      fail(&node, key, "expected " + expected_number(range) + ", got " + describe_node(node));
    }
    if (!std::isfinite(value) || !range.contains(value)) {
      fail(&node, key, "expected " + expected_number(range) + ", got " + show(value));
    }
    return value;
  }
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
  std::optional<std::int64_t> optional_integer(std::string_view key, std::int64_t low, std::int64_t high) const {
    const toml::node* node = get(key);
    if (!node) return std::nullopt;
    const std::string expected = "an integer in [" + std::to_string(low) + ", " + std::to_string(high) + "]";
    std::int64_t value = 0;
    if (const auto* i = node->as_integer()) {
      value = i->get();
    } else if (const auto* f = node->as_floating_point();
               f && std::isfinite(f->get()) && std::floor(f->get()) == f->get() && std::abs(f->get()) < 9e18) {
      value = static_cast<std::int64_t>(f->get());
    } else {
      fail(node, key_path(key), "expected " + expected + ", got " + describe_node(*node));
    }
    if (value < low || value > high) {
      fail(node, key_path(key), "expected " + expected + ", got " + std::to_string(value));
    }
    return value;
  }
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
  std::optional<std::string> optional_choice(std::string_view key, std::initializer_list<std::string_view> words) const {
    std::string expected = "one of";
    for (std::string_view word : words) expected += std::string(word == *words.begin() ? " " : ", ") + "\"" + std::string(word) + "\"";
    const toml::node* node = get(key);
    if (!node) return std::nullopt;
    const auto* s = node->as_string();
    if (!s) fail(node, key_path(key), "expected " + expected + ", got " + describe_node(*node));
    const std::string value(s->get());
    if (std::find(words.begin(), words.end(), value) == words.end()) {
      fail(node, key_path(key), "expected " + expected + ", got \"" + value + "\"");
    }
    return value;
  }
  std::string choice(std::string_view key, std::initializer_list<std::string_view> words) const {
    const auto value = optional_choice(key, words);
    if (!value) {
      std::string expected = "one of";
      for (std::string_view word : words) expected += std::string(word == *words.begin() ? " " : ", ") + "\"" + std::string(word) + "\"";
      missing(key, expected);
    }
    return *value;
  }

  /// An array of N finite numbers.
  template <int N>
  std::optional<Eigen::Matrix<double, N, 1>> optional_vector(std::string_view key, const Range& range = any_number()) const {
    const toml::node* node = get(key);
    if (!node) return std::nullopt;
    const std::string expected = "an array of " + std::to_string(N) + " numbers";
    const auto* array = node->as_array();
    if (!array || array->size() != static_cast<std::size_t>(N)) {
      fail(node, key_path(key), "expected " + expected + ", got " + describe_node(*node));
    }
    Eigen::Matrix<double, N, 1> value;
    for (int i = 0; i < N; ++i) {
      value[i] = number_of(*array->get(static_cast<std::size_t>(i)),
                           key_path(key) + "[" + std::to_string(i) + "]", range);
    }
    return value;
  }
  Vec3 vec3(std::string_view key, const Range& range = any_number()) const {
    const auto value = optional_vector<3>(key, range);
    if (!value) missing(key, "an array of 3 numbers [x, y, z]");
    return *value;
  }
  Vec3 vec3_or(std::string_view key, const Vec3& fallback) const {
    return optional_vector<3>(key).value_or(fallback);
  }
  /// A rotation as a quaternion [w, x, y, z], normalised (must not be zero).
  Quat orientation_or_identity(std::string_view key) const {
    const auto value = optional_vector<4>(key);
    if (!value) return Quat::Identity();
    // stableNorm: the plain norm of [1e200, 0, 0, 0] overflows to inf, and dividing by it made
    // the zero quaternion (a grain that never turns).
    const double norm = value->stableNorm();
    if (!(norm > 1e-12)) fail_key(key, "expected a nonzero quaternion [w, x, y, z], got a zero one");
    Quat q((*value)[0], (*value)[1], (*value)[2], (*value)[3]);
    // Leave unit quaternions bit for bit as written, so that written scenes read back exactly.
    if (std::abs(norm - 1.0) > 1e-15) q = Quat(q.w() / norm, q.x() / norm, q.y() / norm, q.z() / norm);
    return q;
  }

  /// An optional sub-table.
  std::optional<TableReader> optional_table(std::string_view key) const {
    const toml::node* node = get(key);
    if (!node) return std::nullopt;
    const auto* table = node->as_table();
    if (!table) fail(node, key_path(key), "expected a table [" + key_path(key) + "], got " + describe_node(*node));
    return TableReader(file_, *table, key_path(key), node);
  }

  /// The tables of an array of tables ([[key]] entries), in order.
  std::vector<TableReader> tables(std::string_view key) const {
    std::vector<TableReader> result;
    const toml::node* node = get(key);
    if (!node) return result;
    const auto* array = node->as_array();
    if (!array) {
      fail(node, key_path(key), "expected an array of tables ([[" + std::string(key) + "]] entries), got " +
                                    describe_node(*node));
    }
    for (std::size_t i = 0; i < array->size(); ++i) {
      const toml::node* element = array->get(i);
      const std::string path = key_path(key) + "[" + std::to_string(i) + "]";
      const auto* table = element->as_table();
      if (!table) fail(element, path, "expected a table, got " + describe_node(*element));
      result.emplace_back(file_, *table, path, element);
    }
    return result;
  }

 private:
  const std::string& file_;
  const toml::table& table_;
  std::string path_;
  const toml::node* anchor_;
};

/// Where a grain came from, for messages about it.
struct GrainOrigin {
  int body_entry = -1;       ///< index in [[bodies]], or -1
  int generator = -1;        ///< index in [[generators]], or -1
  std::uint64_t ordinal = 0; ///< grain number within its generator
  const toml::node* node = nullptr;  ///< the entry's table
};

/// A grain to add: a sphere, or a polyhedron when `polyhedron` is set.
struct GrainSpec {
  double radius = 0;  ///< sphere radius, or the polyhedron's bounding radius about its centroid
  std::shared_ptr<const ConvexPolyhedron> polyhedron;  ///< body-frame shape, null for a sphere
  int material = 0;
  Vec3 position = Vec3::Zero();
  Quat orientation = Quat::Identity();
  Vec3 velocity = Vec3::Zero();
  Vec3 angular_velocity = Vec3::Zero();
  int motion = -1;  ///< index into the parser's prescribed motions for a driven grain, else -1
  GrainOrigin origin{};
};

/// A wall to add.
struct WallSpec {
  bool is_plane = true;
  Vec3 position = Vec3::Zero();       ///< plane point or box centre
  Vec3 normal = Vec3::UnitZ();        ///< unit, plane only
  Vec3 half_extents = Vec3::Zero();   ///< box only
  Quat orientation = Quat::Identity();
  int material = 0;
  std::optional<PrescribedMotion> motion;  ///< set for a moving wall
  std::string path;
  const toml::node* node = nullptr;
};

/// The grain as named after its key: "the grain" for a [[bodies]] entry, "grain N" for a generator's.
std::string grain_label(const GrainOrigin& origin) {
  if (origin.body_entry >= 0) return "the grain";
  return "grain " + std::to_string(origin.ordinal);
}

/// The grain named in full, for messages about another grain.
std::string grain_name(const GrainOrigin& origin) {
  if (origin.body_entry >= 0) return "bodies[" + std::to_string(origin.body_entry) + "]";
  return "generators[" + std::to_string(origin.generator) + "] (grain " + std::to_string(origin.ordinal) + ")";
}

std::string grain_key(const GrainOrigin& origin) {
  if (origin.body_entry >= 0) return "bodies[" + std::to_string(origin.body_entry) + "]";
  return "generators[" + std::to_string(origin.generator) + "]";
}

/// [x, y, z] for messages.
std::string show_vec3(const Vec3& v) {
  return "[" + show_short(v.x()) + ", " + show_short(v.y()) + ", " + show_short(v.z()) + "]";
}

/// [x, y, z] as TOML floats.
std::string format_vec3(const Vec3& v) {
  return "[" + format_number(v.x()) + ", " + format_number(v.y()) + ", " + format_number(v.z()) + "]";
}

/// Everything the parser has gathered.
class SceneParser {
 public:
  SceneParser(const std::string& file, const toml::table& root) : file_(file), root_(file, root, "", nullptr) {}

  Scene parse(const std::string& default_name) {
    root_.allow_only({"name", "seed", "time", "solver", "detection", "gravity", "output", "materials",
                      "contact_laws", "default_contact_law", "walls", "bodies", "generators", "initial_conditions"},
                     "at the top level");
    scene_.name = root_.optional_string("name").value_or(default_name);
    scene_.run.seed = static_cast<std::uint64_t>(root_.integer_or("seed", 1, 0, std::numeric_limits<std::int64_t>::max()));
    parse_time();
    parse_solver();
    parse_detection();
    parse_gravity();
    parse_output();
    parse_materials();
    parse_contact_laws();
    parse_walls();
    parse_bodies();
    parse_generators();
    parse_initial_conditions();
    if (grains_.empty()) {
      root_.fail(nullptr, "", "the scene has no grains: expected at least one [[bodies]] or [[generators]] entry");
    }
    check_contact_law_coverage();
    check_walls_have_an_inside();
    check_grains_inside_walls();
    check_grains_do_not_overlap();
    build();
    finish_time();
    return std::move(scene_);
  }

 private:
  void parse_time() {
    const auto time = root_.optional_table("time");
    if (!time) root_.fail(nullptr, "time", "missing required table [time] (expected dt and end_time, in s)");
    if (time->has("rest_kinetic_energy")) {
      // Scenes written before issue 18: the mean kinetic energy per grain declared rest while a few
      // grains still moved fast; the criterion is now on the grains' speeds, Z and contacts.
      time->fail_key("rest_kinetic_energy",
                     "replaced by rest_speed (m/s or \"auto\"): rest is now judged on the grains' speeds, the "
                     "coordination number and the contacts (docs/scene-file.md, \"Stopping at rest\")");
    }
    time->allow_only({"dt", "theta", "end_time", "until", "rest_speed", "rest_quantile", "rest_coordination_change",
                      "rest_contact_change", "rest_duration"},
                     "in [time]");
    auto& integrator = scene_.run.step.integrator;
    RunOptions& run = scene_.run;
    run.automatic_time_step = is_auto(*time, "dt");
    if (!run.automatic_time_step) integrator.time_step = time->number("dt", positive());
    integrator.theta = time->number_or("theta", 0.5, closed(0.5, 1.0));
    run.end_time = time->number("end_time", positive());
    run.until_rest = time->optional_choice("until", {"end_time", "rest"}).value_or("end_time") == "rest";
    for (const std::string_view key :
         {"rest_speed", "rest_quantile", "rest_coordination_change", "rest_contact_change", "rest_duration"}) {
      if (time->has(key) && !run.until_rest) {
        time->fail_key(key, "only used with until = \"rest\" (expected that key too, or no " + std::string(key) + ")");
      }
    }
    run.automatic_rest_speed = is_auto(*time, "rest_speed") || !time->has("rest_speed");
    if (!run.automatic_rest_speed) run.rest.speed = time->number("rest_speed", positive());
    run.rest.quantile = time->number_or("rest_quantile", auto_rest_quantile, Range{0.0, 1.0, false, true});
    run.automatic_rest_coordination_change =
        is_auto(*time, "rest_coordination_change") || !time->has("rest_coordination_change");
    if (!run.automatic_rest_coordination_change) {
      run.rest.coordination_change = time->number("rest_coordination_change", non_negative());
    }
    run.rest.contact_change = time->number_or("rest_contact_change", auto_rest_contact_change, closed(0.0, 1.0));
    run.automatic_rest_duration = is_auto(*time, "rest_duration") || !time->has("rest_duration");
    if (!run.automatic_rest_duration) run.rest.duration = time->number("rest_duration", non_negative());
    if (!run.automatic_time_step) check_step_count(*time);
  }

  /// True when `key` holds the string "auto"; any other string is an error (numbers are read later).
  static bool is_auto(const TableReader& table, std::string_view key) {
    const toml::node* node = table.get(key);
    if (!node || !node->is_string()) return false;
    const std::string value(node->as_string()->get());
    if (value != "auto") {
      table.fail(node, table.key_path(key), "expected a finite number or \"auto\", got \"" + value + "\"");
    }
    return true;
  }

  /// dt against end_time: not longer, and not absurdly many steps.
  void check_step_count(const TableReader& time) const {
    const auto& integrator = scene_.run.step.integrator;
    const std::string origin = scene_.run.automatic_time_step ? " (the automatic dt)" : "";
    // A guard against typos in the exponent (dt = 1e-40): more steps than any run can take
    // (the same bound holds --end-time, run_control.hpp).
    constexpr double max_steps = max_run_steps;
    if (scene_.run.end_time / integrator.time_step > max_steps) {
      time.fail_key("dt", "expected at most 10^12 steps (dt >= end_time / 1e12 = " +
                              show_short(scene_.run.end_time / max_steps) + " s), got dt = " +
                              show(integrator.time_step) + origin);
    }
    if (integrator.time_step > scene_.run.end_time) {
      time.fail_key("dt", "expected dt <= end_time (" + show(scene_.run.end_time) + " s), got " +
                              show(integrator.time_step) + origin);
    }
  }

  /// What depends on the grains: dt = "auto" and the automatic rest criterion (run_control.hpp).
  void finish_time() {
    const auto time = root_.optional_table("time");
    RunOptions& run = scene_.run;
    if (run.automatic_time_step) {
      try {
        run.step.integrator.time_step = automatic_time_step(scene_.model, scene_.state, run.step.gravity).time_step;
      } catch (const std::invalid_argument& error) {
        time->fail_key("dt", error.what());
      }
      check_step_count(*time);
    }
    if (run.until_rest) {
      const SceneScales scales = scene_scales(scene_.model, scene_.state, run.step.gravity);
      try {
        const RestCriterion given = run.rest;
        run.rest = automatic_rest_criterion(scales, run.automatic_rest_speed ? 0.0 : given.speed,
                                            run.automatic_rest_duration ? 0.0 : given.duration);
        run.rest.quantile = given.quantile;
        if (!run.automatic_rest_coordination_change) run.rest.coordination_change = given.coordination_change;
        run.rest.contact_change = given.contact_change;
        if (!run.automatic_rest_duration) run.rest.duration = given.duration;  // 0 is a valid duration
      } catch (const std::invalid_argument& error) {
        time->fail_key(run.automatic_rest_speed ? "rest_speed" : "rest_duration", error.what());
      }
    }
  }

  void parse_solver() {
    const auto solver = root_.optional_table("solver");
    if (!solver) return;
    solver->allow_only({"tolerance", "max_iterations", "relaxation", "warm_start", "penetration_correction",
                        "max_correction_velocity", "allowed_overlap", "polish_after", "polish_iterations", "polish_max_contacts",
                        "polish_attempts_per_step", "block_count"},
                       "in [solver]");
    auto& options = scene_.run.step.solver;
    options.tolerance = solver->number_or("tolerance", options.tolerance, positive());
    options.max_iterations =
        static_cast<int>(solver->integer_or("max_iterations", options.max_iterations, 1, 100'000'000));
    options.relaxation = solver->number_or("relaxation", options.relaxation, open(0.0, 2.0));
    options.warm_start = solver->boolean_or("warm_start", options.warm_start);
    auto& recovery = options.overlap_recovery;
    recovery.fraction = solver->number_or("penetration_correction", recovery.fraction, closed(0.0, 1.0));
    recovery.max_velocity = solver->number_or("max_correction_velocity", recovery.max_velocity, non_negative());
    recovery.allowed_overlap = solver->number_or("allowed_overlap", recovery.allowed_overlap, closed(0.0, 1.0));
    options.polish_after = static_cast<int>(solver->integer_or("polish_after", options.polish_after, 0, 100'000'000));
    options.polish_iterations =
        static_cast<int>(solver->integer_or("polish_iterations", options.polish_iterations, 1, 10'000));
    options.polish_max_contacts = static_cast<std::size_t>(
        solver->integer_or("polish_max_contacts", static_cast<std::int64_t>(options.polish_max_contacts), 0, 100'000'000));
    options.polish_attempts_per_step =
        static_cast<int>(solver->integer_or("polish_attempts_per_step", options.polish_attempts_per_step, 1, 100));
    options.block_count = static_cast<int>(solver->integer_or("block_count", options.block_count, 1, 1'000'000));
  }

  void parse_detection() {
    const auto detection = root_.optional_table("detection");
    if (!detection) return;
    detection->allow_only({"alert_distance", "pair_list_margin"}, "in [detection]");
    scene_.run.step.detection.alert_distance = detection->number_or("alert_distance", 0.0, non_negative());
    if (is_auto(*detection, "pair_list_margin")) {
      scene_.run.step.detection.pair_list_margin = -1.0;
    } else {
      scene_.run.step.detection.pair_list_margin =
          detection->number_or("pair_list_margin", scene_.run.step.detection.pair_list_margin, non_negative());
    }
  }

  void parse_gravity() {
    auto& gravity = scene_.run.step.gravity;
    const auto table = root_.optional_table("gravity");
    if (!table) {
      gravity.kind = GravitySettings::Kind::none;
      return;
    }
    const std::string type = table->choice("type", {"none", "uniform", "direct", "tree", "central"});
    if (type == "none") {
      table->allow_only({"type"}, "for [gravity] type = \"none\"");
      gravity.kind = GravitySettings::Kind::none;
    } else if (type == "uniform") {
      table->allow_only({"type", "acceleration"}, "for [gravity] type = \"uniform\"");
      gravity.kind = GravitySettings::Kind::uniform;
      gravity.acceleration = table->vec3("acceleration");
    } else if (type == "central") {
      // A fixed point mass (step.hpp, CentralField): Plummer-softened Kepler field.
      table->allow_only({"type", "centre", "mass", "G", "softening"}, "for [gravity] type = \"central\"");
      gravity.kind = GravitySettings::Kind::central;
      auto& central = gravity.central;
      central.centre = table->vec3("centre", coordinate());
      central.mass = table->number("mass", positive());
      central.G = table->number_or("G", units::gravitational_constant, positive());
      central.softening = table->number_or("softening", 0.0, non_negative());
    } else {
      const bool tree = type == "tree";
      if (tree) {
        table->allow_only(
            {"type", "G", "softening", "theta", "order", "leaf_size", "group_size", "evaluate_every", "backend"},
            "for [gravity] type = \"tree\"");
      } else {
        table->allow_only({"type", "G", "softening", "evaluate_every", "backend"}, "for [gravity] type = \"direct\"");
      }
      // Held field between evaluations (step.cpp); capped so a typo cannot freeze gravity for a run.
      gravity.evaluate_every = static_cast<int>(table->integer_or("evaluate_every", 1, 1, 1'000'000));
      gravity.kind = GravitySettings::Kind::self;
      auto& self = gravity.self_gravity;
      self.method = tree ? gravity::Method::tree : gravity::Method::direct;
      self.G = table->number_or("G", units::gravitational_constant, positive());
      const double softening = table->number_or("softening", 0.0, non_negative());
      self.softening.kind = softening > 0.0 ? gravity::Softening::Kind::plummer : gravity::Softening::Kind::none;
      self.softening.length = softening;
      if (tree) {
        self.theta = table->number_or("theta", self.theta, Range{0.0, 2.0, false, true});
        self.order = static_cast<int>(table->integer_or("order", self.order, 1, 2));
        self.leaf_size = static_cast<int>(table->integer_or("leaf_size", self.leaf_size, 1, 1'000'000));
        self.group_size = static_cast<int>(table->integer_or("group_size", self.group_size, 1, 1'000'000));
      }
      // A GPU backend that cannot run here is refused now, at its line, not at the first step.
      if (table->optional_choice("backend", {"cpu", "cuda"}).value_or("cpu") == "cuda") {
        self.backend = gravity::Backend::cuda;
        const std::string reason = gravity::backend_unavailable_reason(self);
        if (!reason.empty()) table->fail_key("backend", "\"cuda\" cannot run here: " + reason);
      }
    }
  }

  void parse_output() {
    const auto output = root_.optional_table("output");
    if (!output) return;
    output->allow_only({"directory", "snapshot_every_steps", "snapshot_interval", "progress_interval", "vtk",
                        "keep_checkpoint_every"},
                       "in [output]");
    auto& options = scene_.run.output;
    if (const auto directory = output->optional_string("directory")) {
      if (directory->empty()) output->fail_key("directory", "expected a folder name, got an empty string");
      options.directory = *directory;
    }
    options.snapshot_every_steps = output->integer_or("snapshot_every_steps", 0, 0, std::numeric_limits<std::int64_t>::max());
    options.snapshot_interval = output->number_or("snapshot_interval", 0.0, non_negative());
    if (options.snapshot_every_steps > 0 && options.snapshot_interval > 0.0) {
      output->fail_key("snapshot_interval",
                       "expected either snapshot_every_steps or snapshot_interval, not both");
    }
    options.progress_interval = output->number_or("progress_interval", options.progress_interval, non_negative());
    options.write_vtk = output->boolean_or("vtk", options.write_vtk);
    options.keep_checkpoint_every =
        output->integer_or("keep_checkpoint_every", 0, 0, std::numeric_limits<std::int64_t>::max());
  }

  void parse_materials() {
    for (const TableReader& entry : root_.tables("materials")) {
      entry.allow_only({"name", "density"}, "in [[materials]]");
      const std::string name = entry.string("name");
      if (name.empty()) entry.fail_key("name", "expected a nonempty material name");
      if (material_ids_.count(name)) {
        entry.fail_key("name", "material \"" + name + "\" is defined twice (expected unique names)");
      }
      const double density = entry.number("density", positive());
      material_ids_[name] = static_cast<int>(scene_.model.materials.size());
      scene_.model.materials.push_back(Material{name, density});
    }
  }

  /// Material of a grain or wall: the `material` key, or the only material when there is one.
  int material_of(const TableReader& entry) {
    const auto name = entry.optional_string("material");
    if (!name) {
      if (scene_.model.materials.size() == 1) return 0;
      if (scene_.model.materials.empty()) {
        entry.fail_table("no materials defined: expected a [[materials]] entry with name and density");
      }
      entry.missing("material", "the name of a [[materials]] entry (required when there are several)");
    }
    const auto it = material_ids_.find(*name);
    if (it == material_ids_.end()) entry.fail_key("material", "unknown material \"" + *name + "\"" + known_materials());
    return it->second;
  }

  std::string known_materials() const {
    if (material_ids_.empty()) return " (no [[materials]] are defined)";
    std::string list = " (expected one of:";
    for (const Material& m : scene_.model.materials) list += " \"" + m.name + "\"";
    return list + ")";
  }

  ContactLaw parse_law(const TableReader& entry) const {
    ContactLaw law;
    law.friction_coefficient = entry.number("friction", non_negative());
    law.normal_restitution = entry.number_or("restitution", 0.0, closed(0.0, 1.0));
    law.tangential_restitution = entry.number_or("tangential_restitution", 0.0, closed(0.0, 1.0));
    law.cohesion = entry.number_or("cohesion", 0.0, non_negative());
    law.work_of_adhesion = entry.number_or("work_of_adhesion", 0.0, non_negative());
    law.rolling_friction = entry.number_or("rolling_friction", 0.0, non_negative());
    law.twisting_friction = entry.number_or("twisting_friction", 0.0, non_negative());
    return law;
  }

  void parse_contact_laws() {
    const int n = static_cast<int>(scene_.model.materials.size());
    if (const auto fallback = root_.optional_table("default_contact_law")) {
      fallback->allow_only({"friction", "restitution", "tangential_restitution", "cohesion", "work_of_adhesion",
                            "rolling_friction", "twisting_friction"},
                           "in [default_contact_law]");
      default_law_ = parse_law(*fallback);
    }
    scene_.model.contact_laws.reset(n, default_law_.value_or(ContactLaw{}));
    law_defined_.assign(static_cast<std::size_t>(n * n), false);
    for (const TableReader& entry : root_.tables("contact_laws")) {
      entry.allow_only({"materials", "friction", "restitution", "tangential_restitution", "cohesion", "work_of_adhesion",
                        "rolling_friction", "twisting_friction"},
                       "in [[contact_laws]]");
      const toml::node* node = entry.get("materials");
      if (!node) entry.missing("materials", "a pair of material names, e.g. [\"rock\", \"rock\"]");
      const auto* array = node->as_array();
      if (!array || array->size() != 2 || !array->get(0)->is_string() || !array->get(1)->is_string()) {
        entry.fail(node, entry.key_path("materials"),
                   "expected a pair of material names, e.g. [\"rock\", \"rock\"], got " + describe_node(*node));
      }
      int ids[2];
      for (int k = 0; k < 2; ++k) {
        const std::string name(array->get(static_cast<std::size_t>(k))->as_string()->get());
        const auto it = material_ids_.find(name);
        if (it == material_ids_.end()) {
          entry.fail(node, entry.key_path("materials"), "unknown material \"" + name + "\"" + known_materials());
        }
        ids[k] = it->second;
      }
      if (law_defined_[static_cast<std::size_t>(ids[0] * n + ids[1])]) {
        entry.fail(node, entry.key_path("materials"),
                   "the contact law of this pair is defined twice (expected one entry per pair)");
      }
      scene_.model.contact_laws.set(ids[0], ids[1], parse_law(entry));
      law_defined_[static_cast<std::size_t>(ids[0] * n + ids[1])] = true;
      law_defined_[static_cast<std::size_t>(ids[1] * n + ids[0])] = true;
    }
  }

  void parse_walls() {
    for (const TableReader& entry : root_.tables("walls")) {
      WallSpec wall;
      wall.path = entry.path();
      wall.node = entry.anchor();
      const std::string type = entry.choice("type", {"plane", "box"});
      if (type == "plane") {
        entry.allow_only({"type", "point", "normal", "material", "velocity", "angular_velocity", "motion"},
                         "for a wall of type = \"plane\"");
        wall.is_plane = true;
        wall.position = entry.vec3("point", coordinate());
        const Vec3 normal = entry.vec3("normal");
        const double norm = normal.stableNorm();  // the plain norm of [1e200, 0, 0] overflows
        if (!(norm > 1e-12) || !std::isfinite(norm)) {
          entry.fail_key("normal", "expected a nonzero vector (the side grains live on), got " + show_vec3(normal));
        }
        wall.normal = normal / norm;
      } else {
        entry.allow_only({"type", "center", "half_extents", "orientation", "material", "velocity", "angular_velocity",
                          "motion"},
                         "for a wall of type = \"box\"");
        wall.is_plane = false;
        wall.position = entry.vec3("center", coordinate());
        wall.half_extents = entry.vec3("half_extents", length());
        wall.orientation = entry.orientation_or_identity("orientation");
      }
      wall.material = material_of(entry);
      // A wall moves when given a velocity, an angular velocity or a motion table.
      if (entry.has("motion") || entry.has("velocity") || entry.has("angular_velocity")) wall.motion = parse_motion(entry);
      walls_.push_back(wall);
    }
  }

  /// The prescribed motion of a driven wall or body: `motion`, a table of rows
  /// [t, vx, vy, vz] or [t, vx, vy, vz, wx, wy, wz] (s, m/s, rad/s; times increasing; linear in
  /// between, held outside), or else the constant `velocity` and `angular_velocity`.
  PrescribedMotion parse_motion(const TableReader& entry) const {
    PrescribedMotion motion;
    const toml::node* node = entry.get("motion");
    if (!node) {
      motion.time = {0.0};
      motion.velocity = {entry.vec3_or("velocity", Vec3::Zero())};
      motion.angular_velocity = {entry.vec3_or("angular_velocity", Vec3::Zero())};
      return motion;
    }
    for (const std::string_view key : {"velocity", "angular_velocity"}) {
      if (entry.has(key)) {
        entry.fail_key(key, "give either a motion table or a constant velocity and angular_velocity, not both (the "
                            "table's rows hold the velocities)");
      }
    }
    const auto* rows = node->as_array();
    if (!rows || rows->empty()) {
      entry.fail(node, entry.key_path("motion"),
                 "expected an array of rows [t, vx, vy, vz] or [t, vx, vy, vz, wx, wy, wz], got " + describe_node(*node));
    }
    for (std::size_t i = 0; i < rows->size(); ++i) {
      const std::string path = entry.key_path("motion") + "[" + std::to_string(i) + "]";
      const auto* row = rows->get(i)->as_array();
      if (!row || (row->size() != 4 && row->size() != 7)) {
        entry.fail(rows->get(i), path,
                   "expected a row [t, vx, vy, vz] or [t, vx, vy, vz, wx, wy, wz] (s, m/s, rad/s), got " +
                       describe_node(*rows->get(i)));
      }
      double values[7] = {0, 0, 0, 0, 0, 0, 0};
      for (std::size_t k = 0; k < row->size(); ++k) values[k] = entry.number_of(*row->get(k), path, any_number());
      if (!motion.time.empty() && !(values[0] > motion.time.back())) {
        entry.fail(rows->get(i), path,
                   "expected times increasing row by row, got t = " + show(values[0]) + " s after " +
                       show(motion.time.back()) + " s");
      }
      motion.time.push_back(values[0]);
      motion.velocity.emplace_back(values[1], values[2], values[3]);
      motion.angular_velocity.emplace_back(values[4], values[5], values[6]);
    }
    return motion;
  }

  void parse_initial_conditions() {
    for (const TableReader& entry : root_.tables("initial_conditions")) {
      entry.allow_only({"velocity", "angular_velocity", "center", "material", "region_min", "region_max"},
                       "in [[initial_conditions]]");
      if (!entry.has("velocity") && !entry.has("angular_velocity")) {
        entry.fail_table("expected velocity = [vx, vy, vz] (m/s) and/or angular_velocity = [wx, wy, wz] (rad/s)");
      }
      InitialCondition condition;
      condition.velocity = entry.vec3_or("velocity", Vec3::Zero());
      condition.angular_velocity = entry.vec3_or("angular_velocity", Vec3::Zero());
      condition.centre = entry.optional_vector<3>("center", coordinate());
      if (entry.has("material")) condition.material = material_of(entry);
      if (entry.has("region_min") != entry.has("region_max")) {
        entry.fail_key(entry.has("region_min") ? "region_min" : "region_max",
                       "expected both region_min and region_max (the corners of the box the grains' centres lie in)");
      }
      if (entry.has("region_min")) {
        condition.region_min = entry.vec3("region_min", coordinate());
        condition.region_max = entry.vec3("region_max", coordinate());
        if ((condition.region_max->array() < condition.region_min->array()).any()) {
          entry.fail_key("region_max", "expected region_max >= region_min on every axis, got " +
                                           show_vec3(*condition.region_max) + " vs " + show_vec3(*condition.region_min));
        }
      }
      scene_.initial_conditions.push_back(condition);
      condition_nodes_.push_back(entry.anchor());
    }
  }

  void parse_bodies() {
    const auto entries = root_.tables("bodies");
    for (std::size_t i = 0; i < entries.size(); ++i) {
      const TableReader& entry = entries[i];
      const std::string shape = entry.choice("shape", {"sphere", "polyhedron"});
      GrainSpec grain;
      if (shape == "polyhedron") {
        parse_polyhedron_body(entry, grain);
      } else {
        entry.allow_only({"shape", "radius", "position", "orientation", "velocity", "angular_velocity", "material",
                          "driven", "motion"},
                         "for a body of shape = \"sphere\"");
        grain.radius = entry.number("radius", positive());
        grain.position = entry.vec3("position", coordinate());
        grain.orientation = entry.orientation_or_identity("orientation");
      }
      grain.velocity = entry.vec3_or("velocity", Vec3::Zero());
      grain.angular_velocity = entry.vec3_or("angular_velocity", Vec3::Zero());
      grain.material = material_of(entry);
      const bool driven = entry.boolean_or("driven", entry.has("motion"));
      if (entry.has("motion") && !driven) entry.fail_key("driven", "a body with a motion table is driven: expected true");
      if (driven) {
        grain.motion = static_cast<int>(grain_motions_.size());
        grain_motions_.push_back(parse_motion(entry));
      }
      grain.origin.body_entry = static_cast<int>(i);
      grain.origin.node = entry.anchor();
      add_grain(grain);
    }
  }

  /// The parameters of random polyhedra common to [[bodies]] and [[generators]] (defaults: the
  /// accretion study's).
  RandomPolyhedronOptions parse_random_polyhedron_options(const TableReader& entry) const {
    RandomPolyhedronOptions options;
    options.min_vertices = static_cast<int>(entry.integer_or("min_vertices", options.min_vertices, 4, 100'000));
    options.max_vertices = static_cast<int>(entry.integer_or("max_vertices", options.max_vertices, 4, 100'000));
    if (options.max_vertices < options.min_vertices) {
      entry.fail_key("max_vertices", "expected max_vertices >= min_vertices (" + std::to_string(options.min_vertices) +
                                         "), got " + std::to_string(options.max_vertices));
    }
    options.min_elongation = entry.number_or("min_elongation", options.min_elongation, Range{0.0, 1.0, false, true});
    options.min_platyness = entry.number_or("min_platyness", options.min_platyness, Range{0.0, 1.0, false, true});
    return options;
  }

  /// A [[bodies]] entry of shape = "polyhedron": from a mesh file, from listed vertices and
  /// faces, or random. position/orientation place the file's (or the listed vertices') frame;
  /// for a random polyhedron, they are the centroid and the principal frame.
  void parse_polyhedron_body(const TableReader& entry, GrainSpec& grain) {
    const std::vector<std::string_view> placement = {"shape",    "position", "orientation", "velocity",
                                                     "angular_velocity", "material", "driven",      "motion"};
    const auto with = [&](std::initializer_list<std::string_view> more) {
      std::vector<std::string_view> keys = placement;
      keys.insert(keys.end(), more);
      return keys;
    };
    const int sources = (entry.has("file") ? 1 : 0) + (entry.has("vertices") ? 1 : 0) + (entry.has("diameter") ? 1 : 0);
    if (sources != 1) {
      entry.fail_table(sources == 0 ? "a polyhedron needs its shape: expected one of file = \"rock.obj\", vertices = "
                                      "[[x, y, z], ...] with faces, or diameter = D for a random one"
                                    : "expected only one of file, vertices and diameter");
    }
    const Vec3 position = entry.vec3("position", coordinate());
    const Quat orientation = entry.orientation_or_identity("orientation");
    PolyhedronPose pose;  // the body frame in the frame the shape was given in
    ConvexPolyhedron shape;
    if (entry.has("file")) {
      entry.allow_only(with({"file", "scale"}), "for a polyhedron read from a file");
      PolyhedronFileOptions options;
      options.scale = entry.number_or("scale", 1.0, positive());
      std::filesystem::path path = entry.string("file");
      if (path.is_relative()) path = std::filesystem::path(file_).parent_path() / path;
      try {
        shape = load_polyhedron_file(path.string(), options, &pose);
      } catch (const std::exception& error) {
        entry.fail_key("file", std::string("cannot use the polyhedron file: ") + error.what());
      }
    } else if (entry.has("vertices")) {
      entry.allow_only(with({"vertices", "faces", "convexity_tolerance"}), "for a polyhedron given by its vertices");
      const std::vector<Vec3> vertices = vector_list(entry, "vertices");
      const toml::node* faces_node = entry.get("faces");
      if (!faces_node) entry.missing("faces", "an array of faces, each an array of vertex indices (0-based, CCW from outside)");
      std::vector<std::vector<int>> faces;
      const auto* faces_array = faces_node->as_array();
      if (!faces_array) entry.fail(faces_node, entry.key_path("faces"), "expected an array of arrays of vertex indices");
      for (std::size_t f = 0; f < faces_array->size(); ++f) {
        const auto* face = faces_array->get(f)->as_array();
        const std::string key = entry.key_path("faces") + "[" + std::to_string(f) + "]";
        if (!face || face->size() < 3) entry.fail(faces_array->get(f), key, "expected an array of >= 3 vertex indices");
        std::vector<int> indices;
        for (std::size_t k = 0; k < face->size(); ++k) {
          const auto* index = face->get(k)->as_integer();
          if (!index || index->get() < 0 || index->get() >= static_cast<std::int64_t>(vertices.size())) {
            entry.fail(face->get(k), key, "expected vertex indices in [0, " + std::to_string(vertices.size() - 1) +
                                              "], got " + describe_node(*face->get(k)));
          }
          indices.push_back(static_cast<int>(index->get()));
        }
        faces.push_back(std::move(indices));
      }
      PolyhedronBuildOptions options;
      options.convexity_tolerance =
          entry.number_or("convexity_tolerance", options.convexity_tolerance, Range{0.0, 0.5, false, true});
      try {
        shape = make_convex_polyhedron(vertices, std::move(faces), options, &pose);
      } catch (const PolyhedronError& error) {
        entry.fail_key(error.face >= 0 ? "faces" : "vertices", error.what());
      }
    } else {
      entry.allow_only(with({"diameter", "shape_seed", "min_vertices", "max_vertices", "min_elongation", "min_platyness"}),
                       "for a random polyhedron");
      RandomPolyhedronOptions options = parse_random_polyhedron_options(entry);
      options.diameter = entry.number("diameter", positive());
      const auto shape_seed = static_cast<std::uint64_t>(
          entry.integer_or("shape_seed", static_cast<std::int64_t>(derive_seed(scene_.run.seed, 1ULL << 40) >> 1), 0,
                           std::numeric_limits<std::int64_t>::max()));
      try {
        shape = generate_random_polyhedron(options, shape_seed);
      } catch (const std::exception& error) {
        entry.fail_table(std::string("cannot make the random polyhedron: ") + error.what());
      }
    }
    grain.position = position + orientation * pose.centroid;
    grain.orientation = (orientation * pose.orientation).normalized();
    grain.radius = shape.bounding_radius;
    grain.polyhedron = std::make_shared<const ConvexPolyhedron>(std::move(shape));
  }

  /// An array of [x, y, z] arrays.
  std::vector<Vec3> vector_list(const TableReader& entry, std::string_view key) const {
    const toml::node* node = entry.get(key);
    const auto* array = node ? node->as_array() : nullptr;
    if (!array || array->size() < 4) {
      entry.fail(node ? node : entry.anchor(), entry.key_path(key),
                 "expected an array of >= 4 points [[x, y, z], ...]" +
                     (node ? ", got " + describe_node(*node) : std::string()));
    }
    std::vector<Vec3> points;
    for (std::size_t i = 0; i < array->size(); ++i) {
      const std::string path = entry.key_path(key) + "[" + std::to_string(i) + "]";
      const auto* point = array->get(i)->as_array();
      if (!point || point->size() != 3) entry.fail(array->get(i), path, "expected [x, y, z]");
      Vec3 p;
      for (int axis = 0; axis < 3; ++axis) {
        p[axis] = entry.number_of(*point->get(static_cast<std::size_t>(axis)), path, any_number());
      }
      points.push_back(p);
    }
    return points;
  }

  /// Size keys of a generator: radius_min/radius_max, or radius (monodisperse), or bins.
  SizeRange parse_sizes(const TableReader& entry) const {
    const std::string law =
        entry.optional_choice("distribution", {"uniform_radius", "uniform_volume_fraction", "monodisperse", "bins"})
            .value_or("uniform_radius");
    const auto refuse = [&](std::initializer_list<std::string_view> keys, const std::string& why) {
      for (const std::string_view key : keys) {
        if (entry.has(key)) entry.fail_key(key, "not used with distribution = \"" + law + "\" (" + why + ")");
      }
    };
    if (law == "monodisperse") {
      refuse({"radius_min", "radius_max", "bins", "bin_fractions"}, "give radius");
      SizeRange sizes;
      sizes.distribution = SizeDistribution::monodisperse;
      sizes.radius_min = sizes.radius_max = entry.number("radius", positive());
      return sizes;
    }
    if (law == "bins") {
      refuse({"radius_min", "radius_max", "radius"}, "give bins = [[diameter, fraction], ...]");
      const toml::node* node = entry.get("bins");
      if (!node) entry.missing("bins", "an array of [diameter, fraction] pairs, e.g. [[0.01, 0.5], [0.02, 0.5]]");
      const auto* array = node->as_array();
      if (!array || array->empty()) entry.fail(node, entry.key_path("bins"), "expected a nonempty array of [diameter, fraction] pairs");
      std::vector<SizeBin> bins;
      double total = 0.0;
      for (std::size_t i = 0; i < array->size(); ++i) {
        const std::string path = entry.key_path("bins") + "[" + std::to_string(i) + "]";
        const auto* pair = array->get(i)->as_array();
        if (!pair || pair->size() != 2) entry.fail(array->get(i), path, "expected [diameter, fraction]");
        SizeBin bin;
        bin.diameter = entry.number_of(*pair->get(0), path + "[0]", positive());
        bin.fraction = entry.number_of(*pair->get(1), path + "[1]", non_negative());
        total += bin.fraction;
        bins.push_back(bin);
      }
      if (!(total > 0.0)) entry.fail(node, entry.key_path("bins"), "expected fractions summing to more than 0");
      const bool by_volume = entry.optional_choice("bin_fractions", {"volume", "number"}).value_or("volume") == "volume";
      return size_bins(std::move(bins), by_volume);
    }
    refuse({"radius", "bins", "bin_fractions"}, "give radius_min and radius_max");
    SizeRange sizes;
    sizes.radius_min = entry.number("radius_min", positive());
    sizes.radius_max = entry.number("radius_max", positive());
    if (sizes.radius_max < sizes.radius_min) {
      entry.fail_key("radius_max", "expected radius_max >= radius_min (" + show(sizes.radius_min) +
                                       "), got " + show(sizes.radius_max));
    }
    sizes.distribution =
        law == "uniform_radius" ? SizeDistribution::uniform_radius : SizeDistribution::uniform_volume_fraction;
    return sizes;
  }

  /// Refuses (on `entry`'s `key`) a generator whose `count` grains, with the scene's grains so
  /// far, would not fit in this process's memory (simulation/memory_estimate.hpp): checked
  /// before the grains are made, so a scene of 10^8 grains fails at once with the estimate.
  void check_memory(const TableReader& entry, std::string_view key, std::uint64_t count, bool polyhedra) const {
    std::uint64_t spheres = 0, polyhedron_grains = 0;
    for (const GrainSpec& grain : grains_) ++(grain.polyhedron ? polyhedron_grains : spheres);
    (polyhedra ? polyhedron_grains : spheres) += count;
    const std::string shortfall = memory_shortfall(spheres, polyhedron_grains);
    if (!shortfall.empty()) entry.fail_key(key, shortfall);
  }

  void parse_generators() {
    const auto entries = root_.tables("generators");
    const auto max_count = static_cast<std::int64_t>(max_packed_grains);
    for (std::size_t g = 0; g < entries.size(); ++g) {
      const TableReader& entry = entries[g];
      const std::string type = entry.choice("type", {"box_deposit", "cubic_grid", "sphere_cloud"});
      const std::string shape = entry.optional_choice("shape", {"sphere", "polyhedron", "mix"}).value_or("sphere");
      std::vector<std::string_view> allowed = {"type",     "shape",     "distribution", "radius_min", "radius_max",
                                               "radius",   "bins",      "bin_fractions", "material",  "velocity"};
      if (shape != "sphere") {
        allowed.insert(allowed.end(), {"min_vertices", "max_vertices", "min_elongation", "min_platyness"});
      }
      if (shape == "mix") allowed.push_back("polyhedron_fraction");
      if (type == "box_deposit") {
        allowed.insert(allowed.end(), {"count", "region_min", "region_max", "cell_size"});
      } else if (type == "cubic_grid") {
        allowed.insert(allowed.end(), {"cells_per_side", "cell_size", "center"});
      } else {
        allowed.insert(allowed.end(), {"count", "center", "cloud_radius", "volume_fraction"});
      }
      entry.allow_only(allowed, "for a generator of type = \"" + type + "\" and shape = \"" + shape + "\"");
      std::vector<PackedGrain> packed;
      const std::uint64_t seed = derive_seed(scene_.run.seed, g);
      try {
        if (type == "box_deposit") {
          BoxDepositOptions options;
          options.count = static_cast<std::uint64_t>(entry.integer("count", 1, max_count));
          check_memory(entry, "count", options.count, shape != "sphere");
          options.sizes = parse_sizes(entry);
          options.region_min = entry.vec3("region_min", coordinate());
          options.region_max = entry.vec3("region_max", coordinate());
          for (int axis = 0; axis < 3; ++axis) {
            if (!(options.region_max[axis] > options.region_min[axis])) {
              entry.fail_key("region_max", "expected region_max > region_min on every axis, got " +
                                               show_vec3(options.region_max) + " vs " + show_vec3(options.region_min));
            }
          }
          options.cell_size = entry.number_or("cell_size", 0.0, length_or_zero());
          const double cell = box_deposit_cell_size(options);
          if (cell < 2.0 * options.sizes.radius_max) {
            entry.fail_key("cell_size", "expected 0 (automatic) or a cell >= 2 radius_max (" +
                                            show(2.0 * options.sizes.radius_max) + " m), got " + show(cell));
          }
          const std::uint64_t capacity = box_deposit_capacity(options);
          if (options.count > capacity) {
            entry.fail_key("count", "the region is too small: it holds at most " + std::to_string(capacity) +
                                        " grains on a grid of cell " + show(cell) + " m (expected count <= " +
                                        std::to_string(capacity) + ", got " + std::to_string(options.count) +
                                        "); enlarge region_min/region_max or reduce radius_max or cell_size");
          }
          packed = box_deposit(options, seed);
        } else if (type == "cubic_grid") {
          CubicGridOptions options;
          options.cells_per_side = static_cast<std::uint64_t>(entry.integer("cells_per_side", 1, 464));
          check_memory(entry, "cells_per_side", options.cells_per_side * options.cells_per_side * options.cells_per_side,
                       shape != "sphere");
          options.sizes = parse_sizes(entry);
          options.cell_size = entry.number_or("cell_size", 0.0, length_or_zero());
          if (options.cell_size > 0.0 && options.cell_size < 2.0 * options.sizes.radius_max) {
            entry.fail_key("cell_size", "expected 0 (automatic: 2 radius_max) or a cell >= 2 radius_max (" +
                                            show(2.0 * options.sizes.radius_max) + " m), got " +
                                            show(options.cell_size));
          }
          options.center = entry.optional_vector<3>("center", coordinate()).value_or(Vec3::Zero());
          packed = cubic_grid_packing(options, seed);
        } else {
          SphereCloudOptions options;
          options.count = static_cast<std::uint64_t>(entry.integer("count", 1, max_count));
          check_memory(entry, "count", options.count, shape != "sphere");
          options.sizes = parse_sizes(entry);
          options.center = entry.optional_vector<3>("center", coordinate()).value_or(Vec3::Zero());
          if (entry.has("cloud_radius") == entry.has("volume_fraction")) {
            entry.fail_table("expected exactly one of cloud_radius (m) and volume_fraction (grain volume / ball volume)");
          }
          if (entry.has("cloud_radius")) {
            options.radius = entry.number("cloud_radius", length());
            if (options.radius < options.sizes.radius_max) {
              entry.fail_key("cloud_radius", "expected a cloud radius >= the largest grain radius (" +
                                                 show(options.sizes.radius_max) + " m), got " + show(options.radius));
            }
          } else {
            options.radius = sphere_cloud_radius(options.count, options.sizes,
                                                 entry.number("volume_fraction", open(0.0, 1.0)));
            options.radius = std::max(options.radius, options.sizes.radius_max);
          }
          packed = sphere_cloud(options, seed);
        }
      } catch (const PackingError& error) {
        // Options are checked above; anything left is still reported against the generator.
        entry.fail_table(error.what());
      }
      const int material = material_of(entry);
      const Vec3 velocity = entry.vec3_or("velocity", Vec3::Zero());
      RandomPolyhedronOptions polyhedron_options;
      double polyhedron_fraction = shape == "polyhedron" ? 1.0 : 0.0;
      if (shape != "sphere") polyhedron_options = parse_random_polyhedron_options(entry);
      if (shape == "mix") polyhedron_fraction = entry.number("polyhedron_fraction", closed(0.0, 1.0));
      // Per grain, its own seed: whether it is a polyhedron, its shape and its orientation do not
      // depend on the other grains, so grains can be made in parallel and in any order.
      const std::uint64_t shape_stream = derive_seed(seed, 0x5348415045ULL);
      std::vector<GrainSpec> made(packed.size());
      std::string failure;
#pragma omp parallel for schedule(dynamic, 64) if (shape != "sphere" && packed.size() > 256)
      for (std::size_t k = 0; k < packed.size(); ++k) {
        GrainSpec& grain = made[k];
        grain.radius = packed[k].radius;
        grain.position = packed[k].position;
        grain.velocity = velocity;
        grain.material = material;
        grain.origin.generator = static_cast<int>(g);
        grain.origin.ordinal = k;
        grain.origin.node = entry.anchor();
        if (polyhedron_fraction <= 0.0) continue;
        const std::uint64_t grain_seed = derive_seed(shape_stream, k);
        std::mt19937_64 rng(grain_seed);
        if (uniform_01(rng) >= polyhedron_fraction) continue;
        try {
          PlacedPolyhedron placed = random_polyhedron_in_ball(packed[k], polyhedron_options, rng());
          grain.position = placed.position;
          grain.orientation = placed.orientation;
          grain.radius = placed.shape.bounding_radius;
          grain.polyhedron = std::make_shared<const ConvexPolyhedron>(std::move(placed.shape));
        } catch (const std::exception& error) {
#pragma omp critical(rubble_scene_polyhedra)
          if (failure.empty()) failure = "grain " + std::to_string(k) + ": cannot make its polyhedron: " + error.what();
        }
      }
      if (!failure.empty()) entry.fail_table(failure);
      for (const GrainSpec& grain : made) add_grain(grain);
    }
  }

  void add_grain(const GrainSpec& grain) {
    if (grains_.size() >= max_packed_grains) {
      root_.fail(grain.origin.node, grain_key(grain.origin),
                 "too many grains: expected at most " + std::to_string(max_packed_grains) + " in a scene");
    }
    grains_.push_back(grain);
  }

  /// Every pair of materials that can touch (grain-grain, grain-wall) needs a law, unless a
  /// [default_contact_law] covers the missing ones.
  void check_contact_law_coverage() const {
    if (default_law_) return;
    const int n = static_cast<int>(scene_.model.materials.size());
    std::vector<bool> grain_material(static_cast<std::size_t>(n), false);
    std::vector<bool> wall_material(static_cast<std::size_t>(n), false);
    for (const GrainSpec& g : grains_) grain_material[static_cast<std::size_t>(g.material)] = true;
    for (const WallSpec& w : walls_) wall_material[static_cast<std::size_t>(w.material)] = true;
    for (int a = 0; a < n; ++a) {
      if (!grain_material[static_cast<std::size_t>(a)]) continue;
      for (int b = 0; b < n; ++b) {
        if (!grain_material[static_cast<std::size_t>(b)] && !wall_material[static_cast<std::size_t>(b)]) continue;
        if (law_defined_[static_cast<std::size_t>(a * n + b)]) continue;
        const std::string& name_a = scene_.model.materials[static_cast<std::size_t>(a)].name;
        const std::string& name_b = scene_.model.materials[static_cast<std::size_t>(b)].name;
        root_.fail(root_.get("contact_laws"), "contact_laws",
                   "no contact law for materials \"" + name_a + "\" and \"" + name_b +
                       "\", which can touch: expected a [[contact_laws]] entry with materials = [\"" + name_a +
                       "\", \"" + name_b + "\"] (or a [default_contact_law])");
      }
    }
  }

  /// Two plane walls facing away from each other (normals opposite) leave no room between them.
  /// (With grains present, any other empty intersection of half-spaces is caught by the grain check.)
  void check_walls_have_an_inside() const {
    for (std::size_t i = 0; i < walls_.size(); ++i) {
      if (!walls_[i].is_plane) continue;
      for (std::size_t j = i + 1; j < walls_.size(); ++j) {
        if (!walls_[j].is_plane) continue;
        const Vec3& n = walls_[i].normal;
        if (n.dot(walls_[j].normal) > -1.0 + 1e-12) continue;
        // Inside of i: n.(x - p_i) >= 0; inside of j: n.(x - p_j) <= 0 (its normal is -n).
        const double width = n.dot(walls_[j].position - walls_[i].position);
        if (width <= 0.0) {
          root_.fail(walls_[j].node, walls_[j].path,
                     "this plane and " + walls_[i].path + " face away from each other with no space between them (" +
                         "distance " + show_short(width) +
                         " m along the normal): expected their normals to point into a common inside");
        }
      }
    }
  }

  void check_grains_inside_walls() const {
    for (const WallSpec& wall : walls_) {
      const Mat3 to_body = wall.orientation.toRotationMatrix().transpose();
      for (const GrainSpec& grain : grains_) {
        const double tolerance = allowed_initial_overlap * grain.radius;
        if (grain.polyhedron) {
          // A polyhedron is checked by its vertices: none may be behind a plane or inside a box.
          const Mat3 rotation = grain.orientation.toRotationMatrix();
          for (const Vec3& vertex : grain.polyhedron->vertices) {
            const Vec3 x = grain.position + rotation * vertex;
            const bool bad = wall.is_plane
                                 ? wall.normal.dot(x - wall.position) < -tolerance
                                 : ((to_body * (x - wall.position)).cwiseAbs() - wall.half_extents).maxCoeff() < -tolerance;
            if (bad) {
              root_.fail(grain.origin.node, grain_key(grain.origin),
                         grain_label(grain.origin) + " (a polyhedron centred at " + show_vec3(grain.position) +
                             ") has a vertex at " + show_vec3(x) + (wall.is_plane ? " behind plane wall " : " inside box wall ") +
                             wall.path + ": expected every grain entirely on the inner side of the walls");
            }
          }
          continue;
        }
        if (wall.is_plane) {
          const double distance = wall.normal.dot(grain.position - wall.position);
          if (distance < grain.radius - tolerance) {
            const std::string where = distance < 0.0 ? "has its centre behind" : "crosses";
            root_.fail(grain.origin.node, grain_key(grain.origin),
                       grain_label(grain.origin) + " at " + show_vec3(grain.position) + " (radius " +
                           show_short(grain.radius) + " m) " + where + " plane wall " + wall.path +
                           " (signed distance " + show_short(distance) +
                           " m): expected every grain entirely on the side its normal points to");
          }
        } else {
          const Vec3 local = to_body * (grain.position - wall.position);
          const Vec3 outside = (local.cwiseAbs() - wall.half_extents).cwiseMax(0.0);
          if (outside.norm() < grain.radius - tolerance) {
            root_.fail(grain.origin.node, grain_key(grain.origin),
                       grain_label(grain.origin) + " at " + show_vec3(grain.position) + " (radius " +
                           show_short(grain.radius) + " m) overlaps box wall " + wall.path +
                           ": expected grains outside box walls");
          }
        }
      }
    }
  }

  /// Grid search (cell = largest diameter) for pairs of grains overlapping by more than the
  /// allowed fraction of the smaller radius: O(N log N), fine for the largest scenes.
  void check_grains_do_not_overlap() const {
    double radius_max = 0.0;
    for (const GrainSpec& g : grains_) radius_max = std::max(radius_max, g.radius);
    const double cell = 2.0 * radius_max;
    struct Entry {
      std::array<std::int64_t, 3> cell;
      std::size_t grain;
    };
    std::vector<Entry> entries(grains_.size());
    for (std::size_t i = 0; i < grains_.size(); ++i) {
      for (int axis = 0; axis < 3; ++axis) {
        const double c = std::floor(grains_[i].position[axis] / cell);
        entries[i].cell[static_cast<std::size_t>(axis)] = static_cast<std::int64_t>(std::clamp(c, -1e15, 1e15));
      }
      entries[i].grain = i;
    }
    const auto less = [](const Entry& a, const Entry& b) {
      return a.cell != b.cell ? a.cell < b.cell : a.grain < b.grain;
    };
    std::sort(entries.begin(), entries.end(), less);
    for (const Entry& e : entries) {
      const GrainSpec& a = grains_[e.grain];
      for (std::int64_t dx = -1; dx <= 1; ++dx) {
        for (std::int64_t dy = -1; dy <= 1; ++dy) {
          for (std::int64_t dz = -1; dz <= 1; ++dz) {
            const Entry key{{e.cell[0] + dx, e.cell[1] + dy, e.cell[2] + dz}, 0};
            auto it = std::lower_bound(entries.begin(), entries.end(), key, less);
            for (; it != entries.end() && it->cell == key.cell; ++it) {
              if (it->grain <= e.grain) continue;
              const GrainSpec& b = grains_[it->grain];
              // Polyhedra: their bounding spheres may overlap without the solids touching, and
              // generators never make overlapping grains, so only sphere pairs are checked.
              if (a.polyhedron || b.polyhedron) continue;
              const double overlap = a.radius + b.radius - (a.position - b.position).norm();
              if (overlap > allowed_initial_overlap * std::min(a.radius, b.radius)) {
                root_.fail(b.origin.node, grain_key(b.origin),
                           grain_label(b.origin) + " overlaps " + grain_name(a.origin) + " by " + show_short(overlap) +
                               " m: expected grains not to interpenetrate at the start (at most " +
                               show(100 * allowed_initial_overlap) + "% of the smaller radius)");
              }
            }
          }
        }
      }
    }
  }

  /// Grains first (bodies then generators, in file order), then walls.
  void build() {
    Model& model = scene_.model;
    State& state = scene_.state;
    for (GrainSpec& g : grains_) {
      if (g.polyhedron) {
        add_polyhedron_grain(model, *g.polyhedron, g.material);
        // The model holds its own copy: drop the parser's at once, so that the next copy reuses
        // its memory and a scene never holds every shape twice (bench/RESULTS.md, memory per grain).
        g.polyhedron.reset();
      } else {
        add_sphere(model, g.radius, g.material);
      }
    }
    for (const WallSpec& w : walls_) {
      if (w.is_plane) {
        add_plane_wall(model, w.normal, w.material);
      } else {
        add_box_wall(model, w.half_extents, w.material);
      }
    }
    state.resize(model.body_count());
    for (std::size_t i = 0; i < grains_.size(); ++i) {
      state.position[i] = grains_[i].position;
      state.orientation[i] = grains_[i].orientation;
      state.velocity[i] = grains_[i].velocity;
      state.angular_velocity[i] = grains_[i].angular_velocity;
    }
    for (std::size_t k = 0; k < walls_.size(); ++k) {
      state.position[grains_.size() + k] = walls_[k].position;
      state.orientation[grains_.size() + k] = walls_[k].orientation;
    }
    for (std::size_t i = 0; i < grains_.size(); ++i) {
      if (grains_[i].motion >= 0) drive_body(model, static_cast<int>(i), grain_motions_[static_cast<std::size_t>(grains_[i].motion)]);
    }
    for (std::size_t k = 0; k < walls_.size(); ++k) {
      if (walls_[k].motion) drive_body(model, static_cast<int>(grains_.size() + k), *walls_[k].motion);
    }
    set_prescribed_velocities(model, state);
    if (const auto k = apply_initial_conditions(model, scene_.initial_conditions, state)) {
      root_.fail(condition_nodes_[*k], "initial_conditions[" + std::to_string(*k) + "]",
                 "selects no grain (no free grain of its material has its centre in its region)");
    }
  }

  const std::string& file_;
  TableReader root_;
  Scene scene_;
  std::map<std::string, int> material_ids_;
  std::optional<ContactLaw> default_law_;
  std::vector<bool> law_defined_;
  std::vector<WallSpec> walls_;
  std::vector<GrainSpec> grains_;
  std::vector<PrescribedMotion> grain_motions_;     ///< of the driven [[bodies]]
  std::vector<const toml::node*> condition_nodes_;  ///< of the [[initial_conditions]] entries
};

// --- writing ---

std::string toml_string(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    switch (c) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\n': out += "\\n"; break;
      case '\t': out += "\\t"; break;
      case '\r': out += "\\r"; break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          char buffer[8];
          std::snprintf(buffer, sizeof buffer, "\\u%04x", static_cast<unsigned>(c));
          out += buffer;
        } else {
          out += c;
        }
    }
  }
  return out + "\"";
}

/// The keys of a driven body's prescribed motion (a constant one as velocity and
/// angular_velocity, a table as motion = [[t, vx, vy, vz, wx, wy, wz], ...]), or of a free
/// grain's velocities; each line ends with a newline.
std::string motion_keys(const Model& model, const State& state, std::size_t body) {
  std::string out;
  if (model.is_driven(body) && model.is_grain(body)) out += "driven = true\n";
  if (!model.is_driven(body) || model.prescribed_motions[static_cast<std::size_t>(model.motion_of_body[body])].time.size() == 1) {
    const RigidVelocity v = model.is_driven(body) ? model.driven_velocity(body, state.time)
                                                  : RigidVelocity{state.velocity[body], state.angular_velocity[body]};
    if (!model.is_grain(body) && v.linear == Vec3::Zero() && v.angular == Vec3::Zero()) return out;
    return out + "velocity = " + format_vec3(v.linear) + "\nangular_velocity = " + format_vec3(v.angular) + "\n";
  }
  const PrescribedMotion& motion = model.prescribed_motions[static_cast<std::size_t>(model.motion_of_body[body])];
  out += "motion = [";
  for (std::size_t k = 0; k < motion.time.size(); ++k) {
    const Vec3& v = motion.velocity[k];
    const Vec3& w = motion.angular_velocity[k];
    out += (k ? ",\n  [" : "\n  [") + format_number(motion.time[k]);
    for (int i = 0; i < 3; ++i) out += ", " + format_number(v[i]);
    for (int i = 0; i < 3; ++i) out += ", " + format_number(w[i]);
    out += "]";
  }
  return out + "\n]\n";
}

std::string toml_quaternion(const Quat& q) {
  return "[" + format_number(q.w()) + ", " + format_number(q.x()) + ", " + format_number(q.y()) + ", " +
         format_number(q.z()) + "]";
}

}  // namespace

Scene parse_scene(std::string_view toml_text, const std::string& source_name) {
  toml::table root;
  try {
    root = toml::parse(toml_text, source_name);
  } catch (const toml::parse_error& error) {
    throw SceneError(source_name, static_cast<int>(error.source().begin.line), "",
                     "TOML syntax error: " + std::string(error.description()));
  }
  std::string stem = std::filesystem::path(source_name).stem().string();
  if (stem.empty()) stem = "scene";
  return SceneParser(source_name, root).parse(stem);
}

Scene load_scene_file(const std::filesystem::path& path) {
  const std::string name = path.string();
  std::string text;
  try {
    // Regular files of at most 256 MiB (core/input_file.hpp): /dev/zero or a FIFO is refused.
    text = read_input_file(path, max_scene_file_bytes, "scene file");
  } catch (const InputFileError& e) {
    throw SceneError(name, 0, "", e.reason);
  }
  return parse_scene(text, name);
}

std::string default_scene_toml(DefaultScene variant) {
  if (variant == DefaultScene::polyhedra) {
    // The same accretion with the paper's random polyhedra (10-70 vertices, elongation and
    // platyness in [0.5, 1], circumscribed diameter 7.5-10 m): about 90 s of CPU to rest.
    std::string text = default_scene_toml(DefaultScene::spheres);
    auto replace = [&text](const std::string& from, const std::string& to) {
      const auto at = text.find(from);
      if (at != std::string::npos) text.replace(at, from.size(), to);
    };
    replace("the built-in default scene (`rubble run` without a scene file).",
            "the built-in default scene's polyhedra variant (`rubble run --default-scene polyhedra`).");
    replace("# The accretion study (the LMGC90 accretion paper): 10^3 spheres of diameter 7.5-10 m,",
            "# The accretion study (the LMGC90 accretion paper): 10^3 random convex polyhedra (CGAL hulls of 10-70 points on a\n"
            "# sphere, elongation and platyness in [0.5, 1]) of circumscribed diameter 7.5-10 m,");
    replace("name = \"accretion-1000\"", "name = \"accretion-1000-polyhedra\"");
    replace("directory = \"accretion-1000-output\"", "directory = \"accretion-1000-polyhedra-output\"");
    replace("type = \"cubic_grid\"\n", "type = \"cubic_grid\"\nshape = \"polyhedron\"\n");
    return text;
  }
  // The accretion study's smallest classic case (the LMGC90 accretion paper) run
  // to rest: about 3000 steps, a minute or two of CPU on 2 cores (examples/README.md). The number
  // of grains (cells_per_side^3) and the rest criterion are the knobs that set the run time.
  return R"(# rubble scene file: the built-in default scene (`rubble run` without a scene file).
# The accretion study (the LMGC90 accretion paper): 10^3 spheres of diameter 7.5-10 m, uniform in volume fraction,
# one per cell of a cubic grid of mesh d_max = 10 m, at rest, collapse under their own gravity
# (Barnes-Hut tree) into a rubble pile; no friction, no restitution. The run stops when the
# grains are at rest. Reference: docs/scene-file.md. SI units throughout.
name = "accretion-1000"
seed = 1

[time]
dt = "auto"                    # 1% of d_min over the free-fall velocity sqrt(2GM/R): 1.4 s here
end_time = 12000.0             # s, the latest end (7 characteristic times 1/sqrt(G rho))
until = "rest"                 # stop earlier, as soon as the grains are at rest:
rest_speed = "auto"            # 99% of the grains slower than 5% of v_ff (|v| + |w| r) ...
rest_duration = "auto"         # ... while Z and the contacts hold still, for 1/sqrt(G rho)

[gravity]
type = "tree"
G = 6.674e-11
theta = 0.5
order = 2

[output]
directory = "accretion-1000-output"
snapshot_interval = 60.0   # s of simulated time between snapshots
progress_interval = 5.0    # s of wall time between progress lines

[[materials]]
name = "regolith"
density = 5164.0   # kg/m^3, as printed in the paper

[[contact_laws]]
materials = ["regolith", "regolith"]
friction = 0.0
restitution = 0.0

[[generators]]
type = "cubic_grid"
cells_per_side = 10
radius_min = 3.75
radius_max = 5.0
distribution = "uniform_volume_fraction"
)";
}

Scene default_scene(DefaultScene variant) { return parse_scene(default_scene_toml(variant), "<default scene>"); }

std::string scene_to_toml(const Scene& scene) {
  const Model& model = scene.model;
  const State& state = scene.state;
  const RunOptions& run = scene.run;
  std::ostringstream out;
  out << "# rubble scene file (written by rubble). Reference: docs/scene-file.md\n";
  out << "name = " << toml_string(scene.name) << "\n";
  out << "seed = " << static_cast<std::int64_t>(run.seed & 0x7FFFFFFFFFFFFFFFULL) << "\n\n";

  out << "[time]\n";
  out << "dt = " << (run.automatic_time_step ? std::string("\"auto\"") : format_number(run.step.integrator.time_step))
      << "\n";
  out << "theta = " << format_number(run.step.integrator.theta) << "\n";
  out << "end_time = " << format_number(run.end_time) << "\n";
  if (run.until_rest) {
    out << "until = \"rest\"\n";
    out << "rest_speed = " << (run.automatic_rest_speed ? std::string("\"auto\"") : format_number(run.rest.speed))
        << "\n";
    out << "rest_quantile = " << format_number(run.rest.quantile) << "\n";
    out << "rest_coordination_change = "
        << (run.automatic_rest_coordination_change ? std::string("\"auto\"") : format_number(run.rest.coordination_change))
        << "\n";
    out << "rest_contact_change = " << format_number(run.rest.contact_change) << "\n";
    out << "rest_duration = "
        << (run.automatic_rest_duration ? std::string("\"auto\"") : format_number(run.rest.duration)) << "\n";
  }
  out << "\n";

  const SolverOptions& solver = run.step.solver;
  out << "[solver]\n";
  out << "tolerance = " << format_number(solver.tolerance) << "\n";
  out << "max_iterations = " << solver.max_iterations << "\n";
  out << "relaxation = " << format_number(solver.relaxation) << "\n";
  out << "warm_start = " << (solver.warm_start ? "true" : "false") << "\n";
  out << "penetration_correction = " << format_number(solver.overlap_recovery.fraction) << "\n";
  out << "max_correction_velocity = " << format_number(solver.overlap_recovery.max_velocity) << "\n";
  out << "allowed_overlap = " << format_number(solver.overlap_recovery.allowed_overlap) << "\n";
  out << "polish_after = " << solver.polish_after << "\n";
  out << "polish_iterations = " << solver.polish_iterations << "\n";
  out << "polish_max_contacts = " << solver.polish_max_contacts << "\n";
  out << "polish_attempts_per_step = " << solver.polish_attempts_per_step << "\n";
  out << "block_count = " << solver.block_count << "\n\n";

  out << "[detection]\n";
  out << "alert_distance = " << format_number(run.step.detection.alert_distance) << "\n";
  out << "pair_list_margin = "
      << (run.step.detection.pair_list_margin < 0.0 ? std::string("\"auto\"")
                                                     : format_number(run.step.detection.pair_list_margin))
      << "\n\n";

  const GravitySettings& gravity = run.step.gravity;
  out << "[gravity]\n";
  switch (gravity.kind) {
    case GravitySettings::Kind::none: out << "type = \"none\"\n\n"; break;
    case GravitySettings::Kind::uniform:
      out << "type = \"uniform\"\nacceleration = " << format_vec3(gravity.acceleration) << "\n\n";
      break;
    case GravitySettings::Kind::self: {
      const gravity::GravityOptions& self = gravity.self_gravity;
      const bool tree = self.method == gravity::Method::tree;
      out << "type = \"" << (tree ? "tree" : "direct") << "\"\n";
      out << "G = " << format_number(self.G) << "\n";
      out << "softening = "
          << format_number(self.softening.kind == gravity::Softening::Kind::plummer ? self.softening.length : 0.0)
          << "\n";
      if (tree) {
        out << "theta = " << format_number(self.theta) << "\n";
        out << "order = " << self.order << "\n";
        out << "leaf_size = " << self.leaf_size << "\n";
        out << "group_size = " << self.group_size << "\n";
      }
      if (self.backend != gravity::Backend::cpu) out << "backend = \"" << gravity::to_string(self.backend) << "\"\n";
      if (gravity.evaluate_every != 1) out << "evaluate_every = " << gravity.evaluate_every << "\n";
      out << "\n";
      break;
    }
    case GravitySettings::Kind::central: {
      const CentralField& central = gravity.central;
      out << "type = \"central\"\n";
      out << "centre = " << format_vec3(central.centre) << "\n";
      out << "mass = " << format_number(central.mass) << "\n";
      out << "G = " << format_number(central.G) << "\n";
      out << "softening = " << format_number(central.softening) << "\n\n";
      break;
    }
  }

  const OutputOptions& output = run.output;
  out << "[output]\n";
  out << "directory = " << toml_string(output.directory) << "\n";
  if (output.snapshot_every_steps > 0) {
    out << "snapshot_every_steps = " << output.snapshot_every_steps << "\n";
  } else {
    out << "snapshot_interval = " << format_number(output.snapshot_interval) << "\n";
  }
  out << "progress_interval = " << format_number(output.progress_interval) << "\n";
  out << "vtk = " << (output.write_vtk ? "true" : "false") << "\n";
  if (output.keep_checkpoint_every > 0) out << "keep_checkpoint_every = " << output.keep_checkpoint_every << "\n";

  for (const Material& material : model.materials) {
    out << "\n[[materials]]\nname = " << toml_string(material.name) << "\ndensity = " << format_number(material.density)
        << "\n";
  }
  const auto material_name = [&](int id) { return toml_string(model.materials[static_cast<std::size_t>(id)].name); };
  const int n = model.contact_laws.material_count;
  for (int a = 0; a < n; ++a) {
    for (int b = a; b < n; ++b) {
      const ContactLaw& law = model.contact_laws.get(a, b);
      out << "\n[[contact_laws]]\nmaterials = [" << material_name(a) << ", " << material_name(b) << "]\n";
      out << "friction = " << format_number(law.friction_coefficient) << "\n";
      out << "restitution = " << format_number(law.normal_restitution) << "\n";
      if (law.tangential_restitution > 0.0) {
        out << "tangential_restitution = " << format_number(law.tangential_restitution) << "\n";
      }
      if (law.cohesion > 0.0) out << "cohesion = " << format_number(law.cohesion) << "\n";
      if (law.work_of_adhesion > 0.0) out << "work_of_adhesion = " << format_number(law.work_of_adhesion) << "\n";
      if (law.rolling_friction > 0.0) out << "rolling_friction = " << format_number(law.rolling_friction) << "\n";
      if (law.twisting_friction > 0.0) out << "twisting_friction = " << format_number(law.twisting_friction) << "\n";
    }
  }

  for (std::size_t body = 0; body < model.body_count(); ++body) {
    const auto index = static_cast<std::size_t>(model.shape_index[body]);
    switch (model.shape_kind[body]) {
      case ShapeKind::plane:
        out << "\n[[walls]]\ntype = \"plane\"\npoint = " << format_vec3(state.position[body])
            << "\nnormal = " << format_vec3(state.orientation[body] * model.planes[index].normal) << "\n";
        out << motion_keys(model, state, body);
        break;
      case ShapeKind::box:
        out << "\n[[walls]]\ntype = \"box\"\ncenter = " << format_vec3(state.position[body])
            << "\nhalf_extents = " << format_vec3(model.boxes[index].half_extents) << "\n";
        if (state.orientation[body].coeffs() != Quat::Identity().coeffs()) {
          out << "orientation = " << toml_quaternion(state.orientation[body]) << "\n";
        }
        out << motion_keys(model, state, body);
        break;
      case ShapeKind::sphere:
        out << "\n[[bodies]]\nshape = \"sphere\"\nradius = " << format_number(model.spheres[index].radius)
            << "\nposition = " << format_vec3(state.position[body]);
        if (state.orientation[body].coeffs() != Quat::Identity().coeffs()) {
          out << "\norientation = " << toml_quaternion(state.orientation[body]);
        }
        out << "\n" << motion_keys(model, state, body);
        break;
      case ShapeKind::polyhedron: {
        // Body-frame vertices and faces (the shape's principal frame, centroid at the origin), so
        // position and orientation are the state's. Merged faces may be bent by up to the
        // generator's merge angle, hence the convexity tolerance.
        const ConvexPolyhedron& shape = model.polyhedra[index];
        out << "\n[[bodies]]\nshape = \"polyhedron\"\nposition = " << format_vec3(state.position[body])
            << "\norientation = " << toml_quaternion(state.orientation[body]) << "\n"
            << motion_keys(model, state, body) << "convexity_tolerance = 0.05\nvertices = [";
        for (std::size_t v = 0; v < shape.vertices.size(); ++v) out << (v ? ", " : "") << format_vec3(shape.vertices[v]);
        out << "]\nfaces = [";
        for (std::size_t f = 0; f < shape.faces.size(); ++f) {
          out << (f ? ", [" : "[");
          for (std::size_t k = 0; k < shape.faces[f].size(); ++k) out << (k ? ", " : "") << shape.faces[f][k];
          out << "]";
        }
        out << "]\n";
        break;
      }
    }
    out << "material = " << material_name(model.material[body]) << "\n";
  }
  return out.str();
}

}  // namespace rubble
