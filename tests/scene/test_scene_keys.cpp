// Tests of simulation/scene_keys.hpp: the key tables of [solver], [detection], [output] and the
// contact laws are the ones docs/scene-file.md documents (same keys, same order, same kind of
// value, "auto" where accepted), and every key of the tables reads, is written back by
// scene_to_toml and is refused out of its range.
#include "simulation/scene_keys.hpp"
#include "simulation/scene_file.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <functional>
#include <string>
#include <vector>

namespace rubble {
namespace {

using scene_detail::OptionRef;
using scene_detail::SectionKey;

/// One row of a key table in docs/scene-file.md: | `key` | type | ... |.
struct DocRow {
  std::string key;
  std::string type;
  bool required = false;  ///< marked **required** in some column
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
    rows.push_back({line.substr(3, end - 3), type, line.find("**required**") != std::string::npos});
  }
  return rows;
}

/// The doc's word for the kind of value an option holds.
std::string doc_type(const OptionRef& option) {
  if (std::holds_alternative<double*>(option)) return "number";
  if (std::holds_alternative<bool*>(option)) return "boolean";
  if (std::holds_alternative<std::string*>(option)) return "string";
  return "integer";
}

/// The doc's table under `heading` lists `before` (keys the table does not hold), then the table's keys.
template <class Options>
void expect_doc_matches(const std::string& heading, const std::vector<SectionKey<Options>>& keys,
                        const std::vector<std::string>& before = {}) {
  const std::vector<DocRow> rows = doc_rows(heading);
  ASSERT_EQ(rows.size(), before.size() + keys.size())
      << "keys in docs/scene-file.md " << heading << " vs the code's table";
  for (std::size_t i = 0; i < before.size(); ++i) EXPECT_EQ(rows[i].key, before[i]) << heading << " row " << i;
  Options options{};
  for (std::size_t i = 0; i < keys.size(); ++i) {
    const DocRow& row = rows[before.size() + i];
    EXPECT_EQ(row.key, keys[i].name) << heading << " row " << before.size() + i;
    EXPECT_EQ(row.type.rfind(doc_type(keys[i].option(options)), 0), 0u)
        << heading << " `" << keys[i].name << "`: documented as \"" << row.type << "\"";
    EXPECT_EQ(row.type.find("auto") != std::string::npos, keys[i].auto_when_negative)
        << heading << " `" << keys[i].name << "`: \"auto\" documented or accepted but not both";
    EXPECT_EQ(row.required, keys[i].required) << heading << " `" << keys[i].name << "`: required in one only";
    EXPECT_FALSE(keys[i].doc.empty()) << keys[i].name;
  }
}

TEST(SceneKeys, SolverTableMatchesTheDocs) { expect_doc_matches("## `[solver]`", scene_detail::solver_keys()); }

TEST(SceneKeys, DetectionTableMatchesTheDocs) {
  expect_doc_matches("## `[detection]`", scene_detail::detection_keys());
}

TEST(SceneKeys, OutputTableMatchesTheDocs) { expect_doc_matches("## `[output]`", scene_detail::output_keys()); }

TEST(SceneKeys, ContactLawTableMatchesTheDocs) {
  expect_doc_matches("## `[[contact_laws]]`", scene_detail::contact_law_keys(), {"materials"});
}

constexpr const char* one_grain = R"(
[time]
dt = 1e-3
end_time = 0.01
[[materials]]
name = "rock"
density = 2500.0
[[bodies]]
shape = "sphere"
radius = 0.1
position = [0.0, 0.0, 0.0]
)";

/// The text scene_to_toml writes for an option's value.
std::string written_value(const OptionRef& option) {
  if (const auto* x = std::get_if<double*>(&option)) return scene_detail::format_number(**x);
  if (const auto* x = std::get_if<bool*>(&option)) return **x ? "true" : "false";
  if (const auto* x = std::get_if<std::string*>(&option)) return scene_detail::toml_string(**x);
  return std::visit(
      [](auto* x) -> std::string {
        if constexpr (std::is_integral_v<std::remove_pointer_t<decltype(x)>>) return std::to_string(*x);
        return "";
      },
      option);
}

/// A value inside the key's range, different from the default where the range allows.
template <class Options>
std::string inside_value(const SectionKey<Options>& key) {
  Options defaults{};
  const OptionRef option = key.option(defaults);
  if (const auto* flag = std::get_if<bool*>(&option)) return **flag ? "false" : "true";
  if (std::holds_alternative<std::string*>(option)) return "\"elsewhere\"";
  if (std::holds_alternative<double*>(option)) {
    const auto& range = key.range;
    return scene_detail::format_number(range.high < scene_detail::infinity ? 0.5 * (range.low + range.high)
                                                                           : range.low + 0.375);
  }
  return std::to_string(key.high);
}

/// Each key in turn: `section_text(key line)` is a scene setting only that key; `read` gives
/// the options the parsed scene holds.
template <class Options>
void expect_keys_read_and_written(const std::vector<SectionKey<Options>>& keys,
                                  const std::function<std::string(const std::string&, std::string_view)>& section_text,
                                  const std::function<Options(const Scene&)>& read) {
  for (const auto& key : keys) {
    const std::string value = inside_value(key);
    const Scene scene = parse_scene(
        std::string(one_grain) + section_text(std::string(key.name) + " = " + value, key.name), "keys.toml");
    Options options = read(scene);
    EXPECT_EQ(written_value(key.option(options)), value) << key.name;
    EXPECT_NE(scene_to_toml(scene).find("\n" + std::string(key.name) + " = " + value + "\n"), std::string::npos)
        << key.name << " is not written back";
    if (std::holds_alternative<bool*>(key.option(options))) continue;
    const std::string bad = std::string(one_grain) + section_text(std::string(key.name) + " = -7", key.name);
    EXPECT_THROW(parse_scene(bad, "keys.toml"), SceneError) << key.name << " = -7";
  }
}

/// "[section]\nLINE\n" plus a contact law (the scene needs one).
std::function<std::string(const std::string&, std::string_view)> settings_section(const std::string& section) {
  return [section](const std::string& line, std::string_view) {
    return "[" + section + "]\n" + line + "\n[default_contact_law]\nfriction = 0.5\n";
  };
}

TEST(SceneKeys, EverySolverKeyIsReadWrittenAndChecked) {
  expect_keys_read_and_written<SolverOptions>(scene_detail::solver_keys(), settings_section("solver"),
                                              [](const Scene& s) { return s.run.step.solver; });
}

TEST(SceneKeys, EveryDetectionKeyIsReadWrittenAndChecked) {
  expect_keys_read_and_written<DetectionOptions>(scene_detail::detection_keys(), settings_section("detection"),
                                                 [](const Scene& s) { return s.run.step.detection; });
}

TEST(SceneKeys, EveryOutputKeyIsReadWrittenAndChecked) {
  expect_keys_read_and_written<OutputOptions>(scene_detail::output_keys(), settings_section("output"),
                                              [](const Scene& s) { return s.run.output; });
}

TEST(SceneKeys, EveryContactLawKeyIsReadWrittenAndChecked) {
  const auto law_section = [](const std::string& line, std::string_view key) {
    return "[[contact_laws]]\nmaterials = [\"rock\", \"rock\"]\n" +
           std::string(key == "friction" ? "" : "friction = 0.5\n") + line + "\n";
  };
  expect_keys_read_and_written<ContactLaw>(scene_detail::contact_law_keys(), law_section,
                                           [](const Scene& s) { return s.model.contact_laws.get(0, 0); });
}

}  // namespace
}  // namespace rubble
