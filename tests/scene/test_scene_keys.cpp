// Tests of simulation/scene_keys.hpp: every section's key tables are the ones docs/scene-file.md
// documents (same keys, same order, same kind of value, each word of a choice, "auto" and
// **required** where the code has them), and every key of the [solver], [detection], [output],
// contact-law and tree-gravity tables reads, is written back by scene_to_toml and is refused out
// of its range.
#include "simulation/scene_keys.hpp"
#include "simulation/scene_file.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

namespace rubble {
namespace {

using scene_detail::OptionRef;
using scene_detail::SectionKey;

/// One row of a key table in docs/scene-file.md: | `key` | type | ... | (a row may name several
/// keys: | `region_min`, `region_max` | ...).
struct DocRow {
  std::string key;
  std::string type;
  bool required = false;  ///< marked **required** in some column
  std::string second;     ///< the second column, whole
};

/// The lines of docs/scene-file.md.
std::vector<std::string> doc_lines() {
  std::ifstream in(RUBBLE_SCENE_FILE_DOC);
  EXPECT_TRUE(in) << "cannot read " << RUBBLE_SCENE_FILE_DOC;
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

/// The words between backticks in `text`, in order.
std::vector<std::string> backticked(const std::string& text) {
  std::vector<std::string> words;
  for (std::size_t begin = text.find('`'); begin != std::string::npos;) {
    const std::size_t end = text.find('`', begin + 1);
    if (end == std::string::npos) break;
    words.push_back(text.substr(begin + 1, end - begin - 1));
    begin = text.find('`', end + 1);
  }
  return words;
}

/// The cells of a table row "| a | b | c |".
std::vector<std::string> cells(const std::string& line) {
  std::vector<std::string> result;
  std::size_t begin = line.find('|') + 1;
  for (std::size_t end = line.find('|', begin); end != std::string::npos; end = line.find('|', begin)) {
    // A "\|" inside a cell (|v| in a formula) is not a column.
    while (end != std::string::npos && line[end - 1] == '\\') end = line.find('|', end + 1);
    if (end == std::string::npos) break;
    std::string cell = line.substr(begin, end - begin);
    cell.erase(0, cell.find_first_not_of(' '));
    cell.erase(cell.find_last_not_of(' ') + 1);
    result.push_back(cell);
    begin = end + 1;
  }
  return result;
}

/// The level of a Markdown heading ("## x": 2), 0 for any other line.
std::size_t heading_level(const std::string& line) {
  const std::size_t hashes = line.find_first_not_of('#');
  return hashes != std::string::npos && hashes > 0 && line[hashes] == ' ' ? hashes : 0;
}

/// The rows of the tables under the heading that starts with `heading` (up to the next heading
/// of its level or above), or of the first table after the line that starts with `marker` there.
std::vector<DocRow> doc_rows(const std::string& heading, const std::string& marker = "") {
  const std::size_t level = heading_level(heading);
  std::vector<DocRow> rows;
  bool inside = false;
  bool code = false;  // in a code block, where "# ..." is a comment
  bool marked = marker.empty();
  for (const std::string& line : doc_lines()) {
    if (line.rfind("```", 0) == 0) code = !code;
    if (!code && heading_level(line) > 0 && heading_level(line) <= level) {
      if (inside) break;
      inside = line.rfind(heading, 0) == 0;
      continue;
    }
    if (!inside) continue;
    if (!marked) {
      marked = line.rfind(marker, 0) == 0;
      continue;  // the marker line itself is no row (it may be the table's header)
    }
    if (line.rfind("| `", 0) != 0) {
      if (!marker.empty() && !rows.empty() && line.rfind('|', 0) != 0) break;  // the marked table ended
      continue;
    }
    const std::vector<std::string> columns = cells(line);
    for (const std::string& key : backticked(columns[0])) {
      rows.push_back({key, columns.size() > 1 ? columns[1] : "", line.find("**required**") != std::string::npos,
                      columns.size() > 1 ? columns[1] : ""});
    }
  }
  return rows;
}

/// Whether the doc's rows under `heading` (and `marker`) list `before` (keys the table does not
/// hold), then the table's keys, then `after`: same names, same kind of value (the type column
/// starts with it, or names each word of a choice), "auto" where accepted, **required** where
/// required. On failure, every mismatch found (for EXPECT_TRUE).
template <class Options>
::testing::AssertionResult doc_matches(const std::string& heading, const std::vector<SectionKey<Options>>& keys,
                                       const std::vector<std::string>& before = {},
                                       const std::vector<std::string>& after = {}, const std::string& marker = "") {
  const std::vector<DocRow> rows = doc_rows(heading, marker);
  const std::string where = heading + (marker.empty() ? "" : " " + marker);
  if (rows.size() != before.size() + keys.size() + after.size()) {
    return ::testing::AssertionFailure() << where << ": " << rows.size() << " keys in docs/scene-file.md, "
                                         << before.size() + keys.size() + after.size() << " expected";
  }
  std::ostringstream mismatches;
  for (std::size_t i = 0; i < before.size(); ++i) {
    if (rows[i].key != before[i]) mismatches << "\n  row " << i << ": " << rows[i].key << " vs " << before[i];
  }
  for (std::size_t i = 0; i < after.size(); ++i) {
    const std::size_t r = before.size() + keys.size() + i;
    if (rows[r].key != after[i]) mismatches << "\n  row " << r << ": " << rows[r].key << " vs " << after[i];
  }
  for (std::size_t i = 0; i < keys.size(); ++i) {
    const DocRow& row = rows[before.size() + i];
    const SectionKey<Options>& key = keys[i];
    if (row.key != key.name) mismatches << "\n  row " << before.size() + i << ": " << row.key << " vs " << key.name;
    const std::string_view type = scene_detail::key_type(key);
    if (type.empty() && key.choices[0].empty())
      mismatches << "\n  `" << key.name << "`: the table gives no kind of value";
    if (!type.empty() && row.type.rfind(type, 0) != 0) {
      mismatches << "\n  `" << key.name << "`: documented as \"" << row.type << "\", expected \"" << type << "...\"";
    }
    for (const std::string_view word : key.choices) {
      if (!word.empty() && row.type.find("`\"" + std::string(word) + "\"`") == std::string::npos) {
        mismatches << "\n  `" << key.name << "`: the word \"" << word << "\" is not documented";
      }
    }
    const bool accepts_auto = key.auto_when_negative || key.automatic != nullptr;
    if ((row.type.find("auto") != std::string::npos) != accepts_auto) {
      mismatches << "\n  `" << key.name << "`: \"auto\" documented or accepted but not both";
    }
    if (row.required != key.required) mismatches << "\n  `" << key.name << "`: required in one only";
    if (key.doc.empty()) mismatches << "\n  `" << key.name << "`: no doc in the table";
  }
  if (mismatches.str().empty()) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << where << ":" << mismatches.str();
}

TEST(SceneKeys, SolverTableMatchesTheDocs) { EXPECT_TRUE(doc_matches("## `[solver]`", scene_detail::solver_keys())); }

TEST(SceneKeys, DetectionTableMatchesTheDocs) {
  EXPECT_TRUE(doc_matches("## `[detection]`", scene_detail::detection_keys()));
}

TEST(SceneKeys, OutputTableMatchesTheDocs) { EXPECT_TRUE(doc_matches("## `[output]`", scene_detail::output_keys())); }

TEST(SceneKeys, ContactLawTableMatchesTheDocs) {
  EXPECT_TRUE(doc_matches("## `[[contact_laws]]`", scene_detail::contact_law_keys(), {"materials"}));
}

TEST(SceneKeys, TopLevelTableMatchesTheDocs) {
  // The keys in the "Top level" table, the sections in the "Layout of a file" block.
  std::vector<SectionKey<Scene>> keys, sections;
  for (const auto& key : scene_detail::top_level_keys()) (key.type == "table" ? sections : keys).push_back(key);
  EXPECT_TRUE(doc_matches("## Top level", keys));
  std::vector<std::string> layout;
  bool inside = false;
  bool code = false;
  for (const std::string& line : doc_lines()) {
    if (line.rfind("## ", 0) == 0) inside = line == "## Layout of a file";
    if (line.rfind("```", 0) == 0) code = !code;
    if (!inside || !code || line.rfind("```", 0) == 0) continue;
    std::string name = line.substr(0, line.find_first_of(" #"));
    name.erase(0, name.find_first_not_of('['));
    name.erase(name.find(']') == std::string::npos ? name.size() : name.find(']'));
    layout.push_back(name);
  }
  std::vector<std::string> names;
  for (const auto& key : scene_detail::top_level_keys()) names.emplace_back(key.name);
  EXPECT_EQ(layout, names) << "docs/scene-file.md \"Layout of a file\" vs the top-level table";
}

TEST(SceneKeys, TimeTableMatchesTheDocs) {
  // rest_kinetic_energy is a removed key, refused with a message naming its successor.
  EXPECT_TRUE(doc_matches("## `[time]`", scene_detail::time_keys(), {}, {"rest_kinetic_energy"}));
}

TEST(SceneKeys, GravityTablesMatchTheDocs) {
  // The table of types lists each type's keys; the table of keys has each key once, in the order
  // of the types' tables (uniform, tree, direct, central), with its kind of value.
  const std::vector<DocRow> types = doc_rows("## `[gravity]`", "| `type` |");
  std::vector<std::string> documented_types;
  documented_types.reserve(types.size());
  for (const DocRow& row : types) documented_types.push_back(row.key);
  std::vector<std::string> code_types;
  for (const std::string_view type : scene_detail::gravity_types()) code_types.push_back(fmt::format("\"{}\"", type));
  EXPECT_EQ(documented_types, code_types);
  std::vector<SectionKey<GravitySettings>> all;
  for (std::size_t t = 0; t < types.size() && t < scene_detail::gravity_types().size(); ++t) {
    const auto& keys = scene_detail::gravity_keys(scene_detail::gravity_types()[t]);
    ASSERT_EQ(keys.front().name, "type");
    std::vector<std::string> names;
    for (std::size_t k = 1; k < keys.size(); ++k) names.emplace_back(keys[k].name);
    EXPECT_EQ(backticked(types[t].second), names) << "docs/scene-file.md [gravity] type " << types[t].key;
  }
  for (const std::string_view type : {"uniform", "tree", "direct", "central"}) {
    for (const auto& key : scene_detail::gravity_keys(type)) {
      const auto same = [&](const SectionKey<GravitySettings>& other) { return other.name == key.name; };
      if (key.name != "type" && std::find_if(all.begin(), all.end(), same) == all.end()) all.push_back(key);
    }
  }
  EXPECT_TRUE(doc_matches("## `[gravity]`", all, {}, {}, "| key |"));
}

TEST(SceneKeys, MaterialTableMatchesTheDocs) {
  EXPECT_TRUE(doc_matches("## `[[materials]]`", scene_detail::material_keys()));
}

TEST(SceneKeys, WallTablesMatchTheDocs) {
  EXPECT_TRUE(doc_matches("## `[[walls]]`", scene_detail::wall_keys("plane"), {}, {}, "**Plane**"));
  EXPECT_TRUE(doc_matches("## `[[walls]]`", scene_detail::wall_keys("box"), {}, {}, "**Box**"));
}

TEST(SceneKeys, BodyTablesMatchTheDocs) {
  EXPECT_TRUE(doc_matches("## `[[bodies]]`", scene_detail::sphere_body_keys(), {}, {}, "**Sphere**"));
  // A polyhedron: the sphere's keys but `radius` ("as for a sphere"), then one way's keys, which
  // the doc's table of ways lists.
  std::vector<std::string> sphere;
  for (const auto& key : scene_detail::sphere_body_keys()) {
    if (key.name != "radius" && key.name != "shape") sphere.emplace_back(key.name);
  }
  std::vector<std::string> ways_documented;
  bool inside = false;
  for (const std::string& line : doc_lines()) {
    if (line.rfind("**Polyhedron**", 0) == 0) inside = true;
    if (!inside) continue;
    if (line.rfind("| way |", 0) == 0 || line.rfind("|---", 0) == 0) continue;
    if (line.rfind("| ", 0) != 0) {
      if (!ways_documented.empty()) break;
      continue;
    }
    ways_documented.push_back(cells(line)[1]);
  }
  ASSERT_EQ(ways_documented.size(), scene_detail::polyhedron_ways().size());
  for (std::size_t w = 0; w < ways_documented.size(); ++w) {
    const auto& keys = scene_detail::polyhedron_body_keys(scene_detail::polyhedron_ways()[w]);
    std::vector<std::string> placement, own;
    for (std::size_t k = 1; k < keys.size(); ++k) {
      (k < sphere.size() + 1 ? placement : own).emplace_back(keys[k].name);
    }
    EXPECT_EQ(placement, sphere) << scene_detail::polyhedron_ways()[w];
    EXPECT_EQ(backticked(ways_documented[w]), own)
        << "docs/scene-file.md, the polyhedron way of " << scene_detail::polyhedron_ways()[w];
  }
  // The keys of a driven body, as the walls and bodies take them.
  const auto& plane = scene_detail::wall_keys("plane");
  EXPECT_TRUE(
      doc_matches("### Driven bodies", std::vector<SectionKey<scene_detail::WallSpec>>(plane.end() - 3, plane.end())));
}

TEST(SceneKeys, InitialConditionTableMatchesTheDocs) {
  EXPECT_TRUE(doc_matches("## `[[initial_conditions]]`", scene_detail::initial_condition_keys()));
}

// [[inflow]]: the grains' keys (a generator's but `type`) and the inflow's own, in one table;
// the random polyhedra's keys are the generators' (documented there).
TEST(SceneKeys, InflowTableMatchesTheDocs) {
  EXPECT_TRUE(doc_matches("## `[[inflow]]`", scene_detail::inflow_keys(), {}, {}, "| key |"));
}

TEST(SceneKeys, GeneratorTablesMatchTheDocs) {
  const std::string heading = "## `[[generators]]`";
  EXPECT_TRUE(doc_matches(heading, scene_detail::generator_common_keys(), {}, {}, "| key |"));
  EXPECT_TRUE(doc_matches(heading, scene_detail::generator_shape_keys("mix"), {}, {}, "**Random polyhedra**"));
  for (const std::string_view type : {"box_deposit", "cubic_grid", "sphere_cloud"}) {
    EXPECT_TRUE(
        doc_matches(heading, scene_detail::generator_type_keys(type), {}, {}, "**`" + std::string(type) + "`**"));
  }
  // The random [[bodies]] polyhedron takes the same shape keys.
  std::vector<std::string> shape_keys, body_keys;
  for (const auto& key : scene_detail::random_polyhedron_keys()) shape_keys.emplace_back(key.name);
  for (const auto& key : scene_detail::polyhedron_body_keys("diameter")) body_keys.emplace_back(key.name);
  EXPECT_TRUE(std::search(body_keys.begin(), body_keys.end(), shape_keys.begin(), shape_keys.end()) != body_keys.end());
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
/// the options the parsed scene holds. Fails listing every key that is not read back as written,
/// not written back by scene_to_toml, or not refused at -7 (booleans excepted), and fails when the
/// table has no key to check.
template <class Options>
testing::AssertionResult keys_read_and_written(
    const std::vector<SectionKey<Options>>& keys,
    const std::function<std::string(const std::string&, std::string_view)>& section_text,
    const std::function<Options(const Scene&)>& read) {
  std::string failures;
  std::size_t checked = 0;
  for (const auto& key : keys) {
    if (!key.option) continue;  // read by hand: the section's own tests
    ++checked;
    const std::string name(key.name), value = inside_value(key);
    const Scene scene = parse_scene(std::string(one_grain) + section_text(name + " = " + value, key.name), "keys.toml");
    Options options = read(scene);
    if (const std::string got = written_value(key.option(options)); got != value) {
      failures.append("\n  ").append(name).append(": set to ").append(value).append(", read back as ").append(got);
    }
    if (scene_to_toml(scene).find("\n" + name + " = " + value + "\n") == std::string::npos) {
      failures.append("\n  ").append(name).append(": not written back");
    }
    if (std::holds_alternative<bool*>(key.option(options))) continue;
    try {
      parse_scene(std::string(one_grain) + section_text(name + " = -7", key.name), "keys.toml");
      failures.append("\n  ").append(name).append(" = -7: accepted");
    } catch (const SceneError&) {
    }
  }
  if (checked == 0) return testing::AssertionFailure() << "no key of the table is read through an option";
  if (!failures.empty()) return testing::AssertionFailure() << failures;
  return testing::AssertionSuccess();
}

/// "[section]\nLINE\n" plus a contact law (the scene needs one).
std::function<std::string(const std::string&, std::string_view)> settings_section(const std::string& section) {
  return [section](const std::string& line, std::string_view) {
    return "[" + section + "]\n" + line + "\n[default_contact_law]\nfriction = 0.5\n";
  };
}

TEST(SceneKeys, EverySolverKeyIsReadWrittenAndChecked) {
  EXPECT_TRUE(keys_read_and_written<SolverOptions>(scene_detail::solver_keys(), settings_section("solver"),
                                                   [](const Scene& s) { return s.run.step.solver; }));
}

TEST(SceneKeys, EveryDetectionKeyIsReadWrittenAndChecked) {
  EXPECT_TRUE(keys_read_and_written<DetectionOptions>(scene_detail::detection_keys(), settings_section("detection"),
                                                      [](const Scene& s) { return s.run.step.detection; }));
}

TEST(SceneKeys, EveryOutputKeyIsReadWrittenAndChecked) {
  EXPECT_TRUE(keys_read_and_written<OutputOptions>(scene_detail::output_keys(), settings_section("output"),
                                                   [](const Scene& s) { return s.run.output; }));
}

TEST(SceneKeys, EveryContactLawKeyIsReadWrittenAndChecked) {
  const auto law_section = [](const std::string& line, std::string_view key) {
    return "[[contact_laws]]\nmaterials = [\"rock\", \"rock\"]\n" +
           std::string(key == "friction" ? "" : "friction = 0.5\n") + line + "\n";
  };
  EXPECT_TRUE(keys_read_and_written<ContactLaw>(scene_detail::contact_law_keys(), law_section,
                                                [](const Scene& s) { return s.model.contact_laws.get(0, 0); }));
}

TEST(SceneKeys, EveryTreeGravityKeyIsReadWrittenAndChecked) {
  const auto tree = [](const std::string& line, std::string_view) {
    return "[gravity]\ntype = \"tree\"\n" + line + "\n[default_contact_law]\nfriction = 0.5\n";
  };
  EXPECT_TRUE(keys_read_and_written<GravitySettings>(scene_detail::gravity_keys("tree"), tree,
                                                     [](const Scene& s) { return s.run.step.gravity; }));
}

}  // namespace
}  // namespace rubble
