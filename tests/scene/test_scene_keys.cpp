// Tests of simulation/scene_keys.hpp: the key tables of [solver] and [detection] are the ones
// docs/scene-file.md documents (same keys, same order, same kind of value), and every key of the
// tables reads, round-trips through scene_to_toml, and is refused out of its range.
#include "simulation/scene_keys.hpp"
#include "simulation/scene_file.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace rubble {
namespace {

/// One row of a key table in docs/scene-file.md: | `key` | type | default | range | meaning |.
struct DocRow {
  std::string key;
  std::string type;
};

/// The rows of the key table under the heading that starts with `heading`, up to the next heading.
std::vector<DocRow> doc_rows(const std::string& heading) {
  std::ifstream in(RUBBLE_SCENE_FILE_DOC);
  EXPECT_TRUE(in) << "cannot read " << RUBBLE_SCENE_FILE_DOC;
  std::vector<DocRow> rows;
  std::string line;
  bool inside = false;
  while (std::getline(in, line)) {
    if (line.rfind("## ", 0) == 0) {
      if (inside) break;
      inside = line.rfind(heading, 0) == 0;
      continue;
    }
    if (!inside || line.rfind("| `", 0) != 0) continue;
    const std::size_t end = line.find('`', 3);
    const std::size_t type_begin = line.find('|', end) + 1;
    const std::size_t type_end = line.find('|', type_begin);
    std::string type = line.substr(type_begin, type_end - type_begin);
    type.erase(0, type.find_first_not_of(' '));
    rows.push_back({line.substr(3, end - 3), type});
  }
  return rows;
}

/// The doc's word for the kind of value an option holds.
std::string doc_type(const scene_detail::OptionRef& option) {
  if (std::holds_alternative<double*>(option)) return "number";
  if (std::holds_alternative<bool*>(option)) return "boolean";
  return "integer";
}

template <class Options>
void expect_doc_matches(const std::string& heading, const std::vector<scene_detail::SectionKey<Options>>& keys) {
  const std::vector<DocRow> rows = doc_rows(heading);
  ASSERT_EQ(rows.size(), keys.size()) << "keys in docs/scene-file.md " << heading << " vs the code's table";
  Options options;
  for (std::size_t i = 0; i < keys.size(); ++i) {
    EXPECT_EQ(rows[i].key, keys[i].name) << heading << " row " << i;
    EXPECT_EQ(rows[i].type.rfind(doc_type(keys[i].option(options)), 0), 0u)
        << heading << " `" << keys[i].name << "`: documented as \"" << rows[i].type << "\"";
    EXPECT_EQ(rows[i].type.find("auto") != std::string::npos, keys[i].auto_when_negative)
        << heading << " `" << keys[i].name << "`: \"auto\" documented or accepted but not both";
    EXPECT_FALSE(keys[i].doc.empty()) << keys[i].name;
  }
}

TEST(SceneKeys, SolverTableMatchesTheDocs) { expect_doc_matches("## `[solver]`", scene_detail::solver_keys()); }

TEST(SceneKeys, DetectionTableMatchesTheDocs) {
  expect_doc_matches("## `[detection]`", scene_detail::detection_keys());
}

constexpr const char* one_grain = R"(
[time]
dt = 1e-3
end_time = 0.01
[[materials]]
name = "rock"
density = 2500.0
[[contact_laws]]
materials = ["rock", "rock"]
friction = 0.5
[[bodies]]
shape = "sphere"
radius = 0.1
position = [0.0, 0.0, 0.0]
)";

/// A value inside the key's range, different from the default where the range allows.
std::string inside_value(const scene_detail::OptionRef& option, const scene_detail::Range& range,
                         std::int64_t high, double& expected) {
  if (std::holds_alternative<bool*>(option)) {
    expected = *std::get<bool*>(option) ? 0.0 : 1.0;
    return expected > 0.0 ? "true" : "false";
  }
  if (std::holds_alternative<double*>(option)) {
    expected = range.high < scene_detail::infinity ? 0.5 * (range.low + range.high) : range.low + 0.375;
    return scene_detail::format_number(expected);
  }
  expected = static_cast<double>(high);
  return std::to_string(high);
}

template <class Options>
void expect_keys_read_and_written(const std::string& section, const std::vector<scene_detail::SectionKey<Options>>& keys,
                                  Options StepOptions::*member) {
  for (const auto& key : keys) {
    Options defaults;
    double expected = 0.0;
    const std::string value = inside_value(key.option(defaults), key.range, key.high, expected);
    const std::string text = std::string(one_grain) + "[" + section + "]\n" + std::string(key.name) + " = " + value + "\n";
    const Scene scene = parse_scene(text, "keys.toml");
    Options read = scene.run.step.*member;
    const auto option = key.option(read);
    const double got = std::visit([](auto* x) { return static_cast<double>(*x); }, option);
    EXPECT_EQ(got, expected) << section << "." << key.name;
    EXPECT_NE(scene_to_toml(scene).find("\n" + std::string(key.name) + " = " + value + "\n"), std::string::npos)
        << section << "." << key.name << " is not written back";
    const std::string bad = std::string(one_grain) + "[" + section + "]\n" + std::string(key.name) + " = -7\n";
    if (std::holds_alternative<bool*>(option)) continue;
    EXPECT_THROW(parse_scene(bad, "keys.toml"), SceneError) << section << "." << key.name << " = -7";
  }
}

TEST(SceneKeys, EverySolverKeyIsReadWrittenAndChecked) {
  expect_keys_read_and_written("solver", scene_detail::solver_keys(), &StepOptions::solver);
}

TEST(SceneKeys, EveryDetectionKeyIsReadWrittenAndChecked) {
  expect_keys_read_and_written("detection", scene_detail::detection_keys(), &StepOptions::detection);
}

}  // namespace
}  // namespace rubble
