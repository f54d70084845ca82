// libFuzzer target for the scene parser (issue 8, item 3): any byte string given to parse_scene
// must either parse or throw SceneError. Anything else (another exception, a crash, a sanitizer
// report, a hang) is a bug that libFuzzer reports with the input that caused it.
//
// Inputs whose generators or inflows ask for many grains are skipped: expanding 10^6 grains (or building
// thousands of random polyhedra with CGAL) is legitimate work whose cost grows with the count,
// which libFuzzer would report as a timeout, not a parser bug. The scene-file limits themselves
// (at most 10^8 grains, absurd step counts) are tested in tests/scene/bad/.
#include <toml++/toml.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "simulation/scene_file.hpp"

namespace {

/// Grains a generator or inflow table asks for (count, or cells_per_side cubed), as a double; 0 if
/// unknown.
double requested_grains(const toml::table& generator) {
  double grains = 0.0;
  if (const auto count = generator["count"].value<double>()) grains = std::max(grains, std::abs(*count));
  if (const auto n = generator["cells_per_side"].value<double>()) grains = std::max(grains, std::pow(std::abs(*n), 3));
  if (const auto n = generator["grains"].value<double>()) grains = std::max(grains, std::abs(*n));
  if (std::isnan(grains)) grains = 0.0;
  return grains;
}

/// True if the scene asks for more grains than a fuzzing iteration should build.
bool too_many_grains(std::string_view text) {
  toml::table root;
  try {
    root = toml::parse(text, std::string_view("fuzz.toml"));
  } catch (const toml::parse_error&) {
    return false;  // parse_scene reports the syntax error: fuzz it
  }
  // Inflows are generated at parse time too (an inflow of 92 212 polyhedra took 23 s to parse in
  // a release build, 41 s and more under the fuzzer's instrumentation).
  double spheres = 0.0, polyhedra = 0.0;
  for (const char* section : {"generators", "inflow"}) {
    const toml::array* entries = root[section].as_array();
    if (entries == nullptr) continue;
    for (const toml::node& node : *entries) {
      const toml::table* entry = node.as_table();
      if (entry == nullptr) continue;
      const std::string_view shape = (*entry)["shape"].value_or(std::string_view("sphere"));
      (shape == "sphere" ? spheres : polyhedra) += requested_grains(*entry);
    }
  }
  return spheres > 2e4 || polyhedra > 200;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  if (too_many_grains(text)) return -1;  // -1: libFuzzer keeps it out of the corpus
  try {
    const rubble::Scene scene = rubble::parse_scene(text, "fuzz.toml");
    (void)scene;
  } catch (const rubble::SceneError&) {
    // The expected answer to bad input.
  }
  return 0;
}
