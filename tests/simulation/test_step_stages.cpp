// The step's stages as the code runs them and as the docs list them: simulation/step.cpp numbers
// its stages in comments ("// 5. detect ..."), README.md's reading table, simulation/README.md
// and docs/architecture.md's diagram list the same names in the same order, and the timed stages
// (`Stage`, simulation/step.hpp) are declared in the order step() times them.
#include <gtest/gtest.h>

#include <fstream>
#include <regex>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "simulation/step.hpp"

namespace rubble {
namespace {

std::string read_source(const std::string& relative_path) {
  const std::string path = std::string(RUBBLE_SOURCE_DIR) + "/" + relative_path;
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot read " + path);  // fails the test that reads it
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

/// The (number, name) of every match of `pattern` (groups 1 and 2), in file order.
std::vector<std::pair<int, std::string>> numbered(const std::string& text, const std::regex& pattern) {
  std::vector<std::pair<int, std::string>> out;
  for (auto it = std::sregex_iterator(text.begin(), text.end(), pattern); it != std::sregex_iterator(); ++it) {
    out.emplace_back(std::stoi((*it)[1].str()), (*it)[2].str());
  }
  return out;
}

std::vector<std::string> names(const std::vector<std::pair<int, std::string>>& stages) {
  std::vector<std::string> out;
  for (const auto& [number, name] : stages) out.push_back(name);
  return out;
}

/// The stages step.cpp's step() numbers in its comments.
std::vector<std::pair<int, std::string>> code_stages() {
  return numbered(read_source("simulation/step.cpp"), std::regex(R"(\n\s*// (\d+)\. (\w+))"));
}

TEST(StepStages, NumberedOneToNInExecutionOrder) {
  const auto stages = code_stages();
  ASSERT_GE(stages.size(), 9u);
  for (std::size_t k = 0; k < stages.size(); ++k) EXPECT_EQ(stages[k].first, static_cast<int>(k + 1));
}

TEST(StepStages, ReadmeTableListsTheSameStagesThenTheRunLoop) {
  const auto code = code_stages();
  const auto readme = numbered(read_source("README.md"), std::regex(R"(\n\| (\d+)\. (\w+) \|)"));
  ASSERT_GE(readme.size(), code.size());
  for (std::size_t k = 0; k < code.size(); ++k) EXPECT_EQ(readme[k], code[k]) << "README.md row " << k + 1;
  for (std::size_t k = code.size(); k < readme.size(); ++k) EXPECT_EQ(readme[k].first, static_cast<int>(k + 1));
}

TEST(StepStages, ArchitectureDiagramListsTheSameStages) {
  const auto diagram = numbered(read_source("docs/architecture.md"), std::regex(R"(│ +(\d+) (\w+))"));
  EXPECT_EQ(diagram, code_stages());
}

TEST(StepStages, SimulationReadmeListsTheSameNames) {
  std::string text = read_source("simulation/README.md");
  text = std::regex_replace(text, std::regex(R"(\s+)"), " ");
  std::smatch list;
  ASSERT_TRUE(std::regex_search(text, list, std::regex(R"(named stages in execution order \(([a-z_, ]+)\))")));
  std::vector<std::string> listed;
  const std::string items = list[1].str();
  const std::regex word(R"(\w+)");
  for (auto it = std::sregex_iterator(items.begin(), items.end(), word); it != std::sregex_iterator(); ++it) {
    listed.push_back(it->str());
  }
  EXPECT_EQ(listed, names(code_stages()));
}

TEST(StepStages, TimedStagesAreDeclaredInTheOrderStepTimesThem) {
  const std::string source = read_source("simulation/step.cpp");
  const std::size_t body = source.find("StepReport step(");
  ASSERT_NE(body, std::string::npos);
  const std::string step_body = source.substr(body);
  std::vector<std::string> timed;
  const std::regex stage_use(R"(Stage::(\w+))");
  for (auto it = std::sregex_iterator(step_body.begin(), step_body.end(), stage_use); it != std::sregex_iterator();
       ++it) {
    const std::string name = (*it)[1].str();
    if (timed.empty() || timed.back() != name) timed.push_back(name);
  }
  std::vector<std::string> declared;
  for (std::size_t k = 0; k < static_cast<std::size_t>(Stage::count); ++k) {
    declared.emplace_back(stage_name(static_cast<Stage>(k)));
  }
  EXPECT_EQ(timed, declared);
}

}  // namespace
}  // namespace rubble
