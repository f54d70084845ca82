#include "simulation/scene_reader.hpp"

#include <algorithm>
#include <charconv>
#include <cstdio>

#include "simulation/scene_file.hpp"

namespace rubble::scene_detail {

std::string format_number(double x) {
  if (std::isnan(x)) return "nan";
  if (std::isinf(x)) return x > 0 ? "inf" : "-inf";
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof buffer, x);
  std::string text(buffer, result.ptr);
  if (text.find_first_of(".e") == std::string::npos) text += ".0";
  return text;
}

std::string show(double x) {
  if (std::isnan(x)) return "nan";
  if (std::isinf(x)) return x > 0 ? "inf" : "-inf";
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof buffer, x);
  return std::string(buffer, result.ptr);
}

std::string show_short(double x) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.6g", x);
  return buffer;
}

namespace {

/// "[a, b, c]" from three texts. Appended piece by piece: `"[" + std::string` trips GCC 12's
/// -Wrestrict false positive wherever it is inlined.
std::string bracketed(const std::string& a, const std::string& b, const std::string& c) {
  std::string text = "[";
  text.append(a).append(", ").append(b).append(", ").append(c).append("]");
  return text;
}

}  // namespace

std::string show_vec3(const Vec3& v) { return bracketed(show_short(v.x()), show_short(v.y()), show_short(v.z())); }

std::string format_vec3(const Vec3& v) {
  return bracketed(format_number(v.x()), format_number(v.y()), format_number(v.z()));
}

std::string format_quaternion(const Quat& q) {
  // Appended piece by piece: `"[" + std::string` trips GCC 12's -Wrestrict false positive here.
  std::string text = "[";
  text.append(format_number(q.w())).append(", ").append(format_number(q.x())).append(", ");
  text.append(format_number(q.y())).append(", ").append(format_number(q.z())).append("]");
  return text;
}

std::string toml_string(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\t':
        out += "\\t";
        break;
      case '\r':
        out += "\\r";
        break;
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

std::string Range::describe() const {
  const bool has_low = low > -infinity;
  const bool has_high = high < infinity;
  if (has_low && has_high) {
    return "in " + std::string(low_closed ? "[" : "(") + show(low) + ", " + show(high) + (high_closed ? "]" : ")");
  }
  if (has_low) return std::string(low_closed ? ">= " : "> ") + show(low);
  if (has_high) return std::string(high_closed ? "<= " : "< ") + show(high);
  return "";
}

std::string expected_number(const Range& range) {
  const std::string bounds = range.describe();
  return bounds.empty() ? "a finite number" : "a finite number " + bounds;
}

std::string describe_node(const toml::node& node) {
  switch (node.type()) {
    case toml::node_type::string:
      return "the string \"" + std::string(node.as_string()->get()) + "\"";
    case toml::node_type::integer:
      return std::to_string(node.as_integer()->get());
    case toml::node_type::floating_point:
      return show(node.as_floating_point()->get());
    case toml::node_type::boolean:
      return node.as_boolean()->get() ? "true" : "false";
    case toml::node_type::array:
      return "an array of " + std::to_string(node.as_array()->size()) + " elements";
    case toml::node_type::table:
      return "a table";
    default:
      return "a date/time";
  }
}

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

void TableReader::fail(const toml::node* at, const std::string& key, const std::string& message) const {
  throw SceneError(file_, line_of(at), key, message);
}

void TableReader::allow_only(const std::vector<std::string_view>& allowed, std::string_view context) const {
  for (const auto& [key, node] : table_) {
    const std::string_view name = key.str();
    if (std::find(allowed.begin(), allowed.end(), name) != allowed.end()) continue;
    std::string message = "unknown key";
    if (!context.empty()) message.append(" ").append(context);
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

double TableReader::number_of(const toml::node& node, const std::string& key, const Range& range) const {
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

std::optional<std::int64_t> TableReader::optional_integer(std::string_view key, std::int64_t low,
                                                          std::int64_t high) const {
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

namespace {

/// `one of "a", "b"` for messages about a choice of words.
std::string one_of(std::initializer_list<std::string_view> words) {
  std::string expected = "one of";
  for (std::string_view word : words)
    expected += std::string(word == *words.begin() ? " " : ", ") + "\"" + std::string(word) + "\"";
  return expected;
}

}  // namespace

std::optional<std::string> TableReader::optional_choice(std::string_view key,
                                                        std::initializer_list<std::string_view> words) const {
  const std::string expected = one_of(words);
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

std::string TableReader::choice(std::string_view key, std::initializer_list<std::string_view> words) const {
  const auto value = optional_choice(key, words);
  if (!value) missing(key, one_of(words));
  return *value;
}

Quat TableReader::orientation_or_identity(std::string_view key) const {
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

std::optional<TableReader> TableReader::optional_table(std::string_view key) const {
  const toml::node* node = get(key);
  if (!node) return std::nullopt;
  const auto* table = node->as_table();
  if (!table) fail(node, key_path(key), "expected a table [" + key_path(key) + "], got " + describe_node(*node));
  return TableReader(file_, *table, key_path(key), node);
}

std::vector<TableReader> TableReader::tables(std::string_view key) const {
  std::vector<TableReader> result;
  const toml::node* node = get(key);
  if (!node) return result;
  const auto* array = node->as_array();
  if (!array) {
    fail(node, key_path(key),
         "expected an array of tables ([[" + std::string(key) + "]] entries), got " + describe_node(*node));
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

bool is_auto(const TableReader& table, std::string_view key) {
  const toml::node* node = table.get(key);
  if (!node || !node->is_string()) return false;
  const std::string value(node->as_string()->get());
  if (value != "auto") {
    table.fail(node, table.key_path(key), "expected a finite number or \"auto\", got \"" + value + "\"");
  }
  return true;
}

}  // namespace rubble::scene_detail
